"""Tests for TechmanRobot against the fake Listen Node on loopback."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator

import numpy as np
import pytest

from wovenskin.robots.base import JointLimits, Pose, RobotError
from wovenskin.robots.techman import FakeListenNode, TechmanRobot

LIMITS = JointLimits(np.full(6, -np.pi), np.full(6, np.pi), np.full(6, np.pi))


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def wait_until(condition, timeout: float = 1.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.005)
    return condition()


@pytest.fixture
def fake() -> Iterator[FakeListenNode]:
    with FakeListenNode() as node:
        yield node


@pytest.fixture
def robot(fake: FakeListenNode) -> Iterator[TechmanRobot]:
    arm = TechmanRobot("127.0.0.1", fake.listen_port, fake.state_port, limits=LIMITS, timeout_s=0.5)
    arm.connect()
    yield arm
    arm.disconnect()


def test_connect_refused_is_one_line() -> None:
    arm = TechmanRobot("127.0.0.1", free_port(), free_port(), timeout_s=0.5)
    with pytest.raises(RobotError, match="cannot connect to the Techman Listen Node") as info:
        arm.connect()
    assert "\n" not in str(info.value)
    assert not arm.connected


def test_connect_needs_the_ethernet_slave(fake: FakeListenNode) -> None:
    arm = TechmanRobot("127.0.0.1", fake.listen_port, free_port(), timeout_s=0.5)
    with pytest.raises(RobotError, match="Ethernet Slave"):
        arm.connect()


def test_state_reads_the_pushed_frame(robot: TechmanRobot, fake: FakeListenNode) -> None:
    state = robot.state()
    np.testing.assert_allclose(state.tcp.position, [0.4, 0.0, 0.4])
    np.testing.assert_allclose(state.tcp.rotation() @ [0, 0, 1], [0, 0, -1], atol=1e-9)
    assert state.fault is None and not state.moving
    assert fake.violations == []


def test_velocity_session_start_stream_stop(robot: TechmanRobot, fake: FakeListenNode) -> None:
    start = robot.state().tcp.position
    for _ in range(15):
        robot.send_twist(np.array([0.0, 0.05, 0.0, 0.0, 0.0, np.deg2rad(10.0)]))
        time.sleep(0.01)
    assert robot.state().moving
    robot.stop()
    scripts = fake.scripts
    assert scripts[0] == "ContinueVLine(200,250)"
    assert scripts[1] == "SetContinueVLine(0,50,0,0,0,10)"  # mm/s and deg/s
    assert scripts.count("ContinueVLine(200,250)") == 1
    assert scripts[-2:] == ["StopContinueVmode()", "StopAndClearBuffer()"]
    assert not fake.velocity_mode
    assert wait_until(lambda: robot.state().tcp.position[1] - start[1] > 0.005)
    assert wait_until(lambda: not robot.state().moving)  # once a post-stop frame arrives
    assert fake.violations == []


@pytest.mark.parametrize(
    "twist",
    [
        np.array([np.nan, 0, 0, 0, 0, 0]),
        np.array([0, 0, np.inf, 0, 0, 0]),
        np.zeros(5),
        np.zeros((2, 6)),
        ["a", 0, 0, 0, 0, 0],
        np.array([0.3, 0, 0, 0, 0, 0]),  # above the 250 mm/s velocity-mode limit
    ],
)
def test_bad_twists_send_nothing(robot: TechmanRobot, fake: FakeListenNode, twist) -> None:
    before = len(fake.received)
    with pytest.raises(RobotError) as info:
        robot.send_twist(twist)
    assert "\n" not in str(info.value)
    time.sleep(0.02)
    assert len(fake.received) == before
    assert not fake.velocity_mode


def test_commands_need_a_connection() -> None:
    arm = TechmanRobot("127.0.0.1", limits=LIMITS)
    with pytest.raises(RobotError, match="not connected"):
        arm.send_twist(np.zeros(6))
    with pytest.raises(RobotError, match="not connected"):
        arm.state()
    arm.disconnect()  # harmless
    arm.stop()


def test_command_timeout_sends_zero_velocity(robot: TechmanRobot, fake: FakeListenNode) -> None:
    robot.send_twist(np.array([0.02, 0, 0, 0, 0, 0]))
    assert wait_until(lambda: fake.scripts[-1:] == ["SetContinueVLine(0,0,0,0,0,0)"])
    assert robot.watchdog_stops == 1
    np.testing.assert_allclose(fake.command_velocity, 0.0)


def test_disconnect_leaves_velocity_mode(fake: FakeListenNode) -> None:
    arm = TechmanRobot("127.0.0.1", fake.listen_port, fake.state_port, limits=LIMITS)
    arm.connect()
    arm.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    arm.disconnect()
    arm.disconnect()
    assert not fake.velocity_mode
    assert "StopContinueVmode()" in fake.scripts
    assert not arm.connected


def test_lost_connection_is_a_fault(robot: TechmanRobot, fake: FakeListenNode) -> None:
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    fake.drop_clients()
    assert wait_until(lambda: robot.state().fault is not None)
    assert "closed" in robot.state().fault
    with pytest.raises(RobotError, match="closed"):
        robot.send_twist(np.zeros(6))


def test_unanswered_script_times_out(robot: TechmanRobot, fake: FakeListenNode) -> None:
    fake.answer_scripts = False
    with pytest.raises(RobotError, match="did not answer ContinueVLine within 0.5 s"):
        robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))


def test_unanswered_stream_surfaces_on_a_later_tick(
    robot: TechmanRobot, fake: FakeListenNode
) -> None:
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    fake.answer_scripts = False
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))  # streamed, not waited for
    time.sleep(0.6)
    with pytest.raises(RobotError, match="did not answer SetContinueVLine"):
        robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))


def test_robot_fault_is_reported_and_blocks_motion(
    robot: TechmanRobot, fake: FakeListenNode
) -> None:
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    fake.inject_fault(42)
    assert wait_until(lambda: robot.state().fault == "robot error code 42")
    with pytest.raises(RobotError, match="error code 42"):
        robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))


def test_rejected_stream_script_raises_next_tick(robot: TechmanRobot, fake: FakeListenNode) -> None:
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    fake.velocity_mode = False  # the robot left velocity mode on its own
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    time.sleep(0.05)
    with pytest.raises(RobotError, match="rejected SetContinueVLine"):
        robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))


def test_move_to_joints_runs_until_the_tag_is_reached(
    robot: TechmanRobot, fake: FakeListenNode
) -> None:
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    target = np.deg2rad([10, -5, 0, 0, 0, 0])
    robot.move_to_joints(target, speed_fraction=0.5)
    assert fake.scripts[-3] == "StopContinueVmode()"
    assert fake.scripts[-2] == 'PTP("JPP",10,-5,0,0,0,0,50,200,0,false)'
    assert fake.scripts[-1] == "QueueTag(1)"
    assert robot.state().moving
    assert wait_until(lambda: not robot.state().moving)
    np.testing.assert_allclose(robot.state().q, target, atol=1e-9)


def test_move_to_joints_validates(robot: TechmanRobot, fake: FakeListenNode) -> None:
    before = len(fake.received)
    for q, fraction in [
        (np.full(6, np.nan), 0.2),
        (np.zeros(5), 0.2),
        (np.full(6, 4.0), 0.2),
        (np.zeros(6), 0.0),
        (np.zeros(6), 1.5),
    ]:
        with pytest.raises(RobotError):
            robot.move_to_joints(q, fraction)
    assert len(fake.received) == before


def test_move_to_pose_sends_a_line_move(robot: TechmanRobot, fake: FakeListenNode) -> None:
    start = robot.state().tcp
    goal = Pose(start.position + [0.02, 0.0, -0.01], start.quat)
    robot.move_to_pose(goal, speed=0.1)
    assert fake.scripts[-2].startswith('Line("CAP",420,0,390,')
    assert fake.scripts[-2].endswith(",100,200,0,false)")
    assert wait_until(lambda: not robot.state().moving)
    np.testing.assert_allclose(robot.state().tcp.position, goal.position, atol=1e-6)
    with pytest.raises(RobotError):
        robot.move_to_pose(goal, speed=float("nan"))


def test_stop_cancels_a_move(robot: TechmanRobot, fake: FakeListenNode) -> None:
    robot.move_to_joints(np.deg2rad([90, 0, 0, 0, 0, 0]), speed_fraction=0.1)
    time.sleep(0.05)
    robot.stop()
    q_after = robot.state().q.copy()
    time.sleep(0.1)
    assert not robot.state().moving
    assert abs(q_after[0]) < np.deg2rad(90)
    np.testing.assert_allclose(fake.q_deg, np.rad2deg(robot.state().q), atol=1e-6)


def test_default_limits_are_the_tm5_900() -> None:
    tm5 = pytest.importorskip("wovenskin.robots.sim.tm5_900")
    assert TechmanRobot("127.0.0.1").joint_limits() is tm5.JOINT_LIMITS
