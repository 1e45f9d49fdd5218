"""open_session on a study task's scene, with inputs beside (or instead of) the skin."""

from __future__ import annotations

import numpy as np
import pytest

from wovenskin.control.safety_limits import SafetyLimits
from wovenskin.errors import ConfigError
from wovenskin.robots.sim.robot import SimRobot
from wovenskin.runtime import open_session
from wovenskin.tasks import WORKSPACE_LOWER, WORKSPACE_UPPER, PourTask
from wovenskin.teleop.keyboard import Keyboard


def test_a_task_session_runs_the_scene_arm_in_the_task_box():
    session = open_session("none:speed=0", task="pick_place")
    try:
        assert session.task.name == "pick_place"
        assert isinstance(session.robot, SimRobot)
        assert session.robot.physics is session.task.physics
        assert np.allclose(session.safety.limits.workspace_lower, WORKSPACE_LOWER)
        assert np.allclose(session.safety.limits.workspace_upper, WORKSPACE_UPPER)
        assert session.recording_context["session"]["task"] == "pick_place"
    finally:
        session.close()


def test_a_task_object_and_given_limits_are_kept():
    task = PourTask()
    limits = SafetyLimits(watchdog_s=0.2)
    session = open_session("none:speed=0", task=task, limits=limits)
    try:
        assert session.task is task and session.safety.limits.watchdog_s == 0.2
    finally:
        session.close()


def test_no_task_means_task_none():
    session = open_session("none:speed=0")
    try:
        assert session.task is None
    finally:
        session.close()


@pytest.mark.parametrize("robot", ["tm:192.168.1.10", "ur:10.0.0.2"])
def test_a_task_on_a_real_arm_is_one_line(robot):
    with pytest.raises(ConfigError, match="tasks run on the simulated arm") as info:
        open_session("none:speed=0", robot=robot, task="pour")
    assert "\n" not in str(info.value)


def test_unknown_task_is_one_line():
    with pytest.raises(ConfigError, match="unknown task"):
        open_session("none:speed=0", task="juggle")


@pytest.mark.slow
def test_a_keyboard_alone_moves_the_arm_without_a_skin():
    keyboard = Keyboard()

    def press_then_release(session):
        if abs(session.now - 0.8) < 1e-9:
            keyboard.key_down("r")  # swipe_up: translate +z in the tool frame
        if abs(session.now - 1.6) < 1e-9:
            keyboard.key_up("r")

    session = open_session(
        "none:speed=0", task="pick_place", inputs=[keyboard], on_tick=press_then_release
    )
    session.task.reset(1)
    try:
        session.start()
        start = session.safety.state().tcp.position.copy()
        result = session.run(seconds=2.0)
        end = session.state.robot.tcp.position
    finally:
        session.close()
    assert result.stops == [] and session.command_count == 1
    assert session.command_log[0].source == "keyboard"
    assert np.linalg.norm(end - start) > 0.02  # about 50 mm/s for 0.8 s
