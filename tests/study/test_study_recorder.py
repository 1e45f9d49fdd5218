"""TrialRecorder: the trial folder, command counts, durations, summaries, misuse."""

from __future__ import annotations

import csv
import json

import pytest

from wovenskin.errors import DataError
from wovenskin.outputs import OutputExistsError
from wovenskin.study.recorder import TRIALS_COLUMNS, TrialRecorder


def _recorder(tmp_path, **kwargs):
    return TrialRecorder(
        tmp_path, "P01", "novice", "pour", "skin", 1, wall_clock=lambda: 0.0, **kwargs
    )


def test_a_trial_writes_its_folder_and_a_trials_row(tmp_path):
    rec = _recorder(tmp_path, time_limit_s=60)
    rec.start(10.0)
    rec.pose(10.0, (0.3, 0.0, 0.4, 1, 0, 0, 0), 0.0)
    assert rec.elapsed(11.0) == 0.0  # the clock starts at the first command
    rec.command(12.0, "skin", "swipe_up", "gesture")
    rec.command(13.0, "skin", "gripper", "gripper")
    rec.task_event(14.0, {"event": "poured", "particles": 40})
    rec.pose(14.5, (0.3, 0.1, 0.4, 1, 0, 0, 0), 1.0)
    summary = rec.finish(
        20.5, "success", {"particles_delivered": 98, "particles_spilled": 0, "tilt_max_deg": 80}
    )
    assert summary.duration_s == pytest.approx(8.5)
    assert summary.commands == 2
    assert summary.commands_by_kind == {"gesture": 1, "key": 0, "panel": 0, "gripper": 1}
    folder = tmp_path / "trials" / "P01" / "pour-skin-1"
    assert rec.folder == folder
    commands = list(csv.DictReader((folder / "commands.csv").open()))
    assert [c["command"] for c in commands] == ["swipe_up", "gripper"]
    assert commands[0]["t"] == "12.0" and commands[0]["kind"] == "gesture"
    trajectory = list(csv.DictReader((folder / "trajectory.csv").open()))
    assert trajectory[1]["y"] == "0.1" and trajectory[1]["gripper"] == "1.0"
    events = [json.loads(line) for line in (folder / "events.jsonl").open()]
    assert [e["event"] for e in events] == ["start", "first_command", "poured", "finish"]
    data = json.loads((folder / "trial.json").read_text())
    assert data["outcome"] == "success" and data["synthetic"] is False
    assert data["measures"]["tilt_max_deg"] == 80
    rows = list(csv.DictReader((tmp_path / "trials.csv").open()))
    assert list(rows[0]) == list(TRIALS_COLUMNS)
    assert rows[0]["particles_delivered"] == "98.0" and rows[0]["objects_seated"] == ""
    assert json.loads(rows[0]["measures_json"]) == {"tilt_max_deg": 80.0}
    assert rows[0]["folder"] == "trials/P01/pour-skin-1"


def test_a_timeout_is_capped_at_the_limit_and_a_trial_without_commands_times_from_start(
    tmp_path,
):
    rec = _recorder(tmp_path, time_limit_s=5)
    rec.start(0.0)
    rec.command(1.0, "keyboard", "w", "key")
    assert not rec.timed_out(5.9) and rec.timed_out(6.0)
    assert rec.finish(6.2, "timeout").duration_s == 5
    other = TrialRecorder(tmp_path, "P01", "novice", "pour", "skin", 2)
    other.start(3.0)
    assert other.finish(7.0, "give_up").duration_s == 4.0


def test_misuse_is_a_data_error(tmp_path):
    rec = _recorder(tmp_path)
    with pytest.raises(DataError, match="not started"):
        rec.command(0.0, "skin", "tap", "gesture")
    rec.start(0.0)
    with pytest.raises(DataError, match="kind"):
        rec.command(1.0, "skin", "tap", "wave")
    with pytest.raises(DataError, match="7 numbers"):
        rec.pose(1.0, (0, 0, 0), 0.0)
    with pytest.raises(DataError, match="finite"):
        rec.pose(float("nan"), (0, 0, 0, 1, 0, 0, 0), 0.0)
    with pytest.raises(DataError, match="outcome"):
        rec.finish(2.0, "won")
    with pytest.raises(DataError, match="measure"):
        rec.finish(2.0, "success", {"spilled": float("inf")})
    rec.finish(2.0, "success")
    with pytest.raises(DataError, match="finished"):
        rec.command(3.0, "skin", "tap", "gesture")


def test_an_existing_trial_is_kept_unless_overwrite(tmp_path):
    rec = _recorder(tmp_path)
    rec.close()
    with pytest.raises(OutputExistsError):
        _recorder(tmp_path)
    again = _recorder(tmp_path, overwrite=True)
    again.start(0.0)
    again.finish(1.0, "aborted")


def test_synthetic_trials_are_labelled_in_every_file(tmp_path):
    rec = _recorder(tmp_path, synthetic=True)
    rec.start(0.0)
    rec.command(0.5, "sim", "tap", "gesture")
    rec.pose(0.5, (0, 0, 0, 1, 0, 0, 0), 0.0)
    rec.finish(1.0, "success")
    folder = rec.folder
    for name in ("commands.csv", "trajectory.csv"):
        rows = list(csv.DictReader((folder / name).open()))
        assert rows and all(r["synthetic"] == "1" for r in rows)
    assert all(json.loads(line)["synthetic"] for line in (folder / "events.jsonl").open())
    assert json.loads((folder / "trial.json").read_text())["synthetic"] is True
    assert next(csv.DictReader((tmp_path / "trials.csv").open()))["synthetic"] == "1"
