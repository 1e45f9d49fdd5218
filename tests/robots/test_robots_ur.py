"""Tests for URRobot's use of ur_rtde, with recording stand-ins for the RTDE interfaces."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from ur_stand_ins import FakeControl, FakeReceive

from wovenskin.control.safety import SafetyLayer
from wovenskin.robots.base import Pose, RobotError
from wovenskin.robots.registry import make_robot
from wovenskin.robots.ur import URRobot
from wovenskin.robots.ur.models import ur_model
from wovenskin.robots.ur.robot import pose_from_ur, pose_to_ur


@pytest.fixture
def parts() -> tuple[FakeControl, FakeReceive]:
    return FakeControl(), FakeReceive()


@pytest.fixture
def robot(parts) -> URRobot:
    control, receive = parts
    arm = URRobot(
        "10.0.0.5", control_factory=lambda host: control, receive_factory=lambda host: receive
    )
    arm.connect()
    return arm


def test_connect_arms_the_watchdog(robot: URRobot, parts) -> None:
    control, _ = parts
    assert control.calls == [("setWatchdog", 10.0)]


def test_missing_ur_rtde_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "rtde_control", None)
    monkeypatch.setitem(sys.modules, "rtde_receive", None)
    with pytest.raises(RobotError, match=r"install wovenskin\[ur\]"):
        URRobot("10.0.0.5").connect()


def test_unreachable_host_is_one_line() -> None:
    def refuse(host: str):
        raise RuntimeError(f"One of the RTDE input registers are already in use!\n{host}")

    arm = URRobot("10.0.0.9", control_factory=refuse, receive_factory=refuse)
    with pytest.raises(RobotError, match="cannot connect to the UR arm at 10.0.0.9") as info:
        arm.connect()
    assert "\n" not in str(info.value)


def test_refused_watchdog_releases_the_interfaces(parts) -> None:
    control, receive = parts
    control.accept = False
    arm = URRobot("h", control_factory=lambda h: control, receive_factory=lambda h: receive)
    with pytest.raises(RobotError, match="refused the RTDE watchdog"):
        arm.connect()
    assert receive.disconnected and control.names()[-1] == "disconnect"
    with pytest.raises(RobotError, match="not connected"):
        arm.state()


def test_twists_go_to_speedl_and_kick_the_watchdog(robot: URRobot, parts) -> None:
    control, _ = parts
    twist = np.array([0.05, 0.0, -0.02, 0.0, 0.1, 0.0])
    robot.send_twist(twist)
    assert control.calls[-2:] == [("kickWatchdog",), ("speedL", twist.tolist(), 0.5, 0.0)]
    assert robot.state().moving
    robot.stop()
    assert control.calls[-1] == ("speedStop", 2.0)
    assert not robot.state().moving


@pytest.mark.parametrize("twist", [np.full(6, np.nan), np.zeros(3), np.zeros((6, 1)), "abc"])
def test_bad_twists_reach_nothing(robot: URRobot, parts, twist) -> None:
    control, _ = parts
    before = len(control.calls)
    with pytest.raises(RobotError):
        robot.send_twist(twist)
    assert len(control.calls) == before


def test_refused_speedl_raises(robot: URRobot, parts) -> None:
    control, receive = parts
    control.accept = False
    receive.protective = True
    with pytest.raises(RobotError, match="protective stop"):
        robot.send_twist(np.zeros(6))
    receive.protective = False
    with pytest.raises(RobotError, match="refused speedL"):
        robot.send_twist(np.zeros(6))


def test_state_converts_axis_angle(robot: URRobot, parts) -> None:
    control, receive = parts
    receive.speed = [0.03, 0.04, 0.0, 0.0, 0.0, 0.0]
    state = robot.state()
    assert control.calls[-1] == ("kickWatchdog",)
    np.testing.assert_allclose(state.q, receive.q)
    np.testing.assert_allclose(state.tcp.position, [0.3, -0.1, 0.5])
    np.testing.assert_allclose(state.tcp.rotation() @ [0, 0, 1], [0, 0, -1], atol=1e-12)
    assert state.tcp_speed == pytest.approx(0.05)
    assert state.fault is None
    receive.emergency = True
    assert robot.state().fault == "emergency stop"


def test_moves_are_asynchronous_and_end_speed_mode(robot: URRobot, parts) -> None:
    control, _ = parts
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    target = np.array([0.0, -1.57, 1.57, -1.57, -1.57, 0.0])
    control.async_progress = 0
    robot.move_to_joints(target, speed_fraction=0.5)
    assert control.calls[-2] == ("speedStop", 2.0)
    name, q, speed, _accel, asynchronous = control.calls[-1]
    assert (name, q, asynchronous) == ("moveJ", target.tolist(), True)
    assert speed == pytest.approx(np.deg2rad(120) * 0.5)
    assert robot.state().moving
    control.async_progress = -1
    assert not robot.state().moving


def test_move_to_pose_and_stop(robot: URRobot, parts) -> None:
    control, _ = parts
    pose = Pose(np.array([0.4, 0.0, 0.3]), np.array([0.0, 1.0, 0.0, 0.0]))
    control.async_progress = 3
    robot.move_to_pose(pose, speed=0.1)
    name, wire, speed, _accel, asynchronous = control.calls[-1]
    assert (name, speed, asynchronous) == ("moveL", 0.1, True)
    np.testing.assert_allclose(wire[:3], [0.4, 0.0, 0.3])
    np.testing.assert_allclose(np.abs(wire[3:]), [np.pi, 0, 0], atol=1e-12)
    robot.stop()
    assert ("stopL", 2.0) in control.calls[-2:]
    with pytest.raises(RobotError):
        robot.move_to_pose(pose, speed=1.0)
    with pytest.raises(RobotError):
        robot.move_to_joints(np.full(6, 7.0))


def test_disconnect_stops_and_releases(robot: URRobot, parts) -> None:
    control, receive = parts
    robot.send_twist(np.array([0.01, 0, 0, 0, 0, 0]))
    robot.disconnect()
    robot.disconnect()
    assert control.names()[-3:] == ["speedStop", "stopScript", "disconnect"]
    assert receive.disconnected
    with pytest.raises(RobotError, match="not connected"):
        robot.send_twist(np.zeros(6))


def test_lost_control_link_raises(robot: URRobot, parts) -> None:
    control, _ = parts
    control.connected = False
    with pytest.raises(RobotError, match="lost the RTDE control connection"):
        robot.send_twist(np.zeros(6))


def test_pose_conversion_round_trip() -> None:
    rotvec = np.array([0.3, -1.1, 0.7])
    pose = pose_from_ur([0.1, 0.2, 0.3, *rotvec])
    np.testing.assert_allclose(pose.rotation(), Rotation.from_rotvec(rotvec).as_matrix())
    np.testing.assert_allclose(pose_to_ur(pose), [0.1, 0.2, 0.3, *rotvec], atol=1e-12)
    with pytest.raises(RobotError):
        pose_from_ur([1, 2, 3])


# -- a named model: kinematics of the active TCP for the safety layer ---------------------


def _consistent(model_name: str, tool_z: float = 0.15) -> tuple[FakeControl, FakeReceive]:
    """Stand-ins whose reported TCP is the model's flange at the reported joints plus a
    ``tool_z`` tool along the flange's z axis, as a real arm with that TCP reports it."""
    control, receive = FakeControl(), FakeReceive()
    pose = ur_model(model_name).flange_pose(np.asarray(receive.q))
    tip = pose[:3, 3] + tool_z * pose[:3, 2]
    rotvec = Rotation.from_matrix(pose[:3, :3]).as_rotvec()
    receive.tcp = [*tip.tolist(), *rotvec.tolist()]
    return control, receive


