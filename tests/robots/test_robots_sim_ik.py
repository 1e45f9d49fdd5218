"""Differential IK: speed and direction kept, limits scale the whole twist, singularities."""

import mujoco
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from wovenskin.robots.sim import tm5_900
from wovenskin.robots.sim.ik import DifferentialIK, IKInfo, SingularityThresholds
from wovenskin.robots.sim.tm5_900 import load_model

DT = 1.0 / 250.0
LIMITS = tm5_900.JOINT_LIMITS
THRESHOLDS = SingularityThresholds()


@pytest.fixture(scope="module")
def ik() -> DifferentialIK:
    return DifferentialIK(load_model(), LIMITS)


def unit_vectors(size: int) -> st.SearchStrategy[np.ndarray]:
    return (
        st.lists(st.floats(-1.0, 1.0), min_size=size, max_size=size)
        .map(np.array)
        .filter(lambda v: np.linalg.norm(v) > 0.1)
        .map(lambda v: v / np.linalg.norm(v))
    )


def assert_same_direction(achieved: np.ndarray, commanded: np.ndarray) -> None:
    cos = achieved @ commanded / (np.linalg.norm(achieved) * np.linalg.norm(commanded))
    assert cos > 0.999


def rotation_angle(rotation: np.ndarray) -> float:
    """The angle (rad) that the rotation matrix ``rotation`` turns through."""
    return float(np.arccos(np.clip((np.trace(rotation) - 1) / 2, -1, 1)))


def follow_twist(
    ik: DifferentialIK, twist: np.ndarray, steps: int
) -> tuple[np.ndarray, np.ndarray, IKInfo]:
    """The TCP pose before and after ``steps`` IK steps of ``twist`` from the initial
    joints, with the last step's info."""
    q = tm5_900.INITIAL_Q.copy()
    start = tm5_900.forward_kinematics(q)
    for _ in range(steps):
        velocity, info = ik.step(q, twist, DT)
        q = q + velocity * DT
    return start, tm5_900.forward_kinematics(q), info


def joint_speed_ratio(q: np.ndarray, twist: np.ndarray) -> float:
    """The largest joint speed that ``twist`` needs at ``q``, over that joint's limit."""
    unlimited = np.linalg.solve(tm5_900.jacobian(q), twist)
    return float(np.max(np.abs(unlimited) / LIMITS.max_speed))


@settings(max_examples=50, deadline=None)
@given(direction=unit_vectors(3), speed=st.floats(0.01, 0.25))
def test_linear_twist_moves_the_tcp_that_way_at_that_speed(
    ik: DifferentialIK, direction: np.ndarray, speed: float
) -> None:
    steps = 25
    twist = np.concatenate([speed * direction, np.zeros(3)])
    start, end, info = follow_twist(ik, twist, steps)
    moved = (end[:3, 3] - start[:3, 3]) / (steps * DT)
    assert info.limited_by is None and info.scale == 1.0
    assert np.linalg.norm(moved - speed * direction) < 0.02 * speed
    assert rotation_angle(start[:3, :3].T @ end[:3, :3]) < 1e-5


@settings(max_examples=50, deadline=None)
@given(axis=unit_vectors(3), rate=st.floats(0.05, 0.5))
def test_angular_twist_turns_the_tool_about_a_fixed_tcp(
    ik: DifferentialIK, axis: np.ndarray, rate: float
) -> None:
    steps = 25
    start, end, _ = follow_twist(ik, np.concatenate([np.zeros(3), rate * axis]), steps)
    relative = end[:3, :3] @ start[:3, :3].T
    angle = rotation_angle(relative)
    turned_axis = np.array(
        [
            relative[2, 1] - relative[1, 2],
            relative[0, 2] - relative[2, 0],
            relative[1, 0] - relative[0, 1],
        ]
    ) / (2 * np.sin(angle))
    assert abs(angle - rate * steps * DT) < 0.02 * rate * steps * DT
    assert_same_direction(turned_axis, axis)
    assert np.linalg.norm(end[:3, 3] - start[:3, 3]) < 1e-4  # TCP stays put (0.1 mm)


