"""SimRobot: the Robot interface on the simulated TM5-900."""

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.robots.base import Pose, RobotError
from wovenskin.robots.sim import SimRobot, tm5_900
from wovenskin.robots.sim.robot import MAX_STEP_S, STALE_COMMAND_S, STOP_TIME_S

TICK = 0.02
LIMITS = tm5_900.JOINT_LIMITS


@pytest.fixture
def robot() -> SimRobot:
    arm = SimRobot()
    arm.connect()
    return arm


def run_until_still(robot: SimRobot, limit_s: float = 30.0) -> list[float]:
    """Step until the arm stops; the TCP speeds seen on the way."""
    speeds = []
    for _ in range(int(limit_s / TICK)):
        robot.step(TICK)
        state = robot.state()
        speeds.append(state.tcp_speed)
        assert np.all(np.abs(state.dq) <= LIMITS.max_speed * (1 + 1e-6))
        if not state.moving:
            return speeds
    raise AssertionError("the arm never stopped")


def test_starts_at_the_initial_pose_and_reports_state(robot: SimRobot) -> None:
    state = robot.state()
    np.testing.assert_allclose(state.q, tm5_900.INITIAL_Q)
    expected = tm5_900.forward_kinematics(tm5_900.INITIAL_Q)
    np.testing.assert_allclose(state.tcp.position, expected[:3, 3], atol=1e-9)
    np.testing.assert_allclose(state.tcp.rotation(), expected[:3, :3], atol=1e-9)
    assert not state.moving and state.fault is None and state.tcp_speed == 0.0
    assert robot.joint_limits() is LIMITS
    np.testing.assert_allclose(robot.data.qpos, state.q)


@settings(max_examples=30, deadline=None)
@given(
    direction=st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(
        lambda v: np.linalg.norm(v) > 0.1
    ),
    speed=st.floats(0.01, 0.25),
)
def test_twist_moves_the_tcp_in_its_direction_at_its_speed(
    direction: list[float], speed: float
) -> None:
    robot = SimRobot()
    robot.connect()
    velocity = speed * np.array(direction) / np.linalg.norm(direction)
    start = robot.state().tcp.position
    for _ in range(10):
        robot.send_twist(np.concatenate([velocity, np.zeros(3)]))
        robot.step(TICK)
    state = robot.state()
    assert np.linalg.norm((state.tcp.position - start) / (10 * TICK) - velocity) < 0.02 * speed
    assert np.linalg.norm(state.tcp_twist[:3] - velocity) < 0.02 * speed
    assert state.moving and robot.ik_info.scale == 1.0


def test_steps_run_the_ik_at_its_rate(monkeypatch: pytest.MonkeyPatch) -> None:
    for rate, expected_calls in ((250.0, 25), (1000.0, 100)):
        robot = SimRobot(ik_rate_hz=rate)
        robot.connect()
        calls: list[float] = []
        step = robot.ik.step

        def counted(q, twist, dt, step=step, calls=calls):  # noqa: ANN001, ANN202
            calls.append(dt)
            return step(q, twist, dt)

        monkeypatch.setattr(robot.ik, "step", counted)
        robot.send_twist(np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.5]))
        robot.step(0.1)
        assert len(calls) == expected_calls and max(calls) <= 1.0 / rate + 1e-12
        assert robot.state().t == pytest.approx(0.1)
        turned = abs(robot.state().q[5] - tm5_900.INITIAL_Q[5])
        assert turned == pytest.approx(0.05, rel=0.02)


def test_stale_twist_stops_the_arm_by_itself(robot: SimRobot) -> None:
    robot.send_twist(np.array([0.05, 0.0, 0.0, 0.0, 0.0, 0.0]))
    robot.step(STALE_COMMAND_S - TICK)
    assert robot.state().tcp_speed == pytest.approx(0.05, rel=0.02)
    robot.step(2 * TICK)
    assert robot.state().tcp_speed < 0.05 and robot.last_stop_reason is not None
    robot.step(STOP_TIME_S)
    state = robot.state()
    assert not state.moving and state.tcp_speed == 0.0


