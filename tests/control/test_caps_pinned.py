"""The caps, the dwell and the mapping's speeds pinned to their documented numbers.

Other tests compare against the limits object's own values, so a changed default passes
them.  These write the numbers of docs/safety.md and docs/gestures.md out as literals:
changing a default means changing this file and the page that documents it, on purpose.
Each value is also checked by what it does (the twist the robot receives, the stop the
watchdog makes), so a default overridden elsewhere on the way fails too.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from paths import REPO
from test_control_safety import Clock, GantryRobot

from wovenskin.control.joint_moves import CAP_SAFETY_FACTOR
from wovenskin.control.mapping import ActionMapping
from wovenskin.control.safety import MOVE_SPEED_TOLERANCE, SafetyLayer
from wovenskin.control.safety_limits import SafetyLimits
from wovenskin.recognition.arbiter import ArbiterSettings
from wovenskin.recognition.pipeline import load_recognizer, pipeline_settings_for_model

DOCS = REPO / "docs"

# docs/safety.md, "What it enforces"
TCP_SPEED_M_S = 0.250  # 250 mm/s (ISO 10218-1 reduced speed)
ANGULAR_SPEED_DEG_S = 60.0
WATCHDOG_S = 0.100  # 100 ms of silence
JOINT_MARGIN_DEG = 5.0
BOX_LOWER = (-0.8, -0.8, 0.05)  # m
BOX_UPPER = (0.8, 0.8, 1.2)
ASSUMED_STOP_TIME_S = 0.3
JOINT_LOOKAHEAD_S = 0.020  # "The look-ahead of the joint margins (20 ms)
BOX_LOOKAHEAD_S = 0.100  # and of the box (100 ms)"
MOVE_SLOWDOWN = 0.90  # point-to-point moves "slowed to 90 % of the caps"
MOVE_STOP_ABOVE = 1.02  # "a running move that goes faster than 102 % of either cap"
# docs/gestures.md: the dwell and "Full speeds: 50 mm/s and 15 deg/s by default"
DWELL_S = 0.100
LINEAR_SPEED_M_S = 0.050
MAPPING_ANGULAR_SPEED_DEG_S = 15.0


def test_the_safety_limits_are_the_documented_ones() -> None:
    limits = SafetyLimits()
    assert limits.max_linear_speed == pytest.approx(TCP_SPEED_M_S)
    assert math.degrees(limits.max_angular_speed) == pytest.approx(ANGULAR_SPEED_DEG_S)
    assert limits.watchdog_s == pytest.approx(WATCHDOG_S)
    assert math.degrees(limits.joint_margin) == pytest.approx(JOINT_MARGIN_DEG)
    np.testing.assert_allclose(limits.workspace_lower, BOX_LOWER)
    np.testing.assert_allclose(limits.workspace_upper, BOX_UPPER)
    assert limits.assumed_stop_time_s == pytest.approx(ASSUMED_STOP_TIME_S)
    assert limits.joint_horizon_s == pytest.approx(JOINT_LOOKAHEAD_S)
    assert limits.box_horizon_s == pytest.approx(BOX_LOOKAHEAD_S)
    assert pytest.approx(MOVE_SLOWDOWN) == CAP_SAFETY_FACTOR
    assert pytest.approx(MOVE_STOP_ABOVE) == MOVE_SPEED_TOLERANCE


def _page(name: str) -> str:
    """A docs page with its white space folded (a rewrap does not matter)."""
    return " ".join((DOCS / name).read_text(encoding="utf-8").split())


def test_the_safety_page_documents_these_numbers() -> None:
    page = _page("safety.md")
    for row in (
        "| TCP linear speed | 250 mm/s (ISO 10218-1 reduced speed) |",
        "| TCP angular speed | 60 deg/s |",
        "| Joint margins | 5 deg from every joint limit |",
        "| Watchdogs | 100 ms of silence of the skin or the command stream |",
        "| Workspace box | x, y in [-0.8, 0.8] m, z in [0.05, 1.2] m |",
    ):
        assert row in page, row
    assert "`assumed_stop_time_s` (0.3 s)" in page
    assert "slowed to 90 % of the caps" in page and "faster than 102 % of either cap" in page


def _default_layer() -> tuple[SafetyLayer, GantryRobot, Clock]:
    """A layer with no limits given (the defaults every session gets) over an arm that
    follows each twist exactly, well inside the default box."""
    robot, clock = GantryRobot(), Clock()
    layer = SafetyLayer(robot, clock=clock)
    layer.connect()
    return layer, robot, clock


@pytest.mark.parametrize("asked", [2.0, 10.0])  # rad/s: 115 and 573 deg/s
def test_a_fast_turn_reaches_the_arm_at_60_deg_per_s(asked: float) -> None:
    layer, robot, _ = _default_layer()
    layer.send_twist(np.array([0.0, 0.0, 0.0, 0.0, asked, 0.0]))
    sent = robot.received[-1]
    assert math.degrees(float(np.linalg.norm(sent[3:]))) == pytest.approx(ANGULAR_SPEED_DEG_S)
    assert sent[4] > 0 and np.allclose(sent[[0, 1, 2, 3, 5]], 0.0)  # direction kept
    assert layer.limiting == ("speed cap: rotation limited to 60 deg/s",)


@pytest.mark.parametrize("asked", [0.6, 5.0])  # m/s
def test_a_fast_move_reaches_the_arm_at_250_mm_per_s(asked: float) -> None:
    layer, robot, _ = _default_layer()
    layer.send_twist(np.array([asked, 0.0, 0.0, 0.0, 0.0, 0.0]))
    sent = robot.received[-1]
    assert 1000 * float(np.linalg.norm(sent[:3])) == pytest.approx(1000 * TCP_SPEED_M_S)
    assert layer.limiting == ("speed cap: TCP speed limited to 250 mm/s",)


def test_a_twist_under_the_caps_goes_through_unchanged() -> None:
    layer, robot, _ = _default_layer()
    twist = np.array([0.2, 0.0, 0.0, 0.0, 0.0, math.radians(55.0)])
    layer.send_twist(twist)
    np.testing.assert_allclose(robot.received[-1], twist)


def test_the_watchdog_stops_after_100_ms_of_silence() -> None:
    layer, _, clock = _default_layer()
    layer.heartbeat_skin(0.0)
    layer.heartbeat_command(0.0)
    assert layer.check(0.095) == []
    fired = layer.check(0.105)
    assert [event.source for event in fired] == ["skin watchdog"]


def test_the_dwell_is_100_ms_for_the_shipped_model() -> None:
    assert ArbiterSettings().dwell_s == pytest.approx(DWELL_S)
    settings = pipeline_settings_for_model(load_recognizer(None))
    assert settings.arbiter.dwell_s == pytest.approx(DWELL_S)
    assert "recognised continuously for the dwell time (0.1 s by default)" in _page("gestures.md")


def test_the_default_mapping_moves_at_its_documented_speeds() -> None:
    motion = ActionMapping.load().settings
    assert motion.linear_speed == pytest.approx(LINEAR_SPEED_M_S)
    assert math.degrees(motion.angular_speed) == pytest.approx(MAPPING_ANGULAR_SPEED_DEG_S)
    assert motion.linear_accel == pytest.approx(0.5)  # m/s^2
    assert math.degrees(motion.angular_accel) == pytest.approx(150.0)  # deg/s^2
    assert motion.linear_jerk == pytest.approx(10.0)  # m/s^3
    assert math.degrees(motion.angular_jerk) == pytest.approx(3000.0)  # deg/s^3
    profile = motion.profile  # docs/gestures.md, "Speed profile"
    assert profile.kind == "graded"
    assert (profile.start_fraction, profile.fine_s, profile.ramp_s) == pytest.approx(
        (0.2, 0.2, 0.5)
    )
    assert (profile.nudge_mm, profile.nudge_deg) == pytest.approx((1.0, 0.5))
    page = _page("gestures.md")
    assert "Full speeds: 50 mm/s and 15 deg/s by default" in page
    assert "never more than the safety layer's caps (250 mm/s, 60 deg/s)" in page
    # a held gesture's full speed stays under the caps
    assert motion.linear_speed < TCP_SPEED_M_S
    assert math.degrees(motion.angular_speed) < ANGULAR_SPEED_DEG_S
