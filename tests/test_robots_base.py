"""Tests of wovenskin.robots.base: poses, states and command validation."""

from __future__ import annotations

import numpy as np
import pytest

from wovenskin.robots.base import Pose, RobotState, finite_vector


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