def test_stop_decelerates_to_rest_within_the_stop_time(robot: SimRobot) -> None:
    robot.send_twist(np.array([0.0, 0.2, -0.1, 0.0, 0.0, 0.0]))
    robot.step(0.1)
    before = robot.state().tcp_speed
    robot.stop()
    speeds = []
    for _ in range(int(STOP_TIME_S / 0.004) + 1):
        robot.step(0.004)
        speeds.append(robot.state().tcp_speed)
    assert not robot.state().moving and speeds[-1] == 0.0
    steps = np.diff([before, *speeds])
    assert np.all(steps <= 1e-9)
    assert np.max(-steps) / 0.004 <= before / STOP_TIME_S * 1.05


def test_stop_cancels_a_joint_move_smoothly(robot: SimRobot) -> None:
    robot.move_to_joints(tm5_900.HOME_Q, speed_fraction=0.5)
    robot.step(0.5)
    moving_dq = robot.state().dq
    assert np.any(moving_dq)
    robot.stop()
    robot.step(STOP_TIME_S + 0.004)
    state = robot.state()
    assert not state.moving and not np.any(state.dq)
    assert not np.allclose(state.q, tm5_900.HOME_Q, atol=1e-3)


@pytest.mark.parametrize("fraction", [0.2, 1.0])
def test_move_to_joints_reaches_the_target_within_the_speed_fraction(
    robot: SimRobot, fraction: float
) -> None:
    goal = np.deg2rad([40.0, -20.0, 100.0, 10.0, 60.0, -90.0])
    robot.move_to_joints(goal, speed_fraction=fraction)
    peak = np.zeros(6)
    for _ in range(int(30 / TICK)):
        robot.step(TICK)
        state = robot.state()
        peak = np.maximum(peak, np.abs(state.dq))
        if not state.moving:
            break
    np.testing.assert_allclose(robot.state().q, goal, atol=1e-12)
    assert np.all(peak <= fraction * LIMITS.max_speed * (1 + 1e-6))
    assert np.max(peak / (fraction * LIMITS.max_speed)) > 0.9


def test_move_to_pose_reaches_the_pose_within_the_speed(robot: SimRobot) -> None:
    goal_q = np.deg2rad([-25.0, 10.0, 80.0, 0.0, 90.0, 20.0])
    goal = tm5_900.forward_kinematics(goal_q)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, goal[:3, :3].flatten())
    robot.move_to_pose(Pose(goal[:3, 3], quat), speed=0.1)
    speeds = run_until_still(robot)
    state = robot.state()
    np.testing.assert_allclose(state.tcp.position, goal[:3, 3], atol=1e-4)
    np.testing.assert_allclose(state.tcp.rotation(), goal[:3, :3], atol=1e-3)
    assert max(speeds) <= 0.1 * 1.02


def test_twist_after_a_move_takes_over(robot: SimRobot) -> None:
    robot.move_to_joints(tm5_900.HOME_Q, 0.5)
    robot.step(0.2)
    robot.send_twist(np.zeros(6))
    robot.step(0.1)
    assert not robot.state().moving


def assert_refused_without_motion(robot: SimRobot, command, match: str) -> None:  # noqa: ANN001
    q = robot.state().q
    with pytest.raises(RobotError, match=match):
        command()
    robot.step(0.5)
    state = robot.state()
    np.testing.assert_array_equal(state.q, q)
    assert not state.moving


@pytest.mark.parametrize(
    ("twist", "match"),
    [
        (np.array([np.nan, 0, 0, 0, 0, 0]), "non-finite"),
        (np.array([0, 0, np.inf, 0, 0, 0]), "non-finite"),
        (np.zeros(5), "shape"),
        (np.zeros((2, 6)), "shape"),
        ("fast", "numeric"),
    ],
)
def test_bad_twists_are_refused_without_motion(robot: SimRobot, twist, match: str) -> None:  # noqa: ANN001
    assert_refused_without_motion(robot, lambda: robot.send_twist(twist), match)


