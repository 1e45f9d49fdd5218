"""TrialRunner: a real session on a task scene, keyboard input, a real TrialRecorder."""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pytest

from wovenskin.control.session_inputs import CommandRecord
from wovenskin.errors import ConfigError
from wovenskin.runtime import open_session
from wovenskin.study.recorder import TrialRecorder
from wovenskin.study.runner import TrialRunner, command_kind, task_measures
from wovenskin.tasks import PickPlaceTask, PourState
from wovenskin.teleop.keyboard import Keyboard


def _rows(path):
    with path.open(newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.mark.slow
def test_a_keyboard_trial_is_recorded(tmp_path):
    keyboard = Keyboard()
    script = {0.5: ("down", "r"), 1.0: ("up", "r"), 1.2: ("down", "g"), 1.25: ("up", "g")}
    verdicts = []

    def on_tick(session):
        for at, (what, key) in script.items():
            if abs(session.now - at) < 1e-9:
                (keyboard.key_down if what == "down" else keyboard.key_up)(key)
        verdicts.append(runner.tick(session.now))

    session = open_session("none:speed=0", task="pick_place", inputs=[keyboard], on_tick=on_tick)
    task = session.task
    task.reset(7)
    recorder = TrialRecorder(tmp_path, "P01", "novice", "pick_place", "keyboard", 1)
    runner = TrialRunner(session, task, recorder, time_limit_s=60.0, pose_every_s=0.1)
    try:
        session.start()
        runner.start(session.now)
        session.run(seconds=1.5)
        summary = runner.finish(session.now, "give_up")
    finally:
        session.close()
    assert set(verdicts) == {None}
    folder = recorder.folder
    commands = _rows(folder / "commands.csv")
    assert [(c["command"], c["kind"], c["source"]) for c in commands] == [
        ("swipe_up", "key", "keyboard"),
        ("toggle", "gripper", "keyboard"),
    ]
    poses = _rows(folder / "trajectory.csv")
    assert 12 <= len(poses) <= 20  # every 0.1 s over 1.5 s
    z = np.array([float(p["z"]) for p in poses])
    assert abs(z[-1] - z[0]) > 0.01  # the held key moved the arm
    assert float(poses[0]["gripper"]) == 0.0 and float(poses[-1]["gripper"]) == 1.0
    data = json.loads((folder / "trial.json").read_text())
    assert data["outcome"] == "give_up" and data["commands"] == 2
    assert data["commands_by_kind"] == {"gesture": 0, "key": 1, "panel": 0, "gripper": 1}
    assert data["measures"]["objects_total"] == 3.0 and "objects_seated" in data["measures"]
    assert data["first_command_t"] == pytest.approx(0.505)  # polled on the next tick
    assert summary.duration_s == pytest.approx(session.now - 0.505)
    events = [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]
    assert [e["event"] for e in events][:2] == ["start", "task"]
    assert events[1]["state"]["seated"] == 0 and events[-1]["event"] == "finish"


class _FakeTask:
    """A task whose verdicts the test sets."""

    name = "fake"

    def __init__(self):
        self.delivered = 0
        self.spilled = 0

    def state(self):
        return PourState(
            100 - self.delivered, self.delivered, self.spilled, 0, 100, np.zeros(3), 0.0
        )

    def succeeded(self):
        return self.delivered == 100

    def failed(self):
        return self.spilled > 0


def _fake_session():
    return SimpleNamespace(command_log=[], state=SimpleNamespace(robot=None), gripper_closed=False)


def _events(recorder):
    return [json.loads(x) for x in (recorder.folder / "events.jsonl").read_text().splitlines()]


def test_verdicts_and_task_events(tmp_path):
    session, task = _fake_session(), _FakeTask()
    session.command_log.append(CommandRecord(0.0, "skin", "push", "gesture"))  # before: not counted
    recorder = TrialRecorder(tmp_path, "P02", "expert", "pour", "skin", 1)
    runner = TrialRunner(session, task, recorder, pose_every_s=0.05)
    runner.start(1.0)
    assert runner.tick(1.01) is None
    session.command_log.append(CommandRecord(1.02, "skin", "swipe_up", "gesture"))
    task.delivered = 40
    assert runner.tick(1.02) is None  # not yet due for a check
    assert runner.tick(1.06) is None
    task.delivered = 100
    assert runner.tick(1.2) == "success"
    summary = runner.finish(1.2, "success")
    assert summary.commands == 1 and summary.commands_by_kind["gesture"] == 1
    assert summary.measures["particles_delivered"] == 100.0
    assert summary.measures["particles_total"] == 100.0 and "objects_total" not in summary.measures
    changes = [e["changed"] for e in _events(recorder) if "changed" in e]
    assert changes == [
        {"in_cup": 60, "delivered": 40},
        {"in_cup": 0, "delivered": 100, "succeeded": True},
    ]


def test_failure_and_timeout(tmp_path):
    session, task = _fake_session(), _FakeTask()
    recorder = TrialRecorder(tmp_path, "P03", "novice", "pour", "keyboard", 1, time_limit_s=5.0)
    runner = TrialRunner(session, task, recorder)
    runner.start(0.0)
    assert runner.tick(100.0) is None  # no command yet: the clock has not started
    session.command_log.append(CommandRecord(100.0, "keyboard", "push", "press"))
    assert runner.tick(104.0) is None and runner.elapsed(104.0) == pytest.approx(4.0)
    assert runner.tick(105.0) == "timeout"
    assert runner.finish(106.0, "timeout").duration_s == 5.0

    task2 = _FakeTask()
    recorder2 = TrialRecorder(tmp_path, "P03", "novice", "pour", "keyboard", 2)
    runner2 = TrialRunner(_fake_session(), task2, recorder2)
    runner2.start(0.0)
    task2.spilled = 3
    assert runner2.tick(0.1) == "failed"
    assert runner2.finish(0.1, "failed").measures["particles_spilled"] == 3.0


def test_bad_use_is_one_config_error(tmp_path):
    recorder = TrialRecorder(tmp_path, "P04", "novice", "pour", "skin", 1)
    with pytest.raises(ConfigError, match="pose_every_s"):
        TrialRunner(_fake_session(), _FakeTask(), recorder, pose_every_s=0)
    runner = TrialRunner(_fake_session(), _FakeTask(), recorder)
    with pytest.raises(ConfigError, match="not started"):
        runner.tick(0.0)
    runner.start(0.0)
    with pytest.raises(ConfigError, match="outcome"):
        runner.finish(1.0, "won")
    runner.close()
    assert not (recorder.folder / "trial.json").exists()


@pytest.mark.parametrize(
    "record, kind",
    [
        (CommandRecord(0, "skin", "push", "gesture"), "gesture"),
        (CommandRecord(0, "keyboard", "push", "press"), "key"),
        (CommandRecord(0, "keyboard", "toggle", "gripper"), "gripper"),
        (CommandRecord(0, "pendant", "frame tool", "mode"), "panel"),
        (CommandRecord(0, "pendant", "x", "step"), "panel"),
    ],
)
def test_command_kinds(record, kind):
    assert command_kind(record) == kind


def test_measures_of_the_pick_place_state():
    measures = task_measures(PickPlaceTask().state())
    assert measures == {"objects_seated": 0.0, "objects_total": 3.0}


@dataclass
class _Other:
    score: float
    label: str


def test_measures_of_other_states_keep_numbers():
    assert task_measures(_Other(2.5, "x")) == {"score": 2.5}
    with pytest.raises(ConfigError):
        task_measures({"score": 1})
