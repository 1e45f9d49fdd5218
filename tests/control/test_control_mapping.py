"""The action mapping: the packaged default, validation errors, and tool-to-base twists."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.conftest import SHARED
from wovenskin.control.mapping import ActionMapping, MotionSettings, PoseAction, TwistAction
from wovenskin.gestures import CLASS_NAMES, GESTURE_NAMES
from wovenskin.robots.base import Pose


def gestures_md_table() -> dict[str, str]:
    """name -> default action, read from GESTURES.md itself."""
    rows = re.findall(r"^\| `(\w+)` \|.*\| ([^|]+) \|$", (SHARED / "GESTURES.md").read_text(), re.M)
    return {name: action.strip() for name, action in rows}


def expected_spec(action: str) -> str:
    """GESTURES.md's wording in the mapping file's grammar."""
    if action.startswith(("translate", "rotate")):
        return action.split(" (")[0]
    if "initial pose" in action:
        return "pose initial"
    if "home" in action:
        return "pose home"
    assert action == "no action", action
    return "none"


def test_the_default_mapping_is_the_gestures_md_table() -> None:
    mapping = ActionMapping.load()
    table = gestures_md_table() if (SHARED / "GESTURES.md").exists() else {}
    if not table:
        pytest.skip("GESTURES.md is not available")
    assert sorted(table) == sorted(CLASS_NAMES)
    for name, action in table.items():
        mapped = mapping.action_for(name)
        assert (str(mapped) if mapped is not None else "none") == expected_spec(action), name


def test_default_motion_settings_and_pose_actions() -> None:
    mapping = ActionMapping.load()
    s = mapping.settings
    assert s.frame == "tool"
    assert s.linear_speed == pytest.approx(0.05)
    assert s.angular_speed == pytest.approx(math.radians(15))  # stored in deg, read in rad
    assert s.linear_accel > 0 and s.linear_jerk > 0 and s.angular_accel > 0
    assert s.angular_jerk > 0
    assert mapping.action_for("pinch_in_5f") == PoseAction("initial", hold_to_run=True)
    assert mapping.action_for("pinch_out_5f") == PoseAction("home", hold_to_run=True)
    assert mapping.action_for("invalid") is None and mapping.action_for(None) is None
    assert all(isinstance(mapping.action_for(g), TwistAction) for g in GESTURE_NAMES[:12])


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "mapping.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('[gestures]\nswipe_sideways = "translate +x"\n', "gestures.swipe_sideways"),
        ('[gestures]\nswipe_up = "translate +w"\n', "gestures.swipe_up"),
        ('[gestures]\nswipe_up = "rotate"\n', "gestures.swipe_up"),
        ('[gestures]\nswipe_up = "pose nowhere"\n', "gestures.swipe_up"),
        ('[gestures]\ninvalid = "translate +x"\n', "gestures.invalid"),
        ("[gestures]\nswipe_up = 3\n", "gestures.swipe_up"),
        ("[motion]\nlinear_speed = -0.05\n", "motion.linear_speed"),
        ("[motion]\nangular_speed = nan\n", "motion.angular_speed"),
        ("[motion]\nlinear_jerk = true\n", "motion.linear_jerk"),
        ('[motion]\nframe = "world"\n', "motion.frame"),
        ("[motion]\nspeed = 1.0\n", "motion.speed"),
        ('[poses]\nhold_to_run = "yes"\n', "poses.hold_to_run"),
        ("[motion\n", "not valid TOML"),
    ],
)
def test_bad_files_give_one_line_naming_file_and_key(tmp_path, text: str, key: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(ValueError) as info:
        ActionMapping.load(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(str(path)) and key in message


def test_a_missing_file_is_a_one_line_error(tmp_path) -> None:
    with pytest.raises(ValueError, match="cannot read"):
        ActionMapping.load(tmp_path / "absent.toml")


def test_an_edited_file_changes_speeds_frame_and_hold_to_run(tmp_path) -> None:
    path = write(
        tmp_path,
        '[motion]\nframe = "base"\nlinear_speed = 0.02\nangular_speed = 30\n'
        "[poses]\nhold_to_run = false\n"
        '[gestures]\npush = "rotate -z"\nswipe_up = "pose home"\n',
    )
    mapping = ActionMapping.load(path)
    assert mapping.settings == MotionSettings(
        frame="base", linear_speed=0.02, angular_speed=math.radians(30)
    )
    assert mapping.action_for("swipe_up") == PoseAction("home", hold_to_run=False)
    assert mapping.action_for("swipe_down") is None  # left out: does nothing
    tilted = Pose([0.3, 0.0, 0.4], [math.cos(0.3), math.sin(0.3), 0.0, 0.0])
    twist = mapping.target_twist("push", tilted)  # base frame: the TCP's turn is ignored
    np.testing.assert_allclose(twist, [0, 0, 0, 0, 0, -math.radians(30)], atol=1e-12)


def random_pose(draw_angles: tuple[float, float, float]) -> Pose:
    roll, pitch, yaw = draw_angles
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    quat = [
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ]
    return Pose([0.4, -0.1, 0.3], quat)


angles = st.tuples(*(st.floats(-math.pi, math.pi) for _ in range(3)))


@settings(max_examples=60, deadline=None)
@given(angles, st.sampled_from(GESTURE_NAMES[:12]))
def test_tool_frame_twists_turn_with_the_tcp(rpy, gesture: str) -> None:
    mapping = ActionMapping.load()
    tcp = random_pose(rpy)
    twist = mapping.target_twist(gesture, tcp)
    action = mapping.action_for(gesture)
    rotation = tcp.rotation()
    tool_axis = rotation.T @ (twist[:3] if action.kind == "translate" else twist[3:])
    other = twist[3:] if action.kind == "translate" else twist[:3]
    speed = mapping.settings.linear_speed if action.kind == "translate" else (
        mapping.settings.angular_speed
    )  # fmt: skip
    np.testing.assert_allclose(tool_axis, action.axis * speed, atol=1e-12)
    np.testing.assert_allclose(other, 0.0)


def test_tool_frame_example_tool_pointing_down() -> None:
    mapping = ActionMapping.load()
    down = Pose([0.5, 0.0, 0.3], [0.0, 1.0, 0.0, 0.0])  # tool z along base -z, x along base x
    np.testing.assert_allclose(mapping.target_twist("swipe_up", down), [0, 0, -0.05, 0, 0, 0])
    np.testing.assert_allclose(mapping.target_twist("swipe_right", down), [0, -0.05, 0, 0, 0, 0])
    w = math.radians(15)
    np.testing.assert_allclose(mapping.target_twist("circle_cw_2f", down), [0, 0, 0, w, 0, 0])
    np.testing.assert_allclose(mapping.target_twist("swipe_up_2f", down), [0, 0, 0, 0, -w, 0])


def test_pose_and_empty_actions_give_a_zero_twist() -> None:
    mapping = ActionMapping.load()
    tcp = Pose([0.5, 0.0, 0.3], [1.0, 0.0, 0.0, 0.0])
    for gesture in ("pinch_in_5f", "pinch_out_5f", "invalid", None):
        assert not np.any(mapping.target_twist(gesture, tcp))


def test_motion_settings_refuse_bad_values() -> None:
    with pytest.raises(ValueError, match="linear_speed"):
        MotionSettings(linear_speed=0.0)
    with pytest.raises(ValueError, match="frame"):
        MotionSettings(frame="world")  # type: ignore[arg-type]
