"""Tests for TechmanRobot against the fake Listen Node on loopback."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator

import numpy as np
import pytest
from stand_ins import wait_until

from wovenskin.robots.base import JointLimits, Pose, RobotError
from wovenskin.robots.sim import tm5_900
from wovenskin.robots.techman import FakeListenNode, TechmanRobot
from wovenskin.robots.techman.ethernet_slave import SvrMode, state_packet
from wovenskin.robots.techman.protocol import Packet

LIMITS = JointLimits(np.full(6, -np.pi), np.full(6, np.pi), np.full(6, np.pi))


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


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
    assert scripts[0] == "ContinueVLine(300,2000)"  # the two timeouts, ms
    assert scripts[1] == "SetContinueVLine(0,50,0,0,0,10)"  # mm/s and deg/s
    assert scripts.count("ContinueVLine(300,2000)") == 1
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


def test_idle_velocity_mode_is_kept_alive(robot: TechmanRobot, fake: FakeListenNode) -> None:
    """Between gestures the client keeps re-sending zero velocity, so the controller's 2 s
    stop timeout never ends the mode and the next gesture's first command is accepted."""
    robot.send_twist(np.array([0.0, 0.02, 0, 0, 0, 0]))
    deadline = time.monotonic() + 2.6  # longer than the controller's stop timeout
    while time.monotonic() < deadline:
        time.sleep(0.05)
    assert robot.keepalives >= 5
    robot.send_twist(np.array([0.0, -0.02, 0, 0, 0, 0]))
    time.sleep(0.05)
    robot.send_twist(np.zeros(6))
    assert fake.velocity_mode and fake.velocity_mode_exits == []
    assert fake.velocity_mode_entries == robot.velocity_mode_entries == 1
    assert fake.script_errors == [] and fake.violations == []


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


def test_a_lost_velocity_mode_is_one_error_then_re_entered(
    robot: TechmanRobot, fake: FakeListenNode
) -> None:
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    with fake._lock:
        fake._end_velocity_mode("test: the controller left velocity mode on its own")
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))  # streamed: refused
    assert wait_until(lambda: not robot.in_velocity_mode)  # keep-alives stop at once
    with pytest.raises(RobotError, match="refused SetContinueVLine") as info:
        robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    assert "no longer in velocity mode" in str(info.value) and "\n" not in str(info.value)
    refused = len(fake.script_errors)
    time.sleep(0.3)  # no loop of refused keep-alives meanwhile
    assert len(fake.script_errors) == refused
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))  # the next command re-enters cleanly
    assert fake.velocity_mode and robot.velocity_mode_entries == fake.velocity_mode_entries == 2
    assert robot.velocity_refusals == refused


def test_move_to_joints_runs_until_the_tag_is_reached(
    robot: TechmanRobot, fake: FakeListenNode
) -> None:
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    target = np.deg2rad([10, -5, 0, 0, 0, 0])
    robot.move_to_joints(target, speed_fraction=0.5)
    assert "StopContinueVmode()" in fake.scripts[-4:-2]
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
    q_stopped = fake.q_deg.copy()
    assert wait_until(lambda: np.allclose(np.rad2deg(robot.state().q), q_stopped, atol=1e-4))
    assert not robot.state().moving
    assert abs(q_stopped[0]) < 90


def test_default_limits_are_the_tm5_900() -> None:
    assert TechmanRobot("127.0.0.1").joint_limits() is tm5_900.JOINT_LIMITS


# -- the controller as Techman's material describes it ---------------------------------------


def test_the_enter_node_message_is_not_an_error(robot: TechmanRobot, fake: FakeListenNode) -> None:
    assert wait_until(lambda: robot.listen_node_name == "Listen1")
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    robot.send_twist(np.zeros(6))
    assert robot.state().fault is None and fake.violations == []


def test_the_flow_re_entering_the_node_ends_velocity_mode_quietly(
    robot: TechmanRobot, fake: FakeListenNode
) -> None:
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    assert wait_until(lambda: len(fake.velocity_commands) == 1)
    fake.enter_listen_node()  # the flow left and came back: the controller's mode is gone
    assert wait_until(lambda: not robot.in_velocity_mode)
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))  # re-entered, no error
    assert fake.velocity_mode and fake.velocity_mode_entries == 2
    assert robot.velocity_mode_entries == 2


@pytest.mark.parametrize("mode", [SvrMode.BINARY, SvrMode.JSON])
@pytest.mark.parametrize("lowercase", [True, False])
def test_both_state_modes_and_checksum_cases(mode: SvrMode, lowercase: bool) -> None:
    with FakeListenNode(state_mode=mode, lowercase_checksums=lowercase) as fake:
        arm = TechmanRobot("127.0.0.1", fake.listen_port, fake.state_port, limits=LIMITS)
        arm.connect()
        try:

            def at_speed() -> bool:  # keep commanding until the reported speed settles
                arm.send_twist(np.array([0.0, 0.0, 0.02, 0.0, 0.0, 0.0]))
                state = arm.state()  # TCP_Speed in m/s; TCP_Speed3D agrees
                return abs(state.tcp_twist[2] - 0.02) < 1e-4 and abs(state.tcp_speed - 0.02) < 1e-4

            assert wait_until(at_speed)
        finally:
            arm.disconnect()
        assert arm.bad_state_frames == 0 and fake.violations == []


