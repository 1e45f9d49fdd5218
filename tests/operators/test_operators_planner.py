"""The operator's planner on a scene whose arm the test controls: the branches that the
simulated study rarely reaches and the browser study relies on (a safety stop waited out,
an axis held back left for the other, short moves that get nowhere, the stop key)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from wovenskin.operators.operator import NoProgress, OperatorGaveUp, SimulatedOperator
from wovenskin.operators.profiles import sample_profile
from wovenskin.operators.script import Plan, ScriptRunner, Sleep
from wovenskin.robots.base import Pose

SPEED = 0.05  # m/s: a held press moves the point arm at once at this speed
AXES = ("x", "y", "z")


class PointArm:
    """A TCP that moves along base axes at :data:`SPEED` while a press holds it, unless
    ``blocked(axis, position)``; a safety stop between ``stop_from`` and ``stop_until``
    holds it too.  It quacks like the session the planner reads."""

    def __init__(self, blocked=lambda axis, position: False, nudge_gain: float = 1.0) -> None:
        self.now = 0.0
        self.position = np.array([0.3, 0.0, 0.2])
        self.pressing: tuple[str, int] | None = None
        self.blocked, self.nudge_gain = blocked, nudge_gain
        self.stop_from = self.stop_until = math.inf
        self.user_stopped = False
        self.gripper_closed = False
        settings = SimpleNamespace(linear_speed=SPEED, angular_speed=math.radians(15),
                                   linear_accel=0.5, angular_accel=math.radians(150))  # fmt: skip
        self.mapping = SimpleNamespace(settings=settings)

    @property
    def stopped(self) -> bool:
        return self.stop_from <= self.now < self.stop_until

    def velocity(self) -> np.ndarray:
        v = np.zeros(3)
        if self.pressing is not None and not self.stopped:
            axis, sign = self.pressing
            if not self.blocked(axis, self.position):
                v[AXES.index(axis)] = sign * SPEED
        return v

    @property
    def state(self) -> SimpleNamespace:
        twist = np.concatenate([self.velocity(), np.zeros(3)])
        tcp = Pose(self.position.copy(), np.array([1.0, 0, 0, 0]))
        robot = SimpleNamespace(
            tcp=tcp, tcp_twist=twist, tcp_speed=float(np.linalg.norm(twist[:3]))
        )
        held = None if self.pressing is None else "a key"
        return SimpleNamespace(robot=robot, held=held, gesture=None, stopped=self.stopped)

    def holding(self) -> tuple[str, ...]:
        held_back = self.pressing is not None and self.blocked(self.pressing[0], self.position)
        return ("workspace box",) if held_back else ()

    def step(self, dt: float) -> None:
        self.position = self.position + self.velocity() * dt
        self.now += dt


class KeyHand:
    """Presses and nudges on the :class:`PointArm` (the hand's plan interface)."""

    scale, tool_frame, wrong = 1.0, True, 0

    def __init__(self, arm: PointArm) -> None:
        self.arm = arm
        self.acts: list[str] = []  # "press" or "nudge", in order

    def press(self, axis: str, sign: int, distance: float = math.inf) -> Plan:
        yield Sleep(0.05)
        self.acts.append("press")
        self.arm.pressing = (axis, sign)
        return 1

    def release(self) -> Plan:
        self.arm.pressing = None
        return 0
        yield  # a plan

    def nudge(self, axis: str, sign: int, amount: float) -> Plan:
        yield Sleep(0.05)
        self.acts.append("nudge")
        if not self.arm.blocked(axis, self.arm.position):
            self.arm.position[AXES.index(axis)] += sign * amount * self.arm.nudge_gain
        return 1


def _operator(arm: PointArm, log: list[str]) -> SimulatedOperator:
    profile = sample_profile("T01", "expert", 1)
    return SimulatedOperator(arm, None, KeyHand(arm), profile, np.random.default_rng(0), log.append)


def _run(arm: PointArm, plan: Plan, limit_s: float = 300.0) -> ScriptRunner:
    runner = ScriptRunner()
    runner.start(plan, arm.now)
    while runner.running and arm.now < limit_s:
        arm.step(0.005)
        runner.tick(arm.now)
    assert not runner.running, "the plan did not end"
    return runner


def test_an_axis_is_brought_within_its_tolerance_by_a_press_then_short_moves():
    arm, log = PointArm(), []
    operator = _operator(arm, log)
    runner = _run(arm, operator.move_tcp("x", 0.45, tol=0.002))
    assert runner.error is None
    assert abs(arm.position[0] - 0.45) <= 0.002
    acts = operator.hand.acts
    assert acts[0] == "press" and set(acts[1:]) <= {"nudge"}  # 150 mm held, then short moves


def test_a_safety_stop_during_a_press_is_waited_out_and_not_counted_as_held_back():
    arm, log = PointArm(), []
    arm.stop_from, arm.stop_until = 2.0, 4.0  # the press starts about 1 s in
    operator = _operator(arm, log)
    runner = _run(arm, operator.move_tcp("x", 0.45, tol=0.002))
    assert runner.error is None and abs(arm.position[0] - 0.45) <= 0.002
    assert any("safety layer stopped the arm" in line for line in log)
    assert operator.stuck == 0


def test_an_axis_held_back_three_presses_in_a_row_is_left_for_the_other():
    # y cannot move until x has passed 0.35 m (a joint limit the other axis backs out of)
    arm, log = PointArm(blocked=lambda axis, p: axis == "y" and p[0] < 0.35), []
    operator = _operator(arm, log)
    goal = np.array([0.45, 0.1])
    runner = _run(arm, operator.align_xy(lambda: goal - arm.position[:2], 0.004))
    assert runner.error is None, runner.error
    assert np.all(np.abs(arm.position[:2] - goal) <= 0.004)
    assert any("held back three presses in a row" in line and "the other axis first" in line
               for line in log)  # fmt: skip


def test_an_axis_held_back_for_good_gives_up_naming_it():
    arm, log = PointArm(blocked=lambda axis, p: axis == "y"), []
    runner = _run(arm, _operator(arm, log).align_xy(lambda: np.array([0.0, 0.1]), 0.004, passes=2))
    assert isinstance(runner.error, OperatorGaveUp)
    assert "x, y" in str(runner.error) and "held back" in str(runner.error)


def test_short_moves_that_get_nowhere_end_in_no_progress_when_asked():
    arm, log = PointArm(nudge_gain=0.0), []
    operator = _operator(arm, log)
    error = lambda: 0.01 - arm.position[1]  # noqa: E731
    runner = _run(arm, operator.align("y", error, 0.002, presses=False, stall_after=4))
    assert isinstance(runner.error, NoProgress)
    assert "4 short moves in a row" in str(runner.error)
    assert sum("nudge" in line for line in log) == 4


def test_the_stop_key_ends_the_plan():
    arm, log = PointArm(), []
    arm.user_stopped = True
    runner = _run(arm, _operator(arm, log).move_tcp("x", 0.45))
    assert isinstance(runner.error, OperatorGaveUp) and "stop key" in str(runner.error)


@pytest.mark.parametrize("start", [0.3, 0.5])
def test_the_goal_is_reached_from_either_side(start):
    arm, log = PointArm(), []
    arm.position[2] = start
    runner = _run(arm, _operator(arm, log).move_tcp("z", 0.4, tol=0.002))
    assert runner.error is None and abs(arm.position[2] - 0.4) <= 0.002
