"""Tests of wovenskin.robots.base: poses, states and command validation."""

from __future__ import annotations

import numpy as np
import pytest

from wovenskin.robots.base import (
    Pose,
    Robot,
    RobotCapabilities,
    RobotState,
    finite_vector,
    rotation_angle,
)
from wovenskin.robots.sim import SimRobot, tm5_900
from wovenskin.robots.techman import TechmanRobot


def test_finite_vector_accepts_numbers_and_names_what_is_wrong() -> None:
    np.testing.assert_array_equal(finite_vector([1, 2, 3], 3, "twist"), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="twist is not numeric"):
        finite_vector(["a", 1, 2], 3, "twist")
    with pytest.raises(ValueError, match=r"joint target must have shape \(6,\), got \(5,\)"):
        finite_vector(np.zeros(5), 6, "joint target")
    with pytest.raises(ValueError, match="twist has non-finite values"):
        finite_vector([0.0, np.nan, 0.0], 3, "twist")


def test_finite_vector_copies_its_input() -> None:
    source = np.zeros(6)
    finite_vector(source, 6, "twist")[0] = 1.0
    assert source[0] == 0.0


def test_pose_normalises_its_quaternion_and_gives_the_rotation() -> None:
    pose = Pose([0.1, 0.2, 0.3], [2.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(pose.quat, [1.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(pose.rotation(), np.eye(3))
    half = np.sqrt(0.5)
    about_z = Pose([0, 0, 0], [half, 0.0, 0.0, half]).rotation()
    np.testing.assert_allclose(about_z @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-12)


def test_pose_refuses_non_finite_values_and_a_zero_quaternion() -> None:
    with pytest.raises(ValueError, match="non-finite"):
        Pose([np.nan, 0, 0], [1, 0, 0, 0])
    with pytest.raises(ValueError, match="zero norm"):
        Pose([0, 0, 0], [0, 0, 0, 0])


def test_state_reports_the_linear_tcp_speed() -> None:
    state = RobotState(
        t=0.0,
        q=np.zeros(6),
        dq=np.zeros(6),
        tcp=Pose([0, 0, 0], [1, 0, 0, 0]),
        tcp_twist=np.array([0.03, 0.04, 0.0, 1.0, 0.0, 0.0]),
    )
    assert state.tcp_speed == pytest.approx(0.05)


# -- what a backend declares -------------------------------------------------------------


def test_a_backend_declares_nothing_unless_it_says_so() -> None:
    assert Robot.capabilities(object()) == RobotCapabilities()  # type: ignore[arg-type]
    empty = RobotCapabilities()
    assert empty.kinematics is None and empty.scene is None and empty.default_poses == {}
    assert empty.stop_time(np.ones(6)) is None and not Robot.degraded_safety


def test_the_stop_time_comes_from_a_ramp_or_a_deceleration() -> None:
    twist = np.array([0.3, 0.0, 0.4, 0.0, 1.0, 0.0])  # 0.5 m/s, 1 rad/s
    assert RobotCapabilities(stop_time_s=0.1).stop_time(twist) == pytest.approx(0.1)
    decel = RobotCapabilities(stop_deceleration=(2.0, 4.0))
    assert decel.stop_time(twist) == pytest.approx(0.25)  # the linear part is the slower
    both = RobotCapabilities(stop_time_s=0.3, stop_deceleration=(2.0, 4.0))
    assert both.stop_time(twist) == pytest.approx(0.3)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"stop_time_s": -0.1}, "stop_time_s"),
        ({"stop_time_s": float("nan")}, "stop_time_s"),
        ({"stop_deceleration": (0.0, 1.0)}, "stop_deceleration"),
        ({"tracking_error": 1.5}, "tracking_error"),
        ({"control_period_s": -1.0}, "control_period_s"),
        ({"default_poses": {"home": [0.0] * 5}}, "default pose 'home'"),
        ({"default_poses": {"home": [np.nan] * 6}}, "default pose 'home'"),
    ],
)
def test_a_bad_declaration_is_refused_in_one_line(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match) as info:
        RobotCapabilities(**kwargs)
    assert "\n" not in str(info.value)


def test_every_backend_declares_its_kinematics_and_scene() -> None:
    for robot in (SimRobot(), TechmanRobot("127.0.0.1")):  # built, never connected
        declared = robot.capabilities()
        assert declared.kinematics is not None and declared.scene is not None
        q = tm5_900.INITIAL_Q
        np.testing.assert_allclose(declared.kinematics.forward(q), tm5_900.forward_kinematics(q))
    sim = SimRobot().capabilities()
    np.testing.assert_allclose(sim.default_poses["initial"], tm5_900.INITIAL_Q)
    assert sim.stop_time_s is not None and sim.control_period_s > 0.0
    assert TechmanRobot("127.0.0.1").capabilities().default_poses == {}


def test_rotation_angle_reads_how_far_a_rotation_turns() -> None:
    def about_z(angle: float) -> np.ndarray:
        c, s = np.cos(angle), np.sin(angle)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    assert rotation_angle(np.eye(3)) == 0.0
    assert rotation_angle(about_z(0.3)) == pytest.approx(0.3)
    assert rotation_angle(about_z(-2.0)) == pytest.approx(2.0)
    assert rotation_angle(np.diag([1.0, -1.0, -1.0]) * (1 + 1e-12)) == pytest.approx(np.pi)
