"""SafetyLayer: command checks, caps, workspace box, joint margins, watchdogs, stops, fuzzing.

Most tests drive :class:`GantryRobot`, a kinematic stand-in defined here: joints 1-3 are
the TCP's x, y, z (prismatic, metres), joints 4-6 its rotation vector; a twist is followed
exactly and at once (no deceleration), which is the hardest case for the layer. The fuzz
tests run both against it and against the simulated TM5-900.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wovenskin.bench.safety import joint_6_case
from wovenskin.control.safety import SafetyLayer
from wovenskin.control.safety_limits import SafetyLimits, StopEvent, cap_speeds, keep_in_box
from wovenskin.robots.base import (
    JointLimits,
    Kinematics,
    Pose,
    Robot,
    RobotCapabilities,
    RobotError,
    RobotState,
)
from wovenskin.robots.sim import SimRobot, tm5_900


def rotation_vector_quat(r: np.ndarray) -> np.ndarray:
    angle = float(np.linalg.norm(r))
    if angle < 1e-12:
        return np.array([1.0, 0.0, 0.0, 0.0])
    return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * r / angle])


class GantryRobot(Robot):
    """A kinematic stand-in: q = (x, y, z, rx, ry, rz); ``jacobian`` is the identity."""

    name = "gantry"

    def __init__(self, q0=(0.4, 0.0, 0.3, 0.0, 0.0, 0.0), limits: JointLimits | None = None):
        self.q = np.array(q0, dtype=float)
        self.limits = limits or JointLimits(
            lower=np.array([-1.0, -1.0, 0.0, -1.0, -1.0, -1.0]),
            upper=np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0]),
            max_speed=np.full(6, 2.0),
        )
        self.velocity = np.zeros(6)
        self.goal: np.ndarray | None = None
        self.goal_speed = 0.0
        self.t = 0.0
        self.connected = False
        self.received: list[np.ndarray] = []
        self.stops = 0

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        return np.eye(6)

    def forward_kinematics(self, q: np.ndarray) -> np.ndarray:
        pose = np.eye(4)
        pose[:3, 3] = q[:3]
        return pose

    def capabilities(self) -> RobotCapabilities:
        # it stops at once and follows a twist exactly
        model = Kinematics(self.forward_kinematics, self.jacobian)
        return RobotCapabilities(model, stop_time_s=0.0)

    def connect(self) -> None:
        self.connected = True

    def disconnect(self) -> None:
        self.stop()
        self.connected = False

    def state(self) -> RobotState:
        if not self.connected:
            raise RobotError("gantry is not connected")
        tcp = Pose(self.q[:3], rotation_vector_quat(self.q[3:]))
        moving = bool(np.any(self.velocity))
        return RobotState(self.t, self.q.copy(), self.velocity.copy(), tcp, self.velocity.copy(),
                          moving)  # fmt: skip

    def joint_limits(self) -> JointLimits:
        return self.limits

    def send_twist(self, twist: np.ndarray) -> None:
        twist = np.asarray(twist, dtype=float)
        assert twist.shape == (6,) and np.all(np.isfinite(twist)), "a bad twist got through"
        self.received.append(twist.copy())
        self.goal = None
        self.velocity = twist.copy()

    def move_to_joints(self, q: np.ndarray, speed_fraction: float = 0.2) -> None:
        self.goal = np.asarray(q, dtype=float).copy()
        delta = self.goal - self.q
        self.goal_speed = speed_fraction * float(np.min(self.limits.max_speed))
        self.velocity = delta / max(np.linalg.norm(delta), 1e-12) * self.goal_speed

    def move_to_pose(self, pose: Pose, speed: float = 0.05) -> None:
        self.goal = np.concatenate([pose.position, self.q[3:]])
        delta = self.goal - self.q
        self.velocity = delta / max(np.linalg.norm(delta), 1e-12) * speed

    def stop(self) -> None:
        self.stops += 1
        self.goal = None
        self.velocity = np.zeros(6)

    def step(self, dt: float) -> None:
        self.t += dt
        if self.goal is not None:
            remaining = self.goal - self.q
            if np.linalg.norm(remaining) <= np.linalg.norm(self.velocity) * dt:
                self.q, self.goal, self.velocity = self.goal, None, np.zeros(6)
                return
        self.q = self.q + self.velocity * dt


class NoModelGantry(GantryRobot):
    """The stand-in declaring no kinematics: the layer refuses it unless degraded, and
    then must use the reported motion."""

    degraded_safety = True  # as the robot spec's safety=degraded sets it

    def capabilities(self) -> RobotCapabilities:
        return RobotCapabilities(stop_time_s=0.0)


class CoastingGantry(GantryRobot):
    """The stand-in with a real stop: ``stop`` ramps the velocity down to rest over
    ``stop_time`` (declared), so the arm travels speed x stop_time / 2 after a stop."""

    def __init__(self, *args, stop_time: float = 0.3, declare: bool = True, **kwargs):
        super().__init__(*args, **kwargs)
        self.stop_time = stop_time
        self.declare = declare
        self.braking: np.ndarray | None = None
        self.braked = 0.0

    def capabilities(self) -> RobotCapabilities:
        model = Kinematics(self.forward_kinematics, self.jacobian)
        return RobotCapabilities(model, stop_time_s=self.stop_time if self.declare else None)

    def send_twist(self, twist: np.ndarray) -> None:
        self.braking = None
        super().send_twist(twist)

    def stop(self) -> None:
        self.stops += 1
        self.goal = None
        if self.braking is None and np.any(self.velocity):
            self.braking, self.braked = self.velocity.copy(), 0.0

    def step(self, dt: float) -> None:
        if self.braking is None:
            super().step(dt)
            return
        for _ in range(100):  # integrate the ramp finely
            h = dt / 100
            self.braked += h
            self.velocity = self.braking * max(0.0, 1.0 - self.braked / self.stop_time)
            self.q = self.q + self.velocity * h
            self.t += h
        if not np.any(self.velocity):
            self.braking = None


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


BOX = SafetyLimits(workspace_lower=[0.2, -0.3, 0.1], workspace_upper=[0.6, 0.3, 0.5])


def layer(robot: Robot | None = None, limits: SafetyLimits = BOX, **kwargs):
    robot = robot or GantryRobot()
    clock = Clock()
    safe = SafetyLayer(robot, limits, clock=clock, **kwargs)
    safe.connect()
    return safe, robot, clock


# -- bad commands ------------------------------------------------------------------------


@pytest.mark.parametrize(
    "twist",
    [
        [np.nan, 0, 0, 0, 0, 0],
        [0, 0, np.inf, 0, 0, 0],
        [0, 0, 0, 0, 0, -np.inf],
        [0.01, 0.0, 0.0],
        np.zeros((2, 6)),
        "fast",
        None,
    ],
)
def test_a_bad_twist_stops_the_arm_and_is_never_forwarded(twist, caplog) -> None:
    safe, robot, _ = layer()
    safe.send_twist([0.05, 0, 0, 0, 0, 0])
    sent = len(robot.received)
    with caplog.at_level(logging.WARNING), pytest.raises(ValueError) as info:
        safe.send_twist(twist)
    assert "\n" not in str(info.value)
    assert len(robot.received) == sent and not np.any(robot.velocity)
    assert safe.stopped and safe.stops[-1].source == "command"
    assert "bad command" in caplog.text
    with pytest.raises(RobotError, match="stopped"):  # latched: no motion until cleared
        safe.send_twist([0.05, 0, 0, 0, 0, 0])
    safe.clear_stop()
    safe.send_twist([0.05, 0, 0, 0, 0, 0])
    assert np.any(robot.velocity)


# -- speed caps --------------------------------------------------------------------------


def test_speeds_are_capped_keeping_the_direction() -> None:
    safe, robot, _ = layer()
    safe.send_twist([3.0, 4.0, 0.0, 0.0, 0.0, 20.0])
    sent = robot.received[-1]
    assert np.linalg.norm(sent[:3]) == pytest.approx(0.25)
    np.testing.assert_allclose(sent[:3] / np.linalg.norm(sent[:3]), [0.6, 0.8, 0.0])
    assert np.linalg.norm(sent[3:]) == pytest.approx(BOX.max_angular_speed)
    safe.send_twist([0.01, -0.02, 0.0, 0.1, 0.0, 0.0])  # under the caps: unchanged
    np.testing.assert_array_equal(robot.received[-1], [0.01, -0.02, 0.0, 0.1, 0.0, 0.0])


def test_huge_values_are_capped_without_overflow() -> None:
    capped = cap_speeds(np.array([1e308, -1e308, 1e308, 1e300, 0, 0]), 0.25, 1.0)
    assert np.all(np.isfinite(capped))
    np.testing.assert_allclose(capped[:3], np.array([1, -1, 1]) * 0.25 / math.sqrt(3))
    np.testing.assert_allclose(capped[3:], [1.0, 0, 0])


# -- workspace box -----------------------------------------------------------------------


def test_the_tcp_stops_at_the_wall_of_the_box() -> None:
    safe, robot, _ = layer(GantryRobot(q0=(0.5, 0.0, 0.3, 0, 0, 0)))
    for _ in range(600):  # push toward +x (wall at 0.6) and +y at once
        safe.send_twist([0.2, 0.1, 0.0, 0.0, 0.0, 0.0])
        safe.step(0.01)
        assert robot.q[0] <= 0.6 + 1e-12
    assert robot.q[0] == pytest.approx(0.6, abs=1e-3)  # reached the wall ...
    assert robot.q[1] == pytest.approx(0.3, abs=1e-3)  # ... and slid along it to the corner


def test_a_long_step_does_not_carry_the_tcp_out() -> None:
    safe, robot, _ = layer(GantryRobot(q0=(0.55, 0.0, 0.3, 0, 0, 0)))
    safe.send_twist([0.25, 0, 0, 0, 0, 0])
    safe.step(2.0)  # a stalled loop: the layer re-checks over the step's length
    assert robot.q[0] <= 0.6 + 1e-12


def test_outside_the_box_only_motion_back_inside_is_allowed() -> None:
    safe, robot, _ = layer(GantryRobot(q0=(0.7, 0.0, 0.05, 0, 0, 0)))  # beyond +x and -z
    safe.send_twist([0.1, 0.1, -0.1, 0, 0, 0])
    np.testing.assert_allclose(robot.received[-1][:3], [0.0, 0.1, 0.0])
    safe.send_twist([-0.1, 0.0, 0.1, 0, 0, 0])
    np.testing.assert_allclose(robot.received[-1][:3], [-0.1, 0.0, 0.1])


def test_keep_in_box_limits_each_component_to_the_room_left() -> None:
    v = keep_in_box(np.array([1.0, -1.0, 0.01]), np.array([0.59, -0.28, 0.3]), BOX, 0.1)
    np.testing.assert_allclose(v, [0.1, -0.2, 0.01])


def test_a_pose_target_outside_the_box_is_refused_and_logged(caplog) -> None:
    safe, robot, _ = layer()
    with caplog.at_level(logging.WARNING), pytest.raises(RobotError, match="workspace box"):
        safe.move_to_pose(Pose([0.9, 0.0, 0.3], [1, 0, 0, 0]))
    assert robot.goal is None and "workspace box" in caplog.text
    assert safe.stops[-1].source == "workspace" and not safe.stopped  # refused, not latched
    safe.move_to_pose(Pose([0.3, 0.1, 0.2], [1, 0, 0, 0]), speed=5.0)
    assert np.linalg.norm(robot.velocity[:3]) == pytest.approx(0.25)  # speed capped


def test_a_joint_move_leaving_the_box_is_refused() -> None:
    safe, robot, _ = layer()
    with pytest.raises(RobotError, match="outside the workspace box"):
        safe.move_to_joints([0.4, 0.0, 0.7, 0, 0, 0])
    assert robot.goal is None
    safe.move_to_joints([0.3, 0.1, 0.2, 0.0, 0.0, 0.5], speed_fraction=1.0)
    assert np.linalg.norm(robot.velocity[:3]) <= 0.25 + 1e-9  # slowed to the caps
    assert np.linalg.norm(robot.velocity[3:]) <= BOX.max_angular_speed + 1e-9


def test_a_running_move_is_stopped_before_it_leaves_the_box() -> None:
    safe, robot, clock = layer(NoModelGantry())  # no kinematics: the path cannot be checked
    safe.move_to_joints([0.4, 0.0, 0.9, 0, 0, 0], speed_fraction=0.05)  # heads out of the top
    for _ in range(200):
        clock.now += 0.01
        safe.step(0.01)
        assert robot.q[2] <= 0.5
    assert not np.any(robot.velocity) and safe.stops[-1].source == "workspace"
    assert len(safe.stops) == 1 and not safe.stopped


# -- joint limits ------------------------------------------------------------------------

WIDE = SafetyLimits(workspace_lower=[-2, -2, -2], workspace_upper=[2, 2, 2])


@pytest.mark.parametrize("robot_type", [GantryRobot, NoModelGantry])
def test_joints_stop_at_the_margin_and_may_back_out(robot_type) -> None:
    safe, robot, _ = layer(robot_type(q0=(0.0, 0.0, 0.5, 0.8, 0.0, 0.0)), WIDE)
    margin = WIDE.joint_margin
    for _ in range(300):  # turn joint 4 toward its limit of 1 rad
        safe.send_twist([0.0, 0.0, 0.0, 0.5, 0.0, 0.0])
        safe.step(0.01)
        assert robot.q[3] <= 1.0
    limit = safe.stops[-1]
    assert limit.source == "joint limit" and "joint 4" in limit.reason
    assert len([s for s in safe.stops if s.source == "joint limit"]) == 1  # once, not per tick
    assert robot.q[3] >= 1.0 - margin - 0.02 and not np.any(robot.velocity)
    assert not safe.stopped  # not latched: moving away is allowed
    safe.send_twist([0.0, 0.0, 0.0, -0.5, 0.0, 0.0])
    safe.step(0.1)
    assert robot.q[3] < 1.0 - margin - 0.02


def test_joint_targets_inside_the_margin_are_refused() -> None:
    safe, robot, _ = layer(GantryRobot(q0=(0.0, 0.0, 0.5, 0.0, 0.0, 0.0)), WIDE)
    with pytest.raises(RobotError, match="joint 6"):
        safe.move_to_joints([0, 0, 0.5, 0, 0, 0.99])
    with pytest.raises(ValueError):
        safe.move_to_joints([0, 0, np.nan, 0, 0, 0])
    with pytest.raises(ValueError):
        safe.move_to_joints([0, 0, 0.5, 0, 0, 0], speed_fraction=0.0)
    assert robot.goal is None


def drive(safe: SafetyLayer, clock: Clock, twist, seconds: float, tick: float = 0.005):
    """Send ``twist`` every tick for ``seconds``, then coast 0.5 s; yields after each tick."""
    for i in range(round((seconds + 0.5) / tick)):
        if i * tick < seconds:
            safe.send_twist(twist)
        clock.now += tick
        safe.step(tick)
        yield


@pytest.mark.parametrize("speed", [0.2, 1.0, 2.0])
@pytest.mark.parametrize("declare", [True, False])
def test_the_joint_margin_holds_with_the_stopping_distance(speed, declare) -> None:
    """An arm that needs 0.3 s to stop must be stopped that much earlier: the look-ahead
    includes speed x stop time / 2 (declared, or the assumed 0.3 s when undeclared)."""
    robot = CoastingGantry(q0=(0.0, 0.0, 0.5, 0.6, 0.0, 0.0), declare=declare)
    robot.limits = JointLimits(-np.full(6, 1.0), np.full(6, 1.0), np.full(6, 3.0))
    limits = SafetyLimits(
        workspace_lower=[-2, -2, -2], workspace_upper=[2, 2, 2], max_angular_speed=2.0
    )
    safe, robot, clock = layer(robot, limits)
    closest = min(1.0 - robot.q[3] for _ in drive(safe, clock, [0, 0, 0, speed, 0, 0], 2.0))
    assert closest >= limits.joint_margin - 1e-9
    assert safe.stops and safe.stops[-1].source == "joint limit"


def test_the_box_holds_with_the_stopping_distance() -> None:
    safe, robot, clock = layer(CoastingGantry(q0=(0.5, 0.0, 0.3, 0, 0, 0), stop_time=0.4))
    far = 0.5
    for i, _ in enumerate(drive(safe, clock, [0.25, 0, 0, 0, 0, 0], 1.0)):
        far = max(far, robot.q[0])
        if i == 100:
            safe.emergency_stop("stop key")  # slowing for the wall: the arm coasts 0.4 s
            far = max(far, *(robot.q[0] for _ in drive(safe, clock, np.zeros(6), 0.0)))
            safe.clear_stop()
    assert far <= 0.6 + 1e-9


@pytest.mark.parametrize("speed_deg", [60.0, 148.0])
def test_joint_6_driven_fast_stops_outside_its_margin_on_the_simulated_arm(speed_deg) -> None:
    """The probe's case: joint 6 driven toward its limit came within 3.2 deg (60 deg/s) and
    1.5 deg (148 deg/s) of it with a 5 deg margin: the 20 ms look-ahead ignored the
    ~100 ms the arm takes to stop."""
    q0, limits, twist = joint_6_case(speed_deg)
    safe, robot, clock = layer(SimRobot(q0=q0), limits)
    upper = tm5_900.JOINT_LIMITS.upper[5]
    closest = min(upper - robot.state().q[5] for _ in drive(safe, clock, twist, 2.0))
    assert math.degrees(closest) >= math.degrees(limits.joint_margin) - 1e-6
    assert safe.stops[-1].source == "joint limit" and "joint 6" in safe.stops[-1].reason


# -- one contract for every arm ----------------------------------------------------------


class Misnamed(GantryRobot):
    """Kinematics under other names and no declaration: the old layer fell back, silently,
    to the reported joint velocities."""

    jacobian = None  # type: ignore[assignment]
    forward_kinematics = None  # type: ignore[assignment]

    def jac(self, q):
        return np.eye(6)

    def capabilities(self) -> RobotCapabilities:
        return RobotCapabilities()


def test_an_arm_without_declared_kinematics_is_refused_in_one_line() -> None:
    with pytest.raises(RobotError) as info:
        SafetyLayer(Misnamed(), BOX)
    message = str(info.value)
    assert "\n" not in message
    assert "forward kinematics and Jacobian" in message and "safety=degraded" in message


def test_methods_named_like_kinematics_are_not_taken_without_a_declaration() -> None:
    class Undeclared(GantryRobot):
        def capabilities(self) -> RobotCapabilities:
            return RobotCapabilities()  # jacobian() and forward_kinematics() exist, undeclared

    with pytest.raises(RobotError, match="does not declare"):
        SafetyLayer(Undeclared(), BOX)


def test_the_refusal_says_how_to_complete_the_declaration() -> None:
    class Hinted(Misnamed):
        def capabilities(self) -> RobotCapabilities:
            return RobotCapabilities(how_to_complete="name the model (x:HOST?model=y)")

    with pytest.raises(RobotError, match=r"name the model \(x:HOST\?model=y\); or opt into"):
        SafetyLayer(Hinted(), BOX)


def test_degraded_mode_is_an_opt_in_announced_in_the_log(caplog) -> None:
    with caplog.at_level(logging.WARNING):
        safe = SafetyLayer(Misnamed(), BOX, degraded=True)
    assert safe.degraded and "DEGRADED" in caplog.text and "Jacobian" in caplog.text
    robot = Misnamed()
    robot.degraded_safety = True  # what safety=degraded in the robot spec sets
    assert SafetyLayer(robot, BOX).degraded
    full = SafetyLayer(GantryRobot(), BOX, degraded=True)  # nothing missing: full checks
    assert not full.degraded


def test_explicit_kinematics_complete_an_arm() -> None:
    safe = SafetyLayer(Misnamed(), BOX, jacobian=lambda q: np.eye(6),
                       forward_kinematics=GantryRobot().forward_kinematics)  # fmt: skip
    assert not safe.degraded


def test_the_layer_passes_the_declaration_on() -> None:
    robot = GantryRobot()
    assert SafetyLayer(robot, BOX).capabilities().stop_time_s == 0.0


def test_a_declared_tracking_error_leaves_headroom_under_the_caps() -> None:
    class Sloppy(GantryRobot):
        def capabilities(self) -> RobotCapabilities:
            return RobotCapabilities(super().capabilities().kinematics, tracking_error=0.04)

    safe, robot, _ = layer(Sloppy())
    safe.send_twist([1.0, 0, 0, 0, 0, 5.0])
    assert robot.received[-1][0] == pytest.approx(0.25 / 1.04)
    assert robot.received[-1][5] == pytest.approx(BOX.max_angular_speed / 1.04)


# -- watchdogs and stops -----------------------------------------------------------------


def test_a_stalled_skin_stream_stops_the_arm(caplog) -> None:
    safe, robot, clock = layer()
    safe.heartbeat_skin()
    safe.send_twist([0.05, 0, 0, 0, 0, 0])
    clock.now = 0.09
    safe.heartbeat_command()
    assert safe.check() == [] and np.any(robot.velocity)
    clock.now = 0.11
    with caplog.at_level(logging.WARNING):
        fired = safe.check()
    assert [e.source for e in fired] == ["skin watchdog"] and "skin" in fired[0].reason
    assert fired[0].t == pytest.approx(0.11) and fired[0] in safe.stops
    assert safe.stopped and not np.any(robot.velocity) and "skin" in caplog.text
    assert safe.check(0.5) == []  # one stop per stall


def test_a_silent_command_stream_stops_the_arm() -> None:
    safe, robot, clock = layer()
    safe.send_twist([0.05, 0, 0, 0, 0, 0])  # a command is also a heartbeat
    clock.now = 0.1
    assert safe.check() == []
    fired = safe.check(0.1001)
    assert fired and fired[0].source == "command watchdog" and "command" in fired[0].reason
    assert not np.any(robot.velocity) and safe.stopped


def test_watchdogs_wait_for_their_first_heartbeat_and_rearm_on_clear() -> None:
    safe, robot, clock = layer()
    clock.now = 10.0
    assert safe.check() == []  # nothing streamed yet: nothing to miss
    safe.heartbeat_skin()
    safe.heartbeat_command()
    clock.now = 10.5
    assert len(safe.check()) == 1
    safe.clear_stop()  # they count again from now
    assert safe.check(10.55) == []
    assert len(safe.check(10.61)) == 1


def test_the_emergency_stop_latches_until_cleared() -> None:
    safe, robot, clock = layer()
    safe.send_twist([0.05, 0, 0, 0, 0, 0])
    safe.emergency_stop("stop key pressed")
    assert safe.stopped and not np.any(robot.velocity)
    assert safe.stops[-1] == StopEvent(0.0, "stop key pressed", "emergency")
    safe.send_twist(np.zeros(6))  # holding still is fine
    for move in (
        lambda: safe.send_twist([0.05, 0, 0, 0, 0, 0]),
        lambda: safe.move_to_joints([0.4, 0.0, 0.3, 0, 0, 0]),
        lambda: safe.move_to_pose(Pose([0.4, 0.0, 0.3], [1, 0, 0, 0])),
    ):
        with pytest.raises(RobotError, match="stop key pressed"):
            move()
    assert not np.any(robot.velocity) and robot.goal is None
    safe.clear_stop()
    safe.send_twist([0.05, 0, 0, 0, 0, 0])
    assert np.any(robot.velocity) and not safe.stopped


def test_backend_errors_pass_through_without_latching() -> None:
    class Unplugged(GantryRobot):
        def send_twist(self, twist):
            raise RobotError("connection lost")

    safe, _, _ = layer(Unplugged())
    with pytest.raises(RobotError, match="connection lost"):
        safe.send_twist([0.05, 0, 0, 0, 0, 0])
    assert not safe.stopped


def test_limits_refuse_bad_settings() -> None:
    with pytest.raises(ValueError, match="lower"):
        SafetyLimits(workspace_lower=[0, 0, 1], workspace_upper=[1, 1, 0])
    with pytest.raises(ValueError, match="max_linear_speed"):
        SafetyLimits(max_linear_speed=float("nan"))


# -- fuzzing -----------------------------------------------------------------------------

wild = st.one_of(
    st.floats(-2.0, 2.0),
    st.sampled_from([0.0, 1e6, -1e6, 1e300, -1e300, np.nan, np.inf, -np.inf]),
)
twists = st.one_of(
    st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).map(lambda v: [*v, 0.0, 0.0, 0.0]),
    st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6),
    st.lists(wild, min_size=6, max_size=6),
)
steps = st.floats(0.0, 1.0)
point = st.tuples(st.floats(-0.2, 1.0), st.floats(-0.6, 0.6), st.floats(-0.2, 0.8))
motions = st.one_of(
    st.tuples(st.just("twist"), twists, steps),
    st.tuples(st.just("hold"), twists, steps),  # sent again on every tick, like the loop
    st.tuples(st.just("flip"), twists, steps),  # the twist, then its opposite, then again
)
commands = st.one_of(
    motions,
    motions,  # motion more often than the rest
    st.tuples(st.just("pose"), point, steps),
    st.tuples(st.just("joints"), st.lists(st.floats(-1.5, 1.5), min_size=6, max_size=6), steps),
    st.tuples(st.just("stop"), st.just(None), steps),
    st.tuples(st.just("estop"), st.just(None), steps),
    st.tuples(st.just("clear"), st.just(None), steps),
    st.tuples(st.just("silence"), st.just(None), steps),  # no heartbeats for a while
)


def apply(safe: SafetyLayer, kind: str, value, robot_q) -> None:
    try:
        if kind in ("twist", "hold"):
            safe.send_twist(value)
        elif kind == "flip":
            for sign in (1.0, -1.0, 1.0):
                safe.send_twist(np.asarray(value, dtype=float) * sign)
        elif kind == "pose":
            safe.move_to_pose(Pose(value, [1.0, 0.0, 0.0, 0.0]), speed=1.0)
        elif kind == "joints":
            safe.move_to_joints(robot_q(value), speed_fraction=1.0)
        elif kind == "stop":
            safe.stop()
        elif kind == "estop":
            safe.emergency_stop("fuzz")
        elif kind == "clear":
            safe.clear_stop()
    except (ValueError, RobotError):
        pass


def assert_safe(safe: SafetyLayer, limits: JointLimits, speed_tolerance: float, box_tol: float):
    state = safe.state()
    assert state.tcp_speed <= safe.limits.max_linear_speed * (1 + speed_tolerance) + 1e-6
    angular = float(np.linalg.norm(state.tcp_twist[3:]))
    assert angular <= safe.limits.max_angular_speed * (1 + speed_tolerance) + 1e-6
    assert safe.limits.in_box(state.tcp.position, box_tol), state.tcp.position
    assert np.all(state.q >= limits.lower - 1e-9) and np.all(state.q <= limits.upper + 1e-9)


def run_fuzz(robot: Robot, limits: SafetyLimits, program, robot_q, speed_tol, box_tol, substep):
    clock = Clock()
    safe = SafetyLayer(robot, limits, clock=clock)
    safe.connect()
    joint_limits = robot.joint_limits()
    for kind, value, dt in program:
        apply(safe, kind, value, robot_q)
        assert_safe(safe, joint_limits, speed_tol, box_tol)
        elapsed = 0.0
        while elapsed < dt:  # the loop ticks; heartbeats stop during "silence"
            h = min(substep, dt - elapsed)
            elapsed += h
            clock.now += h
            if kind != "silence":
                safe.heartbeat_skin()
                safe.heartbeat_command()
            safe.check()
            if kind == "hold":
                apply(safe, kind, value, robot_q)
            safe.step(h)
            assert_safe(safe, joint_limits, speed_tol, box_tol)
    return safe


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(commands, min_size=1, max_size=25), st.sampled_from([GantryRobot, NoModelGantry]))
def test_fuzzed_commands_never_break_the_limits_of_the_stand_in(program, robot_type) -> None:
    robot = robot_type(q0=(0.4, 0.0, 0.3, 0.0, 0.0, 0.0))
    tight_joints = JointLimits(  # joint z ends below the box top: the margins bind too
        lower=np.array([-1.0, -1.0, 0.0, -2.0, -2.0, -2.0]),
        upper=np.array([1.0, 1.0, 0.45, 2.0, 2.0, 2.0]),
        max_speed=np.full(6, 2.0),
    )
    robot.limits = tight_joints

    def joints(values):  # joint targets around the start, some out of the box or limits
        return np.array([0.4, 0.0, 0.3, 0.0, 0.0, 0.0]) + np.array(values) * [
            0.2,
            0.3,
            0.15,
            1,
            1,
            1,
        ]

    # the stand-in without a model sees joint motion one tick late: it can enter the margin
    # but never the limit itself, and stops at once, so no tolerance is needed anywhere
    run_fuzz(robot, BOX, program, joints, speed_tol=0.0, box_tol=1e-9, substep=0.05)


@pytest.mark.slow  # 60 programs on the MuJoCo arm, ~7 s: `make test-fast` leaves it out
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(commands, min_size=1, max_size=15))
def test_fuzzed_commands_never_break_the_limits_of_the_simulated_arm(program) -> None:
    robot = SimRobot()
    start = tm5_900.forward_kinematics(tm5_900.INITIAL_Q)[:3, 3]
    box = SafetyLimits(workspace_lower=start - [0.15, 0.2, 0.15], workspace_upper=start + 0.15)

    def joints(values):  # joint targets around the initial pose
        return tm5_900.INITIAL_Q + np.asarray(values) * 0.6

    # caps and box hold as the arm reports them: floating-point noise only, 1 um (was 3 %
    # and 2 mm; a nanometre tolerance let hypothesis fail on 5 nm of rounding)
    run_fuzz(robot, box, program, joints, speed_tol=0.0, box_tol=1e-6, substep=0.02)


segments = st.lists(
    st.tuples(
        st.one_of(
            st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6),
            st.lists(st.sampled_from([0.0, 0.05, -0.3, 1.0, -3.0]), min_size=6, max_size=6),
        ),
        st.floats(0.02, 0.4),  # seconds the twist is held
        st.sampled_from([0.005, 0.01, 0.02]),  # the control loop's tick
    ),
    min_size=1,
    max_size=6,
)


@pytest.mark.slow
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(segments, st.lists(st.floats(-0.7, 0.7), min_size=6, max_size=6))
def test_random_twists_keep_the_measured_caps_and_the_box_on_the_simulated_arm(
    program, offset
) -> None:
    """Caps hold as the arm reports them (not only as commanded): TCP linear and angular
    speed never above the caps, the TCP never outside the box, no joint inside its margin.
    The probe found 1.03x the linear cap, 1.016x the angular one and 0.13 mm outside."""
    q0 = tm5_900.INITIAL_Q + np.asarray(offset)  # postures near singularities too
    start = tm5_900.forward_kinematics(q0)[:3, 3]
    box = SafetyLimits(workspace_lower=start - 0.08, workspace_upper=start + 0.08)
    safe, robot, clock = layer(SimRobot(q0=q0), box)
    joints = robot.joint_limits()
    for twist, seconds, tick in program:
        for _ in drive(safe, clock, twist, seconds, tick):
            # Tolerances are floating-point noise only (1 um, 1 um/s, 1 urad): hypothesis
            # once found the TCP 5 nm past a face; the probe behind issue 12 found 0.13 mm
            # outside and speeds 1.6-3 % over the caps.
            state = robot.state()
            assert state.tcp_speed <= box.max_linear_speed + 1e-6
            assert float(np.linalg.norm(state.tcp_twist[3:])) <= box.max_angular_speed + 1e-6
            assert box.in_box(state.tcp.position, 1e-6), state.tcp.position - start
            inside = joints.upper - box.joint_margin - state.q
            assert np.all(np.minimum(inside, state.q - joints.lower - box.joint_margin) > -1e-6)


def test_a_turning_tool_driven_into_a_corner_stays_in_the_box() -> None:
    """Hypothesis found it (2026-11-28): turning about y at 1 rad/s while driving into the
    box's +x/+z corner, the TCP's path bent 1.2 um past the face the straight-line look-ahead
    had stopped it at; the look-ahead now keeps the arc's sagitta off the walls."""
    q0 = tm5_900.INITIAL_Q
    start = tm5_900.forward_kinematics(q0)[:3, 3]
    box = SafetyLimits(workspace_lower=start - 0.08, workspace_upper=start + 0.08)
    safe, robot, clock = layer(SimRobot(q0=q0), box)
    program = [
        ([0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 0.25), ([0.0, 0.0, 0.0, 0.0, -3.0, 0.0], 0.25),
        ([1.0, 0.0, 1.0, 0.0, 0.0, 0.0], 0.125), ([1.0, 0.0, 1.0, 0.0, 1.0, 0.0], 0.25),
    ]  # fmt: skip
    for twist, seconds in program:
        for _ in drive(safe, clock, twist, seconds, 0.005):
            assert box.in_box(robot.state().tcp.position, 1e-6)


class SpinningGantry(GantryRobot):
    """A backend whose pose moves turn the tool at 3 rad/s, whatever it is asked."""

    def move_to_pose(self, pose: Pose, speed: float = 0.05) -> None:
        super().move_to_pose(pose, speed)
        self.velocity[3:] = [0.0, 0.0, 3.0]


def test_a_pose_move_that_turns_the_tool_too_fast_is_stopped() -> None:
    safe, robot, _ = layer(SpinningGantry(q0=(0.4, 0.0, 0.3, 0.0, 0.0, 0.0)))
    safe.move_to_pose(Pose([0.45, 0.0, 0.3], [1.0, 0.0, 0.0, 0.0]), speed=0.05)
    safe.step(0.01)
    assert robot.stops == 1 and not np.any(robot.velocity)
    assert "turned the tool at 172 deg/s" in safe.stops[-1].reason


def test_a_pose_move_that_turns_the_tool_keeps_under_the_angular_cap() -> None:
    """Hypothesis found it: a pose move on the MuJoCo arm turned the tool from the initial
    pose to the base's orientation at 1.055 rad/s, over the 1.047 cap (the move's speed
    was chosen for its travel only)."""
    start = tm5_900.forward_kinematics(tm5_900.INITIAL_Q)[:3, 3]
    box = SafetyLimits(workspace_lower=start - [0.15, 0.2, 0.15], workspace_upper=start + 0.15)
    program = [("pose", (0.375, 0.0, 0.25), 1.0), ("clear", None, 1.0)]
    joints = lambda values: tm5_900.INITIAL_Q + np.asarray(values) * 0.6  # noqa: E731
    run_fuzz(SimRobot(), box, program, joints, speed_tol=0.0, box_tol=1e-6, substep=0.02)