def test_a_named_model_declares_the_active_tcps_kinematics() -> None:
    control, receive = _consistent("ur10e", tool_z=0.15)
    arm = URRobot("h", model="ur10e", control_factory=lambda h: control,
                  receive_factory=lambda h: receive)  # fmt: skip
    assert arm.capabilities().kinematics is not None
    arm.connect()
    model = arm.capabilities().kinematics
    q = np.asarray(receive.q)
    np.testing.assert_allclose(model.forward(q)[:3, 3], receive.tcp[:3], atol=1e-9)
    jacobian, step = model.jacobian(q), 1e-6
    for joint in range(6):  # its linear rows are the TCP's velocity per joint speed
        dq = np.zeros(6)
        dq[joint] = step
        moved = model.forward(q + dq)[:3, 3] - model.forward(q - dq)[:3, 3]
        np.testing.assert_allclose(jacobian[:3, joint], moved / (2 * step), atol=1e-6)
    unnamed = URRobot("h", control_factory=lambda h: control, receive_factory=lambda h: receive)
    assert unnamed.capabilities().kinematics is None


def test_the_declaration_gives_the_drawing_and_how_the_arm_stops() -> None:
    named = URRobot("h", model="ur10e", stop_decel=3.0).capabilities()
    assert named.scene is not None and named.scene.caveat == ""
    assert named.stop_time(np.array([0.3, 0, 0, 0, 0, 0])) == pytest.approx(0.1)
    assert named.default_poses == {}  # a real arm goes only to poses the user stored
    unnamed = URRobot("h").capabilities()
    assert unnamed.scene is not None and "draws a UR5e" in unnamed.scene.caveat
    assert "ur:HOST?model=" in unnamed.how_to_complete


def test_without_a_model_the_safety_layer_refuses_the_arm_unless_degraded(caplog) -> None:
    import logging

    with pytest.raises(RobotError, match=r"ur:HOST\?model=ur5e.*safety=degraded") as info:
        SafetyLayer(make_robot("ur:10.0.0.5"))
    assert "\n" not in str(info.value)
    with caplog.at_level(logging.WARNING):
        safe = SafetyLayer(make_robot("ur:10.0.0.5?safety=degraded"))
    assert safe.degraded and "DEGRADED" in caplog.text
    assert not SafetyLayer(make_robot("ur:10.0.0.5?model=ur5e")).degraded


def test_the_wrong_model_is_refused_on_connect() -> None:
    control, receive = _consistent("ur10e")
    arm = URRobot("h", model="ur3e", control_factory=lambda h: control,
                  receive_factory=lambda h: receive)  # fmt: skip
    with pytest.raises(RobotError, match="does not move like a ur3e") as info:
        arm.connect()
    assert "\n" not in str(info.value)
    assert ("disconnect",) in control.calls  # the interfaces were released


def test_with_a_named_model_the_safety_layer_refuses_a_move_through_the_floor() -> None:
    control, receive = _consistent("ur5e")
    arm = URRobot("h", model="ur5e", control_factory=lambda h: control,
                  receive_factory=lambda h: receive)  # fmt: skip
    safe = SafetyLayer(arm)
    safe.connect()
    goal = np.asarray(receive.q) + np.array([0.0, 1.2, 0.0, 0.0, 0.0, 0.0])  # shoulder down
    assert arm.capabilities().kinematics.forward(goal)[2, 3] < 0.05  # below the floor
    with pytest.raises(RobotError, match="outside the workspace box"):
        safe.move_to_joints(goal)
    assert "moveJ" not in control.names()
