"""A simulated operator: looks at the scene, plans the next move, acts through a hand.

:class:`SimulatedOperator` carries out pick-and-place (each shape of the scene into its
mold: above the object, its faces turned to the fingers, down, grasp, up, over the mold,
turned to the pocket, down, release, up) and pouring (grasp the cup low, carry it over
the container, tilt it until it is empty) one axis at a time, closed loop: before each
move it thinks (the profile's M, longer while it hesitates, shorter with practice), starts
the move through its hand, watches the arm, and lets go when the goal is as near as its
reaction time and its anticipation allow (a novice overshoots more and corrects more).
Short corrections are nudges: a tapped key, a pendant step, a short gesture.  It reads
the scene as a person at the table sees it: the arm's TCP, the objects' poses (from the
task's physics), the gripper's opening.  It never judges success: the study's trial
runner does, from the task's state.  A plan that cannot go on raises
:class:`OperatorGaveUp` (the trial then runs into its time limit, as a person who gives up
would be stopped).

The same planner drives the browser study (``tests/ui/test_ui_study_browser.py``): there
its hand acts through the page (keys, jog buttons, gestures drawn with the mouse) and a
thread steps the plan with :func:`~wovenskin.operators.script.run_blocking` on the
session's clock instead of the session's tick callback.  So the plan never assumes that an
act takes effect at once: it waits for the arm to come to rest over several session
instants, and a stop of the safety layer (which the session clears once nothing is held)
is waited out.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from wovenskin.operators.hands import ROTATIONS, TRANSLATIONS, Hand
from wovenskin.operators.profiles import OperatorProfile
from wovenskin.operators.script import Plan, Sleep, Timeout, Until
from wovenskin.tasks.pick_place import MOLD_Y
from wovenskin.tasks.pour import CONTAINER_XY
from wovenskin.tasks.scene import body_yaw_and_tilt
from wovenskin.tasks.shapes import MOLD_HEIGHT, Shape

STUCK_S = 3.0  # a press that moves nothing this long is let go
MAX_LEAD_S = 1.5  # the most a person learns to let go early
APPROACH_MARGIN = 0.025  # m: held moves toward contact stop this far above it
WRONG_WAY = {"linear": 0.004, "angular": math.radians(3.0)}  # seen going the wrong way


class OperatorGaveUp(Exception):
    """The operator could not go on (three presses held back, a shape that would not seat)."""


class HeldBack(OperatorGaveUp):
    """Three presses in a row along one axis went nowhere (a limit holds the arm back)."""


class NoProgress(OperatorGaveUp):
    """Short moves that move the arm but not what the operator steers by (a held shape
    that turns in the fingers instead of with them)."""


class Missed(Exception):
    """A grasp did not hold the object: pick it up again."""


def wrap(angle: float, period: float = 2 * math.pi) -> float:
    """``angle`` into ``[-period/2, period/2)``."""
    return (angle + period / 2) % period - period / 2


class SimulatedOperator:
    """Completes the session's task through ``hand`` (module docstring)."""

    def __init__(
        self,
        session: Any,
        task: Any,
        hand: Hand,
        profile: OperatorProfile,
        rng: np.random.Generator,
        log: Callable[[str], None] | None = None,
    ) -> None:
        self.session, self.task, self.hand = session, task, hand
        self.profile, self.rng = profile, rng
        self.log = log or (lambda text: None)
        settings = session.mapping.settings
        self.speed = {"linear": settings.linear_speed, "angular": settings.angular_speed}
        self.accel = {"linear": settings.linear_accel, "angular": settings.angular_accel}
        self.trial = 1
        self.gain: dict[str, float] = {}  # per kind: how much more to ask of a short move
        self.lead: dict[str, float] = {}  # per kind: how much earlier (s) to let go
        self.release_speed: dict[str, float] = {}  # per kind: the speed seen when letting go
        self.stuck = 0

    # -- what the operator sees

    @property
    def robot(self) -> Any:
        return self.session.state.robot

    def tcp(self) -> np.ndarray:
        return np.asarray(self.robot.tcp.position, dtype=float)

    def tool_axes(self) -> np.ndarray:
        return self.robot.tcp.rotation().T

    def closing_angle(self) -> float:
        """Direction (rad, about base z) of the gripper's closing axis (the tool's y)."""
        y = self.tool_axes()[1]
        return math.atan2(y[1], y[0])

    def tilt(self) -> float:
        """The tool's z axis from straight down, signed as a turn about base +x (rad)."""
        z = self.tool_axes()[2]
        return math.atan2(z[1], -z[2])

    def body(self, name: str) -> tuple[np.ndarray, float]:
        physics = self.task.physics
        body = physics.model.body(name).id
        yaw, _ = body_yaw_and_tilt(physics.data, body)
        return physics.data.xpos[body].copy(), yaw

    def measure(self, axis: str) -> float:
        if axis in TRANSLATIONS:
            return float(self.tcp()[TRANSLATIONS.index(axis)])
        if axis == "rx":
            return self.tilt()
        if axis == "rz":
            return self.closing_angle()
        raise OperatorGaveUp(f"no measure of {axis}")

    # -- acting

    def think(self) -> Plan:
        """Mental preparation before a move (and a second look while hesitating)."""
        seconds = self.profile.thinking(self.trial)
        if self.rng.random() < self.profile.hesitation:
            seconds *= 2
        yield Sleep(seconds * float(self.rng.lognormal(0.0, 0.25)))

    def settle(self, timeout_s: float = 30.0) -> Plan:
        """Wait until nothing is held, no stop holds the arm and it is still, seen at three
        session instants in a row, then take it in (a reaction).  A stop the session
        clears by itself (any but the stop key's) is waited out; the stop key's ends the
        plan."""
        looks = [math.nan, 0]  # the session instant last looked at, quiet looks in a row

        def quiet() -> bool:
            if self.session.user_stopped:
                return True  # the plan ends below
            now = float(self.session.now)
            if now == looks[0]:
                return looks[1] >= 3
            s = self.session.state
            robot = s.robot
            ok = s.held is None and s.gesture is None and not s.stopped and robot is not None
            ok = ok and robot.tcp_speed < 5e-4 and float(np.linalg.norm(robot.tcp_twist[3:])) < 5e-3
            looks[0], looks[1] = now, looks[1] + 1 if ok else 0
            return looks[1] >= 3

        yield Until(quiet, timeout_s, "the arm at rest")
        if self.session.user_stopped:
            raise OperatorGaveUp("the stop key holds the arm")
        yield Sleep(self.profile.reaction_s)

    def align(self, axis: str, error: Callable[[], float], tol: float, presses: bool = True,
              timeout_s: float = 120.0, stall_after: int | None = None) -> Plan:  # fmt: skip
        """Drive ``axis`` until ``|error()| <= tol`` (goal minus now, m or rad).
        ``presses`` False: short moves only.  ``stall_after``: :class:`NoProgress` after
        that many short moves in a row that brought the error down by less than a tenth of
        what they asked."""
        kind = "angular" if axis in ROTATIONS else "linear"
        a = self.accel[kind]
        aim = tol * self.profile.precision
        start = self.session.now
        stalled = 0
        yield from self.settle()
        while True:
            e = float(error())
            if abs(e) <= tol:
                return
            if self.session.now - start > timeout_s:
                raise OperatorGaveUp(f"{axis}: error {e:+.4f} > {tol} after {timeout_s:g} s")
            sign = 1 if e > 0 else -1
            self.log(f"{self.session.now:7.2f} s  {axis} {e:+.4f} (tolerance {tol:g})")
            yield from self.think()
            v = self.speed[kind] * self.hand.scale
            brake = v * v / (2 * a)
            if presses and abs(e) > 2 * brake + v * self.profile.reaction_s:
                sent = yield from self.hand.press(axis, sign, abs(e))
                v = self.speed[kind] * self.hand.scale
                brake = v * v / (2 * a)
                reached = False
                try:
                    if sent:
                        reached = yield from self._hold(axis, sign, error, brake, v, aim, kind)
                except HeldBack:  # let go before leaving the axis for the other
                    yield from self.hand.release()
                    raise
                yield from self.hand.release()
                yield from self.settle()
                if reached:  # learn how late a release acts: let go earlier or later
                    past = -sign * float(error())  # > 0: beyond the goal
                    rate = self.profile.anticipation  # novices learn it more slowly
                    seen_v = max(self.release_speed.get(kind, v), 0.2 * v)
                    lead = (
                        self.lead.get(kind, 0.0)
                        + rate * (past if past > 0 else 0.5 * past) / seen_v
                    )
                    self.lead[kind] = float(np.clip(lead, 0.0, MAX_LEAD_S))
            else:
                exact = not self.hand.tool_frame  # a pendant step moves its increment
                gain = 1.0 if exact else self.gain.get(kind, 1.0)
                full = self.speed[kind]  # a short move's size does not shrink with the speed
                cap = full * full / a + full * 0.3
                asked = min(abs(e) * gain, abs(e) + 0.1 * brake, cap)
                self.log(f"{self.session.now:7.2f} s  {axis} nudge {sign * asked:+.4f}")
                yield from self.hand.nudge(axis, sign, asked)
                yield from self.settle()
                done = sign * (e - float(error()))
                stalled = stalled + 1 if done < 0.1 * asked else 0
                if stall_after is not None and stalled >= stall_after:
                    raise NoProgress(f"{axis}: {stalled} short moves in a row left it at {e:+.4f}")
                if not exact and done > 0:
                    change = abs(e) / done
                    self.gain[kind] = float(np.clip(gain * np.clip(change, 0.7, 1.4), 0.5, 3.0))

    def _hold(self, axis: str, sign: int, error: Callable[[], float], brake: float,
              v: float, aim: float, kind: str) -> Plan:  # fmt: skip
        """Hold until the goal is within what the person anticipates of its reaction, the
        arm's braking and how late it has learnt its releases act with this interface
        (a lifted gesture ends its command later than a released key); let go a reaction
        time later.  The wrong way: let go and correct; no motion for :data:`STUCK_S`:
        let go (three in a row: :class:`HeldBack`); a stop of the safety layer: let go.
        The person judges by the speed it sees the arm
        move at (an arm still speeding up, as a held gesture's does, is let go later than
        one at full speed).  Returns whether it let go for the goal."""
        p = self.profile
        lead = self.lead.get(kind, 0.0)
        accel = v * v / (2.0 * brake) if brake > 0 else self.accel[kind]
        origin = self.measure(axis)
        e0 = float(error())
        last = [origin, self.session.now]

        def went(now: float) -> float:
            moved = now - origin
            return wrap(moved) if axis in ROTATIONS else moved

        def seen() -> float:
            twist = self.robot.tcp_twist
            speed = float(np.linalg.norm(twist[3:] if kind == "angular" else twist[:3]))
            speed = min(speed, v)
            self.release_speed[kind] = speed
            return p.anticipation * (speed * speed / (2.0 * accel) + speed * p.reaction_s) + (
                speed * lead + aim
            )

        def look() -> bool:
            if self.session.state.stopped:
                return True
            now = self.measure(axis)
            if sign * float(error()) <= seen():
                return True
            if -sign * went(now) > WRONG_WAY[kind]:
                return True
            if abs(now - last[0]) > 1e-4:
                last[0], last[1] = now, self.session.now
            return self.session.now - last[1] > STUCK_S

        try:
            yield Until(look, 4 * abs(e0) / v + 10.0, f"the {axis} goal")
        except Timeout:
            return False
        reached = False
        if self.session.state.stopped:
            self.log(f"{axis}: the safety layer stopped the arm, let go")
        elif -sign * went(self.measure(axis)) > WRONG_WAY[kind]:
            self.log(f"{axis}: going the wrong way, let go")  # a reaction time after seeing it
        elif sign * float(error()) > seen():
            self.stuck += 1
            held = ", ".join(self._holding()) or "nothing said"
            self.log(f"{axis}: no motion while pressed ({held})")
            if self.stuck >= 3:
                self.stuck = 0
                raise HeldBack(f"{axis}: held back three presses in a row ({held})")
            return False
        else:
            self.stuck, reached = 0, True
        yield Sleep(p.reaction_s)
        return reached

    def _holding(self) -> list[str]:
        """What the safety layer says holds the arm back now."""
        return [str(reason) for reason in self.session.holding()]

    def align_xy(self, error: Callable[[], np.ndarray], tol: float, passes: int = 10) -> Plan:
        """Both ``error()[0]`` (x) and ``[1]`` (y) within ``tol``, y first.  An axis held
        back (in the tool frame a turned gripper's key carries the TCP along a diagonal, to
        the edge of the reach or the elbow's fold limit) is left for the other, as a person
        does: that one brings the TCP back, and the next pass tries it again."""
        held: HeldBack | None = None
        for _ in range(passes):
            for i, axis in ((1, "y"), (0, "x")):
                try:
                    yield from self.align(axis, lambda i=i: error()[i], tol)
                except HeldBack as exc:
                    held = exc
                    self.log(f"{exc}: the other axis first")
            yield from self.settle()
            if np.all(np.abs(error()[:2]) <= tol):
                return
        raise OperatorGaveUp(f"x, y: error {error()[:2]} > {tol}" + (f" ({held})" if held else ""))

    def move_tcp(self, axis: str, goal: float, tol: float = 0.002, presses: bool = True) -> Plan:
        i = TRANSLATIONS.index(axis)
        yield from self.align(axis, lambda: goal - self.tcp()[i], tol, presses=presses)

    def approach(self, goal_z: float, tol: float, margin: float = APPROACH_MARGIN) -> Plan:
        """Down to ``goal_z`` near contact as people do: a held move to ``margin`` above
        it (an overshoot there touches nothing), then short moves only."""
        if self.tcp()[2] - goal_z > 2 * margin:
            yield from self.move_tcp("z", goal_z + margin, margin / 2)
        yield from self.move_tcp("z", goal_z, tol, presses=False)

    def gripper(self, close: bool, timeout_s: float = 20.0) -> Plan:
        """Toggle the gripper to ``close`` and wait until its fingers stop."""
        yield from self.settle()
        if bool(self.session.gripper_closed) != close:
            yield from self.hand.gripper()
            yield Until(lambda: bool(self.session.gripper_closed) == close, timeout_s, "gripper")
        last = [None, self.session.now]

        def stopped() -> bool:
            width = self.robot.gripper.width
            if last[0] is None or abs(width - last[0]) > 2e-4:
                last[0], last[1] = width, self.session.now
            return self.session.now - last[1] > 0.6

        yield Until(stopped, timeout_s, "the fingers at rest")

    # -- the tasks

    def run(self, trial: int) -> Plan:
        """The whole task of trial ``trial`` (1-based: practice shortens the thinking)."""
        self.trial = max(1, int(trial))
        yield Sleep(self.profile.thinking(self.trial))  # looks at the scene first
        if self.task.name == "pick_place":
            yield from self.pick_place()
        elif self.task.name == "pour":
            yield from self.pour()
        else:
            raise OperatorGaveUp(f"no plan for the task {self.task.name!r}")

    def pick_place(self, travel_z: float = 0.062, grasp_z: float = 0.027) -> Plan:
        """Seat every shape of the scene in its mold, retrying a shape that did not seat."""
        for shape, row_x in zip(self.task.shapes, self.task.row_x, strict=True):
            for _attempt in range(3):
                try:
                    yield from self._carry(shape, row_x, travel_z, grasp_z)
                except Missed as missed:
                    self.log(f"{shape.name}: {missed}")
                    continue
                yield Sleep(0.3)
                if any(o.seated for o in self.task.state().objects if o.name == shape.name):
                    break
            else:
                raise OperatorGaveUp(f"{shape.name} would not seat in three attempts")

    def _carry(self, shape: Shape, row_x: float, travel_z: float, grasp_z: float) -> Plan:
        def obj() -> tuple[np.ndarray, float]:
            return self.body(shape.name)

        yield from self.settle()
        if abs(self.tcp()[2] - travel_z) > 0.006:
            yield from self.move_tcp("z", travel_z, 0.006)
        yield from self.align_xy(lambda: obj()[0] - self.tcp(), 0.005)
        if shape.symmetry is not None:
            period = math.pi / 3 if shape.sides == 3 else shape.symmetry
            yield from self.align(
                "rz", lambda: wrap(obj()[1] - self.closing_angle(), period), math.radians(4)
            )
        resting_z = obj()[0][2]
        yield from self.approach(grasp_z, 0.004)
        yield from self.settle()
        off = float(np.linalg.norm(obj()[0][:2] - self.tcp()[:2]))
        if off > 0.008:
            yield from self.move_tcp("z", travel_z, 0.006)
            raise Missed(f"pushed {1000 * off:.0f} mm off the fingers' centre")
        yield from self.gripper(True)
        yield from self.move_tcp("z", travel_z, 0.006)
        yield from self.settle()
        if obj()[0][2] < resting_z + 0.015:
            yield from self.gripper(False)
            raise Missed("not lifted by the grasp")
        mold = np.array([row_x, MOLD_Y])

        dropped: list[str] = []

        def to_mold() -> np.ndarray:
            # a shape that slipped out stays behind: a person sees it and picks it up
            # again (steering by it would drive the empty gripper on to the reach's edge);
            # no way left to go ends the move, and the plan checks (predicates never raise)
            position = obj()[0]
            if position[2] < resting_z + 0.005:
                if not dropped:
                    dropped.append(f"dropped at ({position[0]:.3f}, {position[1]:.3f})")
                return np.zeros(2)
            return mold - position[:2]

        def pick_up_again() -> Plan:
            yield from self.gripper(False)
            yield from self.move_tcp("z", travel_z, 0.006)
            raise Missed(f"{dropped[0]} on the way to its mold")

        yield from self.align_xy(to_mold, 0.006)
        if dropped:
            yield from pick_up_again()
        if shape.symmetry is not None:
            try:
                turn = lambda: -wrap(obj()[1], shape.symmetry)  # noqa: E731
                yield from self.align("rz", turn, math.radians(2), stall_after=6)
            except NoProgress as turning:  # it turns in the fingers: grasp it again
                dropped.append(str(turning))
                yield from pick_up_again()
        yield from self.align_xy(to_mold, 0.0018)
        if dropped:
            yield from pick_up_again()
        yield from self.settle()
        drop = obj()[0][2] - (shape.height / 2 + 0.003)
        goal = max(self.tcp()[2] - drop, MOLD_HEIGHT + 0.006)
        yield from self.approach(goal, 0.003)
        yield from self.gripper(False)
        yield from self.move_tcp("z", travel_z, 0.006)

    def pour(self, grasp_z: float = 0.03, carry_z: float = 0.14, pour_y: float = -0.19) -> Plan:
        """Grasp the cup low, carry it over the container, tilt it about base +x until it
        is empty."""

        def cup() -> np.ndarray:
            return self.body("cup")[0]

        yield from self.move_tcp("z", carry_z, 0.01)
        yield from self.align_xy(lambda: cup() - self.tcp(), 0.004)
        yield from self.approach(grasp_z, 0.004)
        yield from self.gripper(True)
        yield from self.move_tcp("z", carry_z, 0.01)
        goal = np.array([CONTAINER_XY[0], pour_y])
        yield from self.align_xy(lambda: goal - self.tcp()[:2], 0.01)
        for degrees in (95, 108):
            tilt = math.radians(degrees)
            yield from self.align("rx", lambda t=tilt: t - self.tilt(), math.radians(6))
            try:
                # the trial runner ends the trial on success; the operator watches the cup
                yield Until(lambda: self.task.state().in_cup <= 1, 20.0, "the cup empty")
                return
            except Timeout:
                self.log(f"at {degrees} deg the cup still holds {self.task.state().in_cup}")
