"""Tests of wovenskin.control.session_inputs: inputs beside the skin drive the simulated arm
through the session's mapping, shaping and safety layer, and every command is counted.

The skin is a replayed contact-free stream (it only clocks the session, 200 Hz); a
scripted input plays events at given session times.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from session_helpers import ScriptedInput, at, idle_session, run_traced

from wovenskin.control.mapping import ActionMapping
from wovenskin.control.session_inputs import (
    CommandRecord,
    InputEvent,
    JointJog,
    active_command,
    parse_joint,
    rotation_matrix,
    rotation_vector,
)
from wovenskin.errors import ConfigError

START_S = 1.0  # the session ticks from here on (after the skin's calibration)


def press(name: str, **kwargs) -> InputEvent:
    return InputEvent("press", name, source="test", **kwargs)


def release(name: str = "") -> InputEvent:
    return InputEvent("release", name, source="test", counts=False)


def test_a_held_press_moves_along_the_mapped_axis_and_the_release_stops(tmp_path) -> None:
    script = ScriptedInput([(1.5, press("translate +x", frame="base")), (2.5, release())])
    session = idle_session(tmp_path, inputs=[script])
    records = run_traced(session)
    assert records[0]["t"] <= 1.5
    start, end, later = at(records, 1.5), at(records, 2.6), at(records, 3.5)
    moved = end["tcp"] - start["tcp"]
    speed = ActionMapping.load().settings.linear_speed
    assert moved[0] == pytest.approx(speed * 1.0, rel=0.15)  # 1 s at 50 mm/s, less the ramps
    assert np.linalg.norm(moved[1:]) < 1e-3
    assert np.linalg.norm(later["tcp"] - end["tcp"]) < 0.003  # it stopped on release
    assert at(records, 3.0)["speed"] < 1e-4
    assert session.command_log == [CommandRecord(1.5, "test", "translate +x", "press")]
    assert session.command_count == 1 and session.held_input is None


def test_a_gesture_name_press_takes_the_mapping_and_its_frame(tmp_path) -> None:
    script = ScriptedInput([(1.5, press("swipe_up")), (2.0, release("swipe_up"))])
    session = idle_session(tmp_path, inputs=[script])
    records = run_traced(session)
    start, end = at(records, 1.5), at(records, 2.2)
    tool_z = start["R"][:, 2]  # swipe_up: translate +z of the tool
    moved = end["tcp"] - start["tcp"]
    assert moved @ tool_z > 0.98 * np.linalg.norm(moved) > 0.015


def test_a_joint_jog_turns_one_joint(tmp_path) -> None:
    script = ScriptedInput([(1.5, press("joint 1 +", frame="joint")), (2.5, release())])
    session = idle_session(tmp_path, inputs=[script])
    records = run_traced(session)
    dq = at(records, 3.0)["q"] - at(records, 1.5)["q"]
    assert dq[0] > math.radians(3)  # up to 15 deg/s, kept under 50 mm/s at the TCP
    assert np.all(np.abs(dq[1:]) < 0.1 * dq[0])  # the IK resolves the twist: a few %


@pytest.mark.parametrize(
    ("name", "frame", "amount"),
    [("translate +x", "base", 0.005), ("translate -z", "tool", 0.01),
     ("rotate +z", "tool", math.radians(5)), ("joint 6 -", "joint", math.radians(10))],
)  # fmt: skip
def test_a_step_moves_by_its_increment(tmp_path, name, frame, amount) -> None:
    event = InputEvent("step", name, source="test", frame=frame, amount=amount)
    session = idle_session(tmp_path, seconds=3.0, inputs=[ScriptedInput([(1.5, event)])])
    records = run_traced(session)
    before, after = at(records, 1.5), records[-1]
    assert after["speed"] < 1e-6 and after["action"] == "-"
    moved = after["tcp"] - before["tcp"]
    turned = rotation_vector(after["R"] @ before["R"].T)
    if name == "translate +x":
        assert moved == pytest.approx([amount, 0, 0], abs=2e-4)
        assert np.linalg.norm(turned) < 1e-3
    elif name == "translate -z":
        assert moved == pytest.approx(-amount * before["R"][:, 2], abs=2e-4)
    elif name == "rotate +z":
        assert turned == pytest.approx(amount * before["R"][:, 2], abs=1e-3)
        assert np.linalg.norm(moved) < 2e-4  # turns about the TCP
    else:
        dq = after["q"] - before["q"]
        assert dq[5] == pytest.approx(-amount, abs=1e-4)
        assert np.all(np.abs(dq[:5]) < 1e-6)
    assert session.command_count == 1


def test_speed_override_gripper_go_to_and_bad_names_are_counted(tmp_path) -> None:
    closed: list[bool] = []
    script = ScriptedInput(
        [
            (1.2, InputEvent("speed", "speed 50 %", source="pendant", amount=0.5)),
            (1.3, InputEvent("gripper", "toggle", source="keyboard")),
            (1.4, InputEvent("gripper", "toggle", source="keyboard")),
            (1.5, InputEvent("mode", "frame tool", source="pendant")),
            (1.6, press("joint 9 +")),
            (1.7, InputEvent("go_to", "home", source="pendant")),
        ]
    )
    session = idle_session(tmp_path, seconds=2.0, inputs=[script])
    session.on_gripper = closed.append
    session.run()
    session.close()
    assert closed == [True, False] and not session.gripper_closed
    assert session.speed_scale == 0.5
    assert [(c.source, c.kind) for c in session.command_log] == [
        ("pendant", "speed"), ("keyboard", "gripper"), ("keyboard", "gripper"),
        ("pendant", "mode"), ("test", "press"), ("pendant", "go_to"),
    ]  # fmt: skip
    assert "joint 9" in session.state.last_error  # one line, no motion, still counted
    assert "home" in session.state.action


def test_the_newest_of_gesture_and_held_input_is_the_active_command(tmp_path) -> None:
    session = idle_session(tmp_path, seconds=1.0)
    session.state.gesture, session.state.gesture_since = "swipe_up", 1.0
    session.apply_input(press("translate +x"), t=2.0)
    state = session.state
    label, action, _, since = active_command(
        session.inputs, state.gesture, state.gesture_since, session.mapping
    )
    assert label == "translate +x (test)" and since == 2.0 and str(action) == "translate +x"
    state.gesture_since = 3.0
    assert active_command(session.inputs, "swipe_up", 3.0, session.mapping).label == "swipe_up"
    session.apply_input(release("translate +x"), t=3.5)
    assert session.held_input is None and session.state.held is None
    session.close()


def test_events_and_joint_names_are_checked() -> None:
    assert parse_joint("joint 3 -") == JointJog(2, -1.0) and str(JointJog(2, -1.0)) == "joint 3 -"
    assert parse_joint("translate +x") is None
    for bad in ("joint 0 +", "joint 7 -", "joint 2 x"):
        with pytest.raises(ConfigError, match="joint"):
            parse_joint(bad)
    with pytest.raises(ConfigError, match="kind"):
        InputEvent("hold", "x")
    with pytest.raises(ConfigError, match="frame"):
        InputEvent("press", "translate +x", frame="world")
    with pytest.raises(ConfigError, match="finite"):
        InputEvent("step", "translate +x", amount=float("nan"))
    vector = np.array([0.1, -0.2, 0.3])
    assert rotation_vector(rotation_matrix(vector)) == pytest.approx(vector)
    assert json.dumps(CommandRecord(1.0, "a", "b", "c").__dict__)
