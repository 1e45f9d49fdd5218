"""Tests for the fake controller's behaviour, driven by a manual clock (no sockets, no sleeps):
velocity-mode timeouts, refusals, CPERR, the enter-node message, status and motion."""

from __future__ import annotations

import numpy as np
import pytest

from wovenskin.robots.sim import tm5_900
from wovenskin.robots.techman.ethernet_slave import SvrMode, read_items, read_state
from wovenskin.robots.techman.fake_controller import FakeController
from wovenskin.robots.techman.protocol import (
    CommError,
    Packet,
    PacketError,
    PacketParser,
    encode_packet,
    parse_tmsct,
)


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def clock() -> Clock:
    return Clock()


@pytest.fixture
def robot(clock: Clock) -> FakeController:
    return FakeController(clock=clock)


def run(robot: FakeController, script_id: str, script: str) -> str:
    (reply,) = robot.handle(Packet("TMSCT", f"{script_id},{script}"))
    assert reply.header == "TMSCT"
    return reply.data


def wait(robot: FakeController, clock: Clock, seconds: float, step: float = 0.01) -> None:
    end = clock.t + seconds
    while clock.t < end - 1e-12:
        clock.t = min(end, clock.t + step)
        robot.advance()


def test_velocity_mode_with_the_two_timeouts(robot: FakeController, clock: Clock) -> None:
    assert run(robot, "1", "ContinueVLine(300, 2000)") == "1,OK"  # the driver's spacing
    assert robot.velocity_mode and robot.timeouts_ms == (300, 2000)
    assert run(robot, "2", "SetContinueVLine(100,0,0,0,0,0)") == "2,OK"
    wait(robot, clock, 0.29)
    np.testing.assert_allclose(robot.command_velocity, [100, 0, 0, 0, 0, 0])
    wait(robot, clock, 0.02)  # 0.31 s without a command: the target drops to zero
    np.testing.assert_allclose(robot.command_velocity, 0.0)
    assert robot.velocity_mode and robot.zero_velocity_timeouts == 1
    wait(robot, clock, 0.5)
    np.testing.assert_allclose(robot.velocity, 0.0)  # the arm has come to rest
    wait(robot, clock, 1.25)  # 2.06 s without a command: velocity mode ends
    assert not robot.velocity_mode
    ((at, reason),) = robot.velocity_mode_exits
    assert "timeout_stop" in reason and at == pytest.approx(102.0)
    assert run(robot, "3", "SetContinueVLine(10,0,0,0,0,0)") == "3,ERROR;1"
    assert "outside velocity mode" in robot.script_errors[-1]
    assert robot.violations == []  # a refused script is an answer, not a violation


def test_streaming_keeps_the_mode_alive(robot: FakeController, clock: Clock) -> None:
    run(robot, "1", "ContinueVLine(300,2000)")
    for i in range(50):  # 5 s of zero velocity, one every 0.1 s
        assert run(robot, str(i + 2), "SetContinueVLine(0,0,0,0,0,0)").endswith(",OK")
        wait(robot, clock, 0.1)
    assert robot.velocity_mode and robot.velocity_mode_exits == []
    assert robot.zero_velocity_timeouts == 0 and robot.velocity_mode_entries == 1


def test_a_stale_command_is_timed_out_even_without_ticks(
    robot: FakeController, clock: Clock
) -> None:
    run(robot, "1", "ContinueVLine(300,2000)")
    clock.t += 5.0  # no simulation step in between: the next packet still sees the timeout
    assert run(robot, "2", "SetContinueVLine(10,0,0,0,0,0)") == "2,ERROR;1"


def test_the_old_reading_of_continuevline_times_out_after_250_ms(
    robot: FakeController, clock: Clock
) -> None:
    # ContinueVLine(200,250) taken as (acceleration, speed) ends the mode 250 ms later.
    run(robot, "1", "ContinueVLine(200,250)\r\nSetContinueVLine(0,50,0,0,0,0)")
    wait(robot, clock, 0.3)
    assert not robot.velocity_mode
    assert run(robot, "2", "SetContinueVLine(0,50,0,0,0,0)") == "2,ERROR;1"


def test_without_the_licence_velocity_mode_is_refused(clock: Clock) -> None:
    robot = FakeController(clock=clock, velocity_licence=False)
    assert run(robot, "1", "ContinueVLine(300,2000)") == "1,ERROR;1"
    assert "licence" in robot.script_errors[0]
    assert not robot.velocity_mode and robot.velocity_mode_entries == 0


def test_acceleration_is_bounded(robot: FakeController, clock: Clock) -> None:
    run(robot, "1", "ContinueVLine(300,2000)\r\nSetContinueVLine(200,0,0,0,0,60)")
    wait(robot, clock, 0.05)
    assert robot.velocity[0] == pytest.approx(100.0)  # 2000 mm/s^2 x 0.05 s
    assert robot.velocity[5] == pytest.approx(36.0)  # 720 deg/s^2 x 0.05 s
    wait(robot, clock, 0.1)
    np.testing.assert_allclose(robot.velocity, [200, 0, 0, 0, 0, 60])
    run(robot, "2", "StopContinueVmode()")
    assert not robot.velocity_mode
    wait(robot, clock, 0.05)
    assert robot.velocity[0] == pytest.approx(100.0)  # decelerating after leaving the mode
    wait(robot, clock, 0.1)
    np.testing.assert_allclose(robot.velocity, 0.0)