@settings(max_examples=50, deadline=None)
@given(direction=unit_vectors(6), magnitude=st.floats(5.0, 20.0))
def test_joint_speed_limit_scales_the_whole_twist(
    ik: DifferentialIK, direction: np.ndarray, magnitude: float
) -> None:
    q = tm5_900.INITIAL_Q.copy()
    twist = magnitude * direction
    assume(joint_speed_ratio(q, twist) > 1.05)
    velocity, info = ik.step(q, twist, DT)
    assert np.all(np.abs(velocity) <= LIMITS.max_speed * (1 + 1e-6))
    assert 0.0 < info.scale < 1.0
    assert info.limited_by is not None and info.limited_by.startswith("joint speed J")
    joint = int(info.limited_by[-1]) - 1
    assert abs(velocity[joint]) == pytest.approx(LIMITS.max_speed[joint], rel=0.02)
    achieved = tm5_900.jacobian(q) @ velocity
    assert_same_direction(achieved, twist)
    assert np.linalg.norm(achieved) == pytest.approx(info.scale * magnitude, rel=0.02)


@settings(max_examples=50, deadline=None)
@given(direction=unit_vectors(6), magnitude=st.floats(0.05, 5.0))
def test_twists_within_the_joint_speeds_are_not_scaled(
    ik: DifferentialIK, direction: np.ndarray, magnitude: float
) -> None:
    q = tm5_900.INITIAL_Q.copy()
    twist = magnitude * direction
    assume(joint_speed_ratio(q, twist) < 0.95)
    velocity, info = ik.step(q, twist, DT)
    assert info.scale == 1.0 and info.limited_by is None
    np.testing.assert_allclose(tm5_900.jacobian(q) @ velocity, twist, atol=0.02 * magnitude)


def test_joint_position_limit_stops_the_motion_in_its_direction(ik: DifferentialIK) -> None:
    q = tm5_900.INITIAL_Q.copy()
    twist = np.array([0.0, 0.0, 0.0, 0.0, 0.0, -3.0])  # tool points down: turns joint 6 up
    infos: list[IKInfo] = []
    for _ in range(1000):
        velocity, info = ik.step(q, twist, DT)
        infos.append(info)
        if np.any(velocity):
            assert_same_direction(tm5_900.jacobian(q) @ velocity, twist)
        q = q + velocity * DT
        assert np.all(q <= LIMITS.upper + 1e-9) and np.all(q >= LIMITS.lower - 1e-9)
    assert infos[0].limited_by is None
    assert infos[-1].limited_by == "joint limit J6" and infos[-1].scale < 1e-3
    assert LIMITS.upper[5] - q[5] < 1e-3


def wrist_twist(q: np.ndarray, joint5_rate: float) -> np.ndarray:
    """The base-frame twist that turning joint 5 alone would give."""
    dq = np.zeros(6)
    dq[4] = joint5_rate
    return tm5_900.jacobian(q) @ dq