def test_a_missing_velocity_licence_is_named() -> None:
    with FakeListenNode(velocity_licence=False) as fake:
        arm = TechmanRobot("127.0.0.1", fake.listen_port, fake.state_port, limits=LIMITS)
        arm.connect()
        try:
            for _ in range(2):  # every attempt: the same one line, no motion
                with pytest.raises(RobotError, match="velocity-mode licence") as info:
                    arm.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
                assert "ContinueVLine" in str(info.value) and "\n" not in str(info.value)
        finally:
            arm.disconnect()
        assert fake.velocity_commands == [] and arm.velocity_refusals == 2


def test_a_flow_outside_the_listen_node_is_named(robot: TechmanRobot, fake: FakeListenNode) -> None:
    fake.leave_listen_node()
    with pytest.raises(RobotError, match=r"not in a Listen Node \(CPERR F1\)"):
        robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    assert fake.velocity_commands == []


def test_connect_needs_the_flow_in_the_listen_node(fake: FakeListenNode) -> None:
    fake.leave_listen_node()
    arm = TechmanRobot("127.0.0.1", fake.listen_port, fake.state_port, limits=LIMITS)
    with pytest.raises(RobotError, match="not in a Listen Node"):
        arm.connect()
    assert not arm.connected


class Junk:
    """A stand-in for a state packet whose bytes on the wire are ``raw``."""

    def __init__(self, raw: bytes) -> None:
        self.raw = raw

    def encode(self, lowercase: bool = False) -> bytes:
        return self.raw


def nan_frame(fake: FakeListenNode):
    items = FakeListenNode.state_items(fake)
    items["Joint_Angle"] = [0.0, float("nan"), 0.0, 0.0, 0.0, 0.0]
    return state_packet("1", items, SvrMode.BINARY)


@pytest.mark.parametrize(
    ("frame", "words"),
    [
        (nan_frame, "Joint_Angle"),
        (lambda f: Packet("TMSVR", b'1,3,[{"Item":"Robot_Error","Value":"yes"}]'), "Robot_Error"),
        (lambda f: Packet("TMSVR", b"1,1,\x0b\x00Joint_Angle\x18\x00\x00"), "ends inside"),
        (lambda f: Junk(b"\x00\xff garbage without a packet"), "stray bytes"),
        (lambda f: Packet("TMSVR", b"1,2,Joint_Angle=1"), "string mode"),
    ],
)
def test_bad_state_frames_are_one_line_faults_and_no_motion(
    robot: TechmanRobot, fake: FakeListenNode, frame, words: str
) -> None:
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    fake.state_frame = lambda: frame(fake)  # from now on every pushed frame is bad
    assert wait_until(lambda: words in (robot.state().fault or ""))
    fault = robot.state().fault
    assert "no valid state" in fault and "\n" not in fault
    assert robot.bad_state_frames > 0
    sent = len(fake.velocity_commands)
    with pytest.raises(RobotError, match="no valid state"):
        robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    assert len(fake.velocity_commands) == sent  # nothing was sent


def test_connect_names_a_state_table_that_lacks_items(fake: FakeListenNode) -> None:
    def without_speed():
        items = FakeListenNode.state_items(fake)
        del items["TCP_Speed"]
        return state_packet("1", items, SvrMode.BINARY)

    fake.state_frame = without_speed
    arm = TechmanRobot("127.0.0.1", fake.listen_port, fake.state_port, limits=LIMITS)
    with pytest.raises(RobotError, match="lacks TCP_Speed") as info:
        arm.connect()
    assert "\n" not in str(info.value)


def test_a_stalled_client_re_enters_velocity_mode_cleanly(fake: FakeListenNode) -> None:
    """If no velocity went out for half the controller's stop timeout (a stalled host), the
    client stops trusting the mode: the next twist leaves it and enters it afresh."""
    offset = [0.0]
    arm = TechmanRobot(
        "127.0.0.1",
        fake.listen_port,
        fake.state_port,
        limits=LIMITS,
        clock=lambda: time.monotonic() + offset[0],
    )
    arm.connect()
    try:
        arm.send_twist(np.zeros(6))
        offset[0] += 1.5  # as if the process had stalled for 1.5 s
        assert wait_until(lambda: not arm.in_velocity_mode and arm.state().fault is None)
        arm.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
        assert arm.velocity_mode_entries == 2 and fake.velocity_mode_entries == 2
        assert fake.script_errors == []
        assert wait_until(lambda: fake.scripts[-1] == "SetContinueVLine(10,0,0,0,0,0)")
        assert fake.scripts[-3:-1] == ["StopContinueVmode()", "ContinueVLine(300,2000)"]
    finally:
        arm.disconnect()


def test_the_command_timeout_must_beat_the_controllers(fake: FakeListenNode) -> None:
    with pytest.raises(ValueError, match="zero-velocity timeout"):
        TechmanRobot("127.0.0.1", command_timeout_s=0.5)
