"""Tests of the study panel's plan (wovenskin.ui.dashboard.plan)."""

from __future__ import annotations

from wovenskin.study.counterbalance import study_plan
from wovenskin.study.definition import add_participant, init_study, load_study
from wovenskin.study.recorder import TRIALS_DIR, trial_folder_name
from wovenskin.ui.dashboard.plan import next_step


def _study(tmp_path):
    init_study(tmp_path / "s", "plan")
    for pid in ("P01", "P02"):
        add_participant(tmp_path / "s", pid, "novice")
    return tmp_path / "s"


def test_the_next_step_follows_the_counterbalanced_plan_and_counts_trials(tmp_path):
    study_dir = _study(tmp_path)
    study = load_study(study_dir)
    planned = [s for s in study_plan(study) if s.participant == "P02"]
    step = next_step(study_dir, "P02")
    assert (step["task"], step["interface"]) == (planned[0].task, planned[0].interface)
    assert step["step"] == 1 and step["trial"] == 1 and step["steps"] == len(planned) == 6
    folder = study_dir / TRIALS_DIR / "P02"
    for n in range(1, study.trials_per_condition + 1):  # the first condition's trials done
        (folder / trial_folder_name(planned[0].task, planned[0].interface, n)).mkdir(parents=True)
    step = next_step(study_dir, "P02")
    assert (step["task"], step["interface"], step["step"]) == (
        planned[1].task, planned[1].interface, 2,
    )  # fmt: skip
    (folder / trial_folder_name(planned[1].task, planned[1].interface, 1)).mkdir()
    assert next_step(study_dir, "P02")["trial"] == 2


def test_a_participant_who_did_everything_is_done(tmp_path):
    study_dir = _study(tmp_path)
    study = load_study(study_dir)
    for s in study_plan(study):
        if s.participant == "P01":
            for n in range(1, s.trials + 1):
                folder = study_dir / TRIALS_DIR / "P01" / trial_folder_name(s.task, s.interface, n)
                folder.mkdir(parents=True)
    assert next_step(study_dir, "P01") == {"participant": "P01", "steps": 6, "done": True}


def test_no_study_or_an_unknown_participant_has_no_plan(tmp_path):
    study_dir = _study(tmp_path)
    assert next_step(None, "P01") is None
    assert next_step(study_dir, "P99") is None
    assert next_step(study_dir, "") is None
    assert next_step(tmp_path / "nowhere", "P01") is None