def test_packet_errors_get_cperr_and_count_as_violations(robot: FakeController) -> None:
    raw = bytearray(encode_packet("TMSCT", "1,StopAndClearBuffer()"))
    raw[-3] ^= 0x01
    (error,) = PacketParser().feed(bytes(raw))
    assert isinstance(error, PacketError)
    assert robot.handle(error) == [Packet("CPERR", "02")]
    assert robot.handle(Packet("TMSVR", "1,3,[]")) == [Packet("CPERR", "03")]
    assert robot.handle(Packet("TMSCT", "noscript")) == [Packet("CPERR", "04")]
    assert robot.handle(Packet("TMSTA", "99")) == [Packet("CPERR", "04")]
    assert robot.protocol_violations == 4 and robot.scripts == []


def test_scripts_outside_the_listen_node_get_cperr_f1(robot: FakeController) -> None:
    assert run(robot, "1", "ScriptExit()") == "1,OK"
    assert robot.handle(Packet("TMSCT", "2,ContinueVLine(300,2000)")) == [
        Packet("CPERR", CommError.NOT_IN_LISTEN_NODE.value)
    ]
    assert robot.handle(Packet("TMSTA", "00")) == [Packet("TMSTA", "00,false,")]
    message = robot.enter_listen_node()
    assert parse_tmsct(message.data).node == "Listen1"
    assert robot.handle(Packet("TMSTA", "00")) == [Packet("TMSTA", "00,true,Listen1")]
    assert robot.violations == []


def test_status_and_tags(robot: FakeController, clock: Clock) -> None:
    assert run(robot, "1", 'PTP("JPP",9,0,0,0,0,-9,50,200,0,false)\r\nQueueTag(3,0)') == "1,OK"
    assert robot.handle(Packet("TMSTA", "01,3")) == [Packet("TMSTA", "01,03,false")]
    wait(robot, clock, 0.2)  # 9 deg at 90 deg/s
    assert robot.handle(Packet("TMSTA", "01,3")) == [Packet("TMSTA", "01,03,true")]
    assert robot.handle(Packet("TMSTA", "01,7")) == [Packet("TMSTA", "01,07,none")]
    np.testing.assert_allclose(robot.q_deg, [9, 0, 0, 0, 0, -9])


def test_script_errors_name_the_line(robot: FakeController) -> None:
    assert run(robot, "1", "Teleport(1)") == "1,ERROR;1"
    assert run(robot, "2", "ContinueVLine(300,2000)\r\nSetContinueVLine(1,0,0)") == "2,ERROR;2"
    assert not robot.velocity_mode  # a refused script runs none of its lines
    assert run(robot, "3", "ContinueVLine(0,2000)") == "3,ERROR;1"
    assert run(robot, "4", "ContinueVLine(300,2000)") == "4,OK"
    assert run(robot, "5", 'PTP("JPP",0,0,0,0,0,0,10,200,0,false)') == "5,ERROR;1"
    assert run(robot, "6", "SetContinueVLine(1,0,0,0,0,nan)") == "6,ERROR;1"
    assert len(robot.script_errors) == 5 and robot.violations == []


def test_a_fault_stops_everything_and_refuses_motion(robot: FakeController, clock: Clock) -> None:
    run(robot, "1", "ContinueVLine(300,2000)\r\nSetContinueVLine(50,0,0,0,0,0)")
    wait(robot, clock, 0.1)
    robot.inject_fault(3)
    np.testing.assert_allclose(robot.velocity, 0.0)
    assert not robot.velocity_mode and "robot error 3" in robot.velocity_mode_exits[0][1]
    assert run(robot, "2", "ContinueVLine(300,2000)") == "2,ERROR;1"
    items = read_items(robot.state_frame().payload)
    assert items is not None and items["Error_Code"] == 3 and items["Robot_Error"] is True


@pytest.mark.parametrize("mode", [SvrMode.BINARY, SvrMode.JSON])
def test_state_frames_carry_the_table(clock: Clock, mode: SvrMode) -> None:
    robot = FakeController(clock=clock, state_mode=mode)
    run(robot, "1", "ContinueVLine(300,2000)\r\nSetContinueVLine(0,30,40,0,0,0)")
    wait(robot, clock, 0.2)
    items = read_items(robot.state_frame().payload)
    assert items is not None
    state = read_state(items)
    np.testing.assert_allclose(state.tcp_speed, [0, 30, 40, 0, 0, 0], atol=1e-4)
    assert state.tcp_speed3d == pytest.approx(50.0, abs=1e-3)  # one number


def test_with_a_kinematic_model_joints_and_tcp_agree(clock: Clock) -> None:
    robot = FakeController(
        np.rad2deg(tm5_900.INITIAL_Q),
        clock=clock,
        forward_kinematics=tm5_900.forward_kinematics,
        jacobian=tm5_900.jacobian,
    )
    start = robot.tcp_wire()
    run(robot, "1", "ContinueVLine(300,2000)\r\nSetContinueVLine(0,50,0,0,0,0)")
    wait(robot, clock, 0.25)
    moved = robot.tcp_wire() - start
    assert 5.0 < moved[1] < 12.5 and abs(moved[0]) < 0.5 and abs(moved[2]) < 0.5
    pose = tm5_900.forward_kinematics(np.deg2rad(robot.q_deg))
    np.testing.assert_allclose(pose[:3, 3] * 1000.0, robot.tcp_wire()[:3], atol=1e-6)
    assert np.any(robot.joint_velocity_deg_s != 0.0)