@pytest.mark.parametrize(
    ("q", "fraction", "match"),
    [
        (np.zeros(7), 0.2, "shape"),
        (np.array([np.nan] * 6), 0.2, "non-finite"),
        (np.array([0.0, 0.0, 3.0, 0.0, 0.0, 0.0]), 0.2, "outside the joint limits"),
        (np.zeros(6), 0.0, "speed_fraction"),
        (np.zeros(6), 1.5, "speed_fraction"),
        (np.zeros(6), float("nan"), "speed_fraction"),
    ],
)
def test_bad_joint_moves_are_refused_without_motion(
    robot: SimRobot, q: np.ndarray, fraction: float, match: str
) -> None:
    assert_refused_without_motion(robot, lambda: robot.move_to_joints(q, fraction), match)


def test_bad_pose_moves_are_refused_without_motion(robot: SimRobot) -> None:
    far = Pose(np.array([1.5, 0.0, 0.4]), np.array([1.0, 0.0, 0.0, 0.0]))
    near = robot.state().tcp
    assert_refused_without_motion(robot, lambda: robot.move_to_pose(far), "unreachable")
    assert_refused_without_motion(robot, lambda: robot.move_to_pose(near, speed=-1.0), "speed")
    assert_refused_without_motion(robot, lambda: robot.move_to_pose(near.position), "Pose")


def test_bad_command_while_moving_stops_the_arm(robot: SimRobot) -> None:
    robot.send_twist(np.array([0.1, 0.0, 0.0, 0.0, 0.0, 0.0]))
    robot.step(0.1)
    with pytest.raises(RobotError):
        robot.send_twist(np.full(6, np.nan))
    robot.step(STOP_TIME_S + 0.004)
    assert not robot.state().moving


def test_disconnected_robot_refuses_commands_and_state() -> None:
    robot = SimRobot()
    with pytest.raises(RobotError, match="not connected"):
        robot.state()
    with pytest.raises(RobotError, match="not connected"):
        robot.send_twist(np.zeros(6))
    with pytest.raises(RobotError, match="not connected"):
        robot.move_to_joints(tm5_900.HOME_Q)
    robot.connect()
    robot.send_twist(np.array([0.05, 0.0, 0.0, 0.0, 0.0, 0.0]))
    robot.step(0.1)
    robot.disconnect()
    robot.disconnect()
    q = robot.data.qpos.copy()
    robot.step(0.1)
    np.testing.assert_array_equal(robot.data.qpos, q)


def test_constructor_checks_its_arguments() -> None:
    with pytest.raises(ValueError, match="q0"):
        SimRobot(q0=np.array([0.0, 0.0, 3.0, 0.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="q0"):
        SimRobot(q0=np.zeros(3))
    with pytest.raises(ValueError, match="ik_rate_hz"):
        SimRobot(ik_rate_hz=0.0)
    np.testing.assert_array_equal(SimRobot(q0=tm5_900.HOME_Q).data.qpos, tm5_900.HOME_Q)
    with pytest.raises(ValueError, match="dt"):
        SimRobot().step(float("nan"))


def test_a_huge_step_is_capped_and_logged(robot: SimRobot, caplog: pytest.LogCaptureFixture):
    """step(1e300) ran ceil(1e300 * ik_rate_hz) substeps: it never returned."""
    robot.send_twist(np.array([0.05, 0.0, 0.0, 0.0, 0.0, 0.0]))
    with caplog.at_level("WARNING", logger="wovenskin.robots.sim.robot"):
        robot.step(1e300)
    assert robot.t == pytest.approx(MAX_STEP_S)
    assert "capped" in caplog.text and "1e+300" in caplog.text
    state = robot.state()
    assert not state.moving and state.tcp_speed == 0.0  # the stale command stopped it


def test_the_stop_leaves_room_for_a_control_tick_within_0_1_s() -> None:
    """A STOP must get the TCP below 1 mm/s within 0.1 s; the stop arrives between ticks,
    so the arm's own ramp must be shorter by at least one 5 ms tick."""
    assert STOP_TIME_S <= 0.1 - 0.005
