"""Tests of wovenskin.teleop.pendant: jogs in base, tool and joint frames, step mode, the
speed override and go-to-pose drive the simulated arm through the session; each panel
operation is one command."""

from __future__ import annotations

import math

import numpy as np
import pytest
from session_helpers import at, idle_session, run_traced
from test_teleop_keyboard import Driven

from wovenskin.errors import ConfigError
from wovenskin.robots.sim.tm5_900 import INITIAL_Q
from wovenskin.teleop.pendant import Pendant, jog_name


def jog(tmp_path, setup, seconds: float = 3.5):
    pendant = Pendant(speed_percent=100)
    session = idle_session(tmp_path, seconds=seconds, inputs=[Driven(pendant, setup(pendant))])
    return pendant, session, run_traced(session)


@pytest.mark.parametrize(("frame", "axis", "sign"), [("base", "z", 1), ("tool", "x", -1)])
def test_a_held_button_jogs_along_its_frames_axis_and_stops_on_release(
    tmp_path, frame, axis, sign
) -> None:
    def setup(p):
        return [(1.2, lambda: p.set_frame(frame)), (1.5, lambda: p.press(axis, sign)),
                (2.5, p.release)]  # fmt: skip

    pendant, session, records = jog(tmp_path, setup)
    start, end, later = at(records, 1.5), at(records, 2.6), at(records, 3.4)
    moved = end["tcp"] - start["tcp"]
    index = "xyz".index(axis)
    direction = np.eye(3)[index] if frame == "base" else start["R"][:, index]
    assert moved @ (sign * direction) > 0.98 * np.linalg.norm(moved) > 0.04
    assert np.linalg.norm(later["tcp"] - end["tcp"]) < 0.003 and later["speed"] < 1e-4
    assert [c.kind for c in session.command_log] == ["mode", "press"]
    assert pendant.jogging is None


def test_step_mode_moves_one_increment_per_press(tmp_path) -> None:
    def setup(p):
        return [(1.2, lambda: p.set_step(5)), (1.3, lambda: p.press("y", -1)),
                (1.5, p.release), (2.3, lambda: p.press("y", -1))]  # fmt: skip

    _, session, records = jog(tmp_path, setup)
    moved = records[-1]["tcp"] - at(records, 1.3)["tcp"]
    assert moved == pytest.approx([0.0, -0.010, 0.0], abs=3e-4)  # two steps of 5 mm
    assert [c.kind for c in session.command_log] == ["mode", "step", "step"]


def test_a_joint_step_turns_one_joint_by_the_increment(tmp_path) -> None:
    def setup(p):
        return [(1.2, lambda: p.set_frame("joint")), (1.3, lambda: p.set_step(10)),
                (1.4, lambda: p.press(4, 1))]  # fmt: skip

    _, _, records = jog(tmp_path, setup, seconds=2.5)
    dq = records[-1]["q"] - at(records, 1.4)["q"]
    assert dq == pytest.approx(np.eye(6)[3] * math.radians(10), abs=1e-4)


def test_the_speed_override_scales_the_jog_speed(tmp_path) -> None:
    def setup(p):
        return [(1.2, lambda: p.press("x", 1)), (2.0, p.release), (2.4, lambda: p.set_speed(40)),
                (2.5, lambda: p.press("x", 1)), (3.3, p.release)]  # fmt: skip

    _, session, records = jog(tmp_path, setup, seconds=3.5)
    full = max(r["speed"] for r in records if 1.2 <= r["t"] < 2.0)
    slow = max(r["speed"] for r in records if 2.5 <= r["t"] < 3.3)
    assert full == pytest.approx(0.05, rel=0.03)
    assert slow / full == pytest.approx(0.4, rel=0.03)
    assert session.speed_scale == 0.4


def test_go_to_pose_and_the_command_count(tmp_path) -> None:
    def setup(p):
        return [(1.1, lambda: p.set_frame("joint")), (1.2, lambda: p.step(1, 1, size=10)),
                (2.0, lambda: p.go_to("initial")), (2.1, p.gripper), (2.2, p.release)]  # fmt: skip

    _, session, records = jog(tmp_path, setup, seconds=4.0)
    turned = max(r["q"][0] for r in records if r["t"] < 2.0) - INITIAL_Q[0]
    assert turned == pytest.approx(math.radians(10), abs=2e-3)  # (nearly) all of the step
    assert records[-1]["q"] == pytest.approx(INITIAL_Q, abs=1e-4)  # back at the stored pose
    assert records[-1]["speed"] < 1e-6
    assert [(c.source, c.kind, c.name) for c in session.command_log] == [
        ("pendant", "mode", "frame joint"), ("pendant", "step", "joint 1 +"),
        ("pendant", "go_to", "initial"), ("pendant", "gripper", "toggle"),
    ]  # fmt: skip  # the initial speed and a release with no button held are none
    assert session.gripper_closed


def test_panel_operations_are_checked() -> None:
    assert jog_name("base", "rz", -1) == "rotate -z"
    assert jog_name("tool", "y", 1) == "translate +y"
    assert jog_name("joint", 6, -1) == "joint 6 -" == jog_name("joint", "j6", -1)
    pendant = Pendant()
    for call, match in (
        (lambda: pendant.set_frame("world"), "frame"),
        (lambda: pendant.set_speed(0), "speed"),
        (lambda: pendant.set_speed(float("nan")), "speed"),
        (lambda: pendant.set_step(2), "step"),
        (lambda: pendant.press("q", 1), "axis"),
        (lambda: pendant.press("x", 2), "sign"),
        (lambda: jog_name("joint", 7, 1), "joint"),
        (lambda: pendant.go_to("park"), "pose"),
    ):
        with pytest.raises(ConfigError, match=match):
            call()
    panel = pendant.panel()
    assert panel["frame"] == "base" and panel["speed_percent"] == 50
    assert panel["step_sizes"] == [1, 5, 10] and panel["poses"] == ["initial", "home"]
    events = pendant.poll(0.0)
    assert [(e.kind, e.counts, e.amount) for e in events] == [("speed", False, 0.5)]
    pendant.set_frame("joint")
    assert pendant.panel()["axes"] == [1, 2, 3, 4, 5, 6]
    pendant.go_to("initial", hold=True)
    pendant.release()
    kinds = [(e.kind, e.name) for e in pendant.poll(0.0)]
    assert kinds == [("mode", "frame joint"), ("press", "pose initial"),
                     ("release", "pose initial")]  # fmt: skip
