"""Synthetic studies: deterministic, labelled synthetic, never written over real data."""

from __future__ import annotations

import csv

import pytest

from wovenskin.outputs import OutputExistsError
from wovenskin.study.definition import load_study
from wovenskin.study.reader import read_trials
from wovenskin.study.synthetic import synthetic_study


def test_a_synthetic_study_is_complete_deterministic_and_labelled(tmp_path):
    synthetic_study(tmp_path / "a", participants=2, seed=3, trials=1)
    synthetic_study(tmp_path / "b", participants=2, seed=3, trials=1)
    a, b = tmp_path / "a", tmp_path / "b"
    assert (a / "trials.csv").read_text() == (b / "trials.csv").read_text()
    study = load_study(a)
    assert study.synthetic and [p.expertise for p in study.participants] == ["novice", "expert"]
    trials, warnings = read_trials(a)
    assert len(trials) == 2 * 2 * 3 and not warnings
    assert all(t.synthetic for t in trials)
    assert {t.participant for t in trials} == {"S01", "S02"}
    for row in csv.DictReader((a / "questionnaires.csv").open()):
        assert row["synthetic"] == "1"
    assert "SYNTHETIC" in (a / "study.toml").read_text()
    assert (a / "SYNTHETIC.md").exists() and (a / "plan.csv").exists()


def test_it_never_writes_into_a_folder_with_files(tmp_path):
    (tmp_path / "study.toml").write_text('name = "real"\n')
    with pytest.raises(OutputExistsError):
        synthetic_study(tmp_path, participants=1)
    assert (tmp_path / "study.toml").read_text() == 'name = "real"\n'
