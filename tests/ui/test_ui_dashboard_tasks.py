"""The dashboard's study tasks, keyboard, teach pendant and trials, without a browser."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from stand_ins import ContactMeans
from stand_ins import wait_until as _wait

from wovenskin.runtime.session import open_session
from wovenskin.study.definition import add_participant, init_study
from wovenskin.study.reader import read_trials
from wovenskin.tasks import make_task
from wovenskin.ui.dashboard.runner import DashboardRunner
from wovenskin.ui.dashboard.scene import TaskScene
from wovenskin.ui.dashboard.server import _handle, _release
from wovenskin.ui.dashboard.teleop import PageHold, PageInputs, handle_input
from wovenskin.ui.dashboard.trials import StudyPanel, next_trial

pytestmark = pytest.mark.slow  # each opens a physics scene and a control loop (3-10 s)


def _opener(tmp_path):
    def opener(skin: str, robot: str, task=None):
        return open_session(
            skin, robot, recognizer=ContactMeans("swipe_up"), poses=tmp_path / "poses.toml",
            task=task,
        )  # fmt: skip

    return opener


def _runner(tmp_path, task: str | None = "pick_place", **kwargs) -> DashboardRunner:
    runner = DashboardRunner(_opener(tmp_path), "none", "sim", task=task, **kwargs)
    runner.start()
    assert _wait(lambda: runner.latest() is not None)
    return runner


def _tcp(runner) -> np.ndarray:
    return np.array(runner.latest()["robot"]["tcp"]["pos"])


def _command(runner, **command) -> None:
    runner.submit(command)
    seq = runner.latest()["seq"]
    assert _wait(lambda: runner.latest()["seq"] > seq + 2)


# -- the task scene -----------------------------------------------------------------------


def test_the_pick_place_scene_draws_molds_once_and_objects_and_fingers_per_frame() -> None:
    scene = TaskScene(make_task("pick_place"))
    described = scene.describe()
    moving = [shape["name"] for shape in described["moving"]]
    assert {"cube", "cylinder", "prism", "finger_left", "finger_right"} == set(moving)
    fixed = [shape["name"] for shape in described["fixed"]]
    assert "table" in fixed and any(name.startswith("mold_prism") for name in fixed)
    assert all(len(shape["pose"]) == 7 for shape in described["fixed"])
    prism = described["moving"][moving.index("prism")]
    assert prism["type"] == "mesh" and len(prism["vertices"]) % 3 == 0 and prism["faces"]
    assert described["particles"]["count"] == 0 and described["hide"] == [
        "finger_left",
        "finger_right",
    ]
    poses = scene.poses()
    assert len(poses["geoms"]) == len(moving) and poses["particles"] == []
    json.dumps(described, allow_nan=False)


def test_the_pour_scene_sends_its_particles_as_a_flat_position_list() -> None:
    task = make_task("pour")
    task.reset(0)
    scene = TaskScene(task)
    described = scene.describe()
    assert described["particles"]["count"] == 100
    assert described["particles"]["radius"] == pytest.approx(0.005)
    positions = np.array(scene.poses()["particles"]).reshape(-1, 3)
    assert positions.shape == (100, 3)
    cup = task.physics.data.body("cup").xpos
    assert np.all(np.linalg.norm(positions[:, :2] - cup[:2], axis=1) < 0.04)  # in the cup


# -- keyboard and pendant messages ---------------------------------------------------------


def test_key_and_pendant_messages_need_their_interface_and_bad_ones_are_refused() -> None:
    inputs, hold = PageInputs(), PageHold()
    with pytest.raises(ValueError, match="keyboard is off"):
        handle_input(inputs, {"type": "key", "key": "w", "down": True}, hold)
    inputs.choose("keyboard")
    handle_input(inputs, {"type": "key", "key": "W", "down": True}, hold)
    assert hold.keys == {"w"} and hold.held and inputs.keyboard.down == {"w"}
    for bad in ({"key": "ww", "down": True}, {"key": "w", "down": 1}, {"key": "z", "down": True}):
        with pytest.raises(ValueError):
            handle_input(inputs, {"type": "key", **bad}, hold)
    handle_input(inputs, {"type": "key", "release_all": True}, hold)
    assert not hold.held and inputs.keyboard.down == frozenset()
    with pytest.raises(ValueError, match="pendant is off"):
        handle_input(inputs, {"type": "pendant", "op": "press", "axis": "x", "sign": 1}, hold)
    inputs.choose("pendant")
    handle_input(inputs, {"type": "pendant", "op": "press", "axis": "x", "sign": 1}, hold)
    assert hold.jog and inputs.pendant.jogging == "translate +x"
    for bad in ({"op": "fly"}, {"op": "step", "value": 3}, {"op": "speed", "value": 0},
                {"op": "frame", "value": "world"}, {"op": "press", "axis": "x", "sign": 2},
                {"op": "go_to", "pose": "away"}):  # fmt: skip
        with pytest.raises(ValueError):
            handle_input(inputs, {"type": "pendant", **bad}, hold)
    with pytest.raises(ValueError):
        PageInputs("mouse")


class _Runner:
    def __init__(self) -> None:
        self.inputs = PageInputs("keyboard")


def test_a_page_that_goes_silent_has_its_keys_and_jog_released() -> None:
    runner, hold = _Runner(), PageHold()
    down = json.dumps({"type": "key", "key": "r", "down": True})
    assert _handle(runner, down, None, hold) is None
    assert _handle(runner, json.dumps({"type": "hold"}), None, hold) is None
    runner.inputs.choose("pendant")  # choosing another interface lets go of everything
    assert runner.inputs.keyboard.down == frozenset()
    press = {"type": "pendant", "op": "press", "axis": "y", "sign": -1}
    assert _handle(runner, json.dumps(press), None, hold) is None
    assert runner.inputs.pendant.jogging == "translate -y" and hold.jog
    _release(runner, hold)  # what the server does after 1 s without a message
    assert not hold.held and runner.inputs.pendant.jogging is None
    reply = _handle(runner, json.dumps({"type": "key", "key": "r", "down": True}), None, hold)
    assert reply["type"] == "error" and "keyboard is off" in reply["message"]


# -- the runner with a task ------------------------------------------------------------------


def test_choosing_a_task_reopens_the_session_in_its_scene_and_the_page_draws_it(tmp_path) -> None:
    runner = _runner(tmp_path, task=None)
    try:
        assert runner.latest()["task"] is None and runner.describe()["task"] is None
        key = runner.scene_key
        _command(runner, cmd="task", task="pour")
        assert _wait(lambda: (runner.latest()["task"] or {}).get("name") == "pour")
        state = runner.latest()
        assert len(state["task"]["particles"]) == 300 and state["task"]["state"]["total"] == 100
        described = runner.describe()
        assert described["task"]["particles"]["count"] == 100 and runner.scene_key != key
        assert described["tasks"] == ["none", "pick_place", "pour"]
        assert {row["key"] for row in described["keys"]} >= {"w", "s", "g"}
        _command(runner, cmd="task", task="kitchen")  # unknown: one line, nothing changes
        assert any("unknown task" in m for m in runner.latest()["messages"])
        assert runner.task_name == "pour"
        _command(runner, cmd="task", task="none")
        assert _wait(lambda: runner.latest()["task"] is None)
    finally:
        runner.close()


def test_a_held_key_moves_the_tcp_along_its_axis_and_the_gripper_key_closes(tmp_path) -> None:
    runner = _runner(tmp_path)
    try:
        hold = PageHold()
        _command(runner, cmd="interface", interface="keyboard")
        before = _tcp(runner)
        z_axis = np.array(runner.latest()["robot"]["tcp"]["z_axis"])
        handle_input(runner.inputs, {"type": "key", "key": "r", "down": True}, hold)
        assert _wait(lambda: np.linalg.norm(_tcp(runner) - before) > 0.02)
        handle_input(runner.inputs, {"type": "key", "key": "r", "down": False}, hold)
        moved = _tcp(runner) - before  # r is swipe_up: translate +z (tool frame)
        assert moved @ z_axis / np.linalg.norm(moved) > 0.95
        width = runner.task.physics.gripper_state().width
        handle_input(runner.inputs, {"type": "key", "key": "g", "down": True}, hold)
        assert _wait(lambda: runner.latest()["teleop"]["gripper_closed"])
        assert _wait(lambda: runner.task.physics.gripper_state().width < width - 0.02)
        teleop = runner.latest()["teleop"]
        assert teleop["interface"] == "keyboard" and teleop["commands"] == 2
    finally:
        runner.close()


def test_the_pendant_steps_by_its_increment_in_the_base_frame(tmp_path) -> None:
    runner = _runner(tmp_path)
    try:
        hold = PageHold()
        _command(runner, cmd="interface", interface="pendant")
        assert runner.latest()["teleop"]["pendant"]["frame"] == "base"
        handle_input(runner.inputs, {"type": "pendant", "op": "step", "value": 10}, hold)
        before = _tcp(runner)
        press = {"type": "pendant", "op": "press", "axis": "x", "sign": 1}
        handle_input(runner.inputs, press, hold)
        assert not hold.jog  # a step is one increment, nothing stays held
        assert _wait(lambda: _tcp(runner)[0] - before[0] > 0.0095)
        time.sleep(0.3)
        moved = _tcp(runner) - before
        assert moved[0] == pytest.approx(0.010, abs=0.001)
        assert np.hypot(moved[1], moved[2]) < 0.001
        assert runner.latest()["teleop"]["commands"] == 2  # the step mode and the step
    finally:
        runner.close()


def test_a_trial_from_the_study_panel_writes_its_folder_and_row(tmp_path) -> None:
    study = tmp_path / "study"
    init_study(study, "dashboard")
    add_participant(study, "P01", "novice")
    runner = _runner(tmp_path, study_dir=study)
    try:
        _command(runner, cmd="trial", op="start", participant="P01")  # the skin is chosen
        assert runner.latest()["study"]["running"] and runner.latest()["study"]["trial"] == 1
        _command(runner, cmd="interface", interface="keyboard")  # refused while it runs
        assert runner.inputs.interface == "skin"
        _command(runner, cmd="gripper")  # the page's gripper button: one command
        assert _wait(lambda: runner.latest()["study"]["started"])
        _command(runner, cmd="trial", op="success")
        assert _wait(lambda: not runner.latest()["study"]["running"])
        last = runner.latest()["study"]["last"]
        assert last["outcome"] == "success" and last["commands"] == 1
        summary = json.loads((study / "trials/P01/pick_place-skin-1/trial.json").read_text())
        assert summary["commands"] == 1 and summary["commands_by_kind"]["gripper"] == 1
        assert summary["expertise"] == "novice" and summary["outcome"] == "success"
        trials, problems = read_trials(study)
        assert len(trials) == 1 and problems == []
        assert (study / "trials.csv").read_text().count("\n") == 2  # header and the trial
        assert next_trial(study, "P01", "pick_place", "skin") == 2
        assert runner.latest()["teleop"]["gripper_closed"]  # the trial ended with it closed
        _command(runner, cmd="trial", op="start", participant="P01")  # the reset opens it:
        assert not runner.latest()["teleop"]["gripper_closed"]  # the next toggle closes it
        _command(runner, cmd="trial", op="abort")
    finally:
        runner.close()


def test_a_trial_needs_a_study_a_task_and_a_known_participant(tmp_path) -> None:
    with pytest.raises(ValueError, match="no study folder"):
        StudyPanel(None).start(None, object(), "skin", "P01", 0.0)
    init_study(tmp_path / "s", "x")
    panel = StudyPanel(tmp_path / "s")
    with pytest.raises(ValueError, match="choose a task"):
        panel.start(None, None, "skin", "P01", 0.0)
    with pytest.raises(ValueError, match="no participant"):
        panel.start(None, make_task("pick_place"), "skin", "P09", 0.0)
    with pytest.raises(ValueError, match="no trial is running"):
        panel.end(0.0, "success")
    assert panel.part(0.0) == {"folder": str(tmp_path / "s"), "running": False, "last": None}


def test_the_skin_registered_interface_reads_gestures_in_the_patch_frame(tmp_path) -> None:
    runner = _runner(tmp_path)
    try:
        assert runner.session.gesture_frame is None  # the paper's tool-frame mapping
        _command(runner, cmd="interface", interface="skin_registered")
        assert runner.latest()["teleop"]["interface"] == "skin_registered"
        assert runner.session.gesture_frame == "skin"
        _command(runner, cmd="task", task="pour")  # a new session keeps the interface's frame
        assert _wait(lambda: runner.task is not None and runner.task.name == "pour")
        assert _wait(lambda: runner.session.gesture_frame == "skin")
        _command(runner, cmd="interface", interface="skin")
        assert runner.session.gesture_frame is None
        assert "skin_registered" in runner.describe()["interfaces"]
    finally:
        runner.close()