def test_approaching_the_wrist_singularity_slows_then_stops(ik: DifferentialIK) -> None:
    q = tm5_900.INITIAL_Q.copy()
    twist = wrist_twist(q, -0.5)  # joint 5 toward 0: axes 4 and 6 line up
    speeds, infos = [], []
    for _ in range(1500):
        velocity, info = ik.step(q, twist, DT)
        achieved = tm5_900.jacobian(q) @ velocity
        if info.scale > 1e-6:
            assert_same_direction(achieved, twist)
        speeds.append(np.linalg.norm(achieved))
        infos.append(info)
        q = q + velocity * DT
        assert np.all(np.abs(velocity) <= LIMITS.max_speed * (1 + 1e-6))
    full = np.linalg.norm(twist)
    assert speeds[0] == pytest.approx(full, rel=0.02)
    slowed = [i for i, info in enumerate(infos) if info.limited_by == "singularity"]
    assert slowed, "never slowed for the singularity"
    assert infos[slowed[0]].condition > THRESHOLDS.slow_down
    assert max(info.condition for info in infos) < THRESHOLDS.hard_stop + 0.05
    assert speeds[-1] < 0.01 * full
    for i in slowed:  # linear slow-down between the thresholds
        expected = np.clip((THRESHOLDS.hard_stop - infos[i].condition) / 13.0, 0.0, 1.0)
        assert infos[i].scale == pytest.approx(expected, abs=1e-9)
        # (within 1e-6 of the twist: the QP's own tolerance where the scale nears zero)
        assert speeds[i] == pytest.approx(expected * full, rel=0.02, abs=1e-6 * full)
    assert abs(q[4]) > np.deg2rad(5.0)


def test_motion_away_from_the_singularity_is_not_slowed(ik: DifferentialIK) -> None:
    q = tm5_900.INITIAL_Q.copy()
    q[4] = np.deg2rad(8.0)  # past the hard stop (it stops 10.6 degrees from the singularity)
    twist = wrist_twist(q, 0.5)
    velocity, info = ik.step(q, twist, DT)
    assert info.condition > THRESHOLDS.hard_stop
    assert info.scale == 1.0 and info.limited_by is None
    assert np.linalg.norm(tm5_900.jacobian(q) @ velocity) == pytest.approx(
        np.linalg.norm(twist), rel=0.02
    )
    _, toward = ik.step(q, -twist, DT)
    assert toward.scale == 0.0 and toward.limited_by == "singularity"


def test_stretching_the_elbow_straight_stops_before_the_singularity(ik: DifferentialIK) -> None:
    q = tm5_900.INITIAL_Q.copy()
    reach = tm5_900.forward_kinematics(q)[:3, 3] - np.array([0.0, 0.0, tm5_900.DH[0].d])
    reach[1] = 0.0
    twist = np.concatenate([0.2 * reach / np.linalg.norm(reach), np.zeros(3)])
    conditions = []
    for _ in range(2000):
        velocity, info = ik.step(q, twist, DT)
        conditions.append(info.condition)
        q = q + velocity * DT
    assert max(conditions) < THRESHOLDS.hard_stop + 0.05
    assert np.linalg.norm(tm5_900.jacobian(q) @ velocity) < 0.01 * 0.2
    assert abs(q[2]) > np.deg2rad(5.0)


def test_zero_twist_gives_zero_velocity(ik: DifferentialIK) -> None:
    velocity, info = ik.step(tm5_900.INITIAL_Q, np.zeros(6), DT)
    assert not np.any(velocity) and info.scale == 1.0


def test_solve_pose_reaches_a_reachable_pose_and_refuses_a_far_one(ik: DifferentialIK) -> None:
    goal_q = np.deg2rad([30.0, 10.0, 80.0, -20.0, 70.0, 40.0])
    target = tm5_900.forward_kinematics(goal_q)
    found = ik.solve_pose(tm5_900.INITIAL_Q, target)
    assert found is not None
    np.testing.assert_allclose(tm5_900.forward_kinematics(found), target, atol=1e-4)
    far = target.copy()
    far[:3, 3] = [1.5, 0.0, 0.5]
    assert ik.solve_pose(tm5_900.INITIAL_Q, far, iterations=100) is None


def test_thresholds_must_be_ordered() -> None:
    with pytest.raises(ValueError, match="thresholds"):
        SingularityThresholds(slow_down=30.0, hard_stop=17.0)


def test_ik_refuses_limits_of_the_wrong_size() -> None:
    model: mujoco.MjModel = load_model()
    short = type(LIMITS)(LIMITS.lower[:5], LIMITS.upper[:5], LIMITS.max_speed[:5])
    with pytest.raises(ValueError, match="joints"):
        DifferentialIK(model, short)
