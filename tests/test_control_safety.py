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

from wovenskin.control.safety import (
    SafetyLayer,
    SafetyLimits,
    StopEvent,
    cap_speeds,
    keep_in_box,
)
from wovenskin.robots.base import JointLimits, Pose, Robot, RobotError, RobotState


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
    """The stand-in without Jacobian or kinematics: the layer must use reported motion."""

    jacobian = None  # type: ignore[assignment]
    forward_kinematics = None  # type: ignore[assignment]


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
    assert state.tcp_speed <= safe.limits.max_linear_speed * (1 + speed_tolerance) + 1e-9
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


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(commands, min_size=1, max_size=15))
def test_fuzzed_commands_never_break_the_limits_of_the_simulated_arm(program) -> None:
    sim = pytest.importorskip("wovenskin.robots.sim")  # another helper's backend
    from wovenskin.robots.sim import tm5_900

    robot = sim.SimRobot()
    start = tm5_900.forward_kinematics(tm5_900.INITIAL_Q)[:3, 3]
    box = SafetyLimits(workspace_lower=start - [0.15, 0.2, 0.15], workspace_upper=start + 0.15)

    def joints(values):  # joint targets around the initial pose
        return tm5_900.INITIAL_Q + np.asarray(values) * 0.6

    run_fuzz(robot, box, program, joints, speed_tol=0.03, box_tol=2e-3, substep=0.02)
