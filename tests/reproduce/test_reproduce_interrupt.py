"""Ctrl-C in ``wovenskin reproduce``'s simulated study says what was kept, exit status 130."""

from __future__ import annotations

from cli_helpers import invoke

import wovenskin.reproduce.report as report
from wovenskin.study.simulate import StudyInterrupted


def test_an_interrupted_reproduce_says_what_the_study_kept(monkeypatch, tmp_path):
    folder = tmp_path / "out" / "study"

    def interrupted(*args, **kwargs):
        raise StudyInterrupted(folder, 3, 12)

    monkeypatch.setattr(report, "reproduce", interrupted)
    result = invoke("reproduce", "--out", tmp_path / "out", "--quick")
    assert result.exit_code == 130, result.output
    assert "interrupted: 3 of 12 trials were written" in result.stderr
    assert "no report written" in result.stderr
