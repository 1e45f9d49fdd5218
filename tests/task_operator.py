"""An experimenter's robot operator for the study tasks: closed loop on the server's state.

:class:`Operator` completes ``pick_place`` (cube, cylinder, prism into their molds) and
``pour`` (empty the cup into the container) in a running dashboard the way a person at the
page would: it looks at the scene (the session's newest published state on the SERVER,
``DashboardRunner.latest()``: a loaded machine's page may show a state seconds old), plans
a few waypoints (above the object at a safe height, turn the gripper to the object's faces,
down, close, lift, over the mold, turn the object to the mold modulo its symmetry, down,
open, up; pour: grasp the cup, carry it over the container, tilt, wait, and so on), and
moves one axis at a time through a :class:`Driver`, re-reading the state after every move
and correcting.  Nothing is timed open loop: a long move is held until the state shows the
goal within braking distance, then released; short moves are nudges repeated until the
measured error is within tolerance.  The operator never decides whether the task
succeeded: the test reads that from the trial log and the task's state.

The driver interface (one class per study interface; add one for the skin in ``tests/``)::

    class Driver(Protocol):
        interface: str                  # the page's interface name: "keyboard", ...
        def prepare(self) -> None: ...  # choose the interface in the page, set it up
        def press(self, axis: str, sign: int) -> int: ...  # start moving; held until
        def release(self) -> None: ...                     # ... this stops it
        def nudge(self, axis: str, sign: int, amount: float) -> int: ...  # a short move
        def gripper(self) -> int: ...   # toggle the gripper

``axis`` is a BASE-frame axis: ``x``, ``y``, ``z`` (translate, ``amount`` in m) or ``rx``,
``ry``, ``rz`` (rotate about the TCP, ``amount`` in rad, right-hand rule); ``sign`` is +1
or -1.  A driver whose interface works in another frame (the keyboard's and the skin's
gestures act in the tool frame) picks the command whose axis best matches, from the TCP's
axes in :meth:`ServerView.tool_axes`.  ``nudge`` may move more or less than ``amount``
(a tap, a step of the pendant's nearest increment): the operator measures and repeats.
A driver whose nudges move exactly ``amount`` or less (a pendant's steps) sets
``exact_nudges = True``; otherwise the operator learns how far a nudge goes and asks for
more or less (a short key tap moves less than its length at full speed: the twist ramps).
``press``, ``nudge`` and ``gripper`` return how many commands they sent (the session counts
every press, step, panel setting and toggle; a release is none): the operator waits until
the server has counted them before it waits for the arm to come to rest.
A skin driver would hold a gesture on the virtual skin in ``press`` (e.g. a two-finger
swipe held down) and lift it in ``release``; ``nudge`` a short gesture.
"""

from __future__ import annotations

import math
import time
from typing import Protocol

import numpy as np

from wovenskin.tasks.pick_place import MOLD_Y, ROW_X
from wovenskin.tasks.pour import CONTAINER_XY
from wovenskin.tasks.shapes import MOLD_HEIGHT, SHAPES

TRANSLATIONS = ("x", "y", "z")
ROTATIONS = ("rx", "ry", "rz")


class Driver(Protocol):
    """See the module docstring."""

    interface: str

    def prepare(self) -> None: ...

    def press(self, axis: str, sign: int) -> int: ...

    def release(self) -> None: ...

    def nudge(self, axis: str, sign: int, amount: float) -> int: ...

    def gripper(self) -> int: ...


class OperatorError(AssertionError):
    """The operator could not do a step (a test failure with what it saw)."""


class HeldBack(OperatorError):
    """Three presses in a row along one axis went nowhere (a limit holds the arm back)."""


class Missed(Exception):
    """A grasp did not hold the object (pushed aside, not lifted, dropped): try it again."""


class NoProgress(OperatorError):
    """Short moves that move the arm but not what the operator steers by."""


class Dropped(Exception):
    """The carried shape is back on the table (it slipped out of the fingers)."""


def _watchdog_stop(state: dict) -> bool:
    """Whether the stop holding the arm is a watchdog's (the skin or command stream fell
    silent): the session clears it by itself once frames flow and nothing is held."""
    stops = state["safety"]["stops"]
    return bool(stops) and stops[-1].get("source") in ("skin watchdog", "command watchdog")


def wrap(angle: float, period: float = 2 * math.pi) -> float:
    """``angle`` into ``[-period/2, period/2)``."""
    return (angle + period / 2) % period - period / 2


def quat_yaw(q: list[float]) -> float:
    """Yaw (rad) of a ``[w, x, y, z]`` quaternion's x axis about base z."""
    w, x, y, z = q
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


class ServerView:
    """The session's newest state as the server publishes it (``runner.latest()``)."""

    def __init__(self, runner) -> None:
        self.runner = runner
        self._names: tuple[str, list[str]] = ("", [])

    def state(self) -> dict:
        return self.runner.latest() or {}

    def wait(self, predicate, timeout_s: float, what: str) -> dict:
        """The first state for which ``predicate`` holds; OperatorError after the timeout."""
        deadline = time.monotonic() + timeout_s
        while True:
            state = self.state()
            try:
                if state and predicate(state):
                    return state
            except (KeyError, TypeError, IndexError):
                pass
            if time.monotonic() > deadline:
                raise OperatorError(f"timed out after {timeout_s} s waiting for {what}")
            time.sleep(0.02)

    def live(self, state: dict) -> dict:
        """``state`` with the robot's TCP as the session has it now: its robot state is
        replaced every control tick, the published state only between batches of ticks."""
        robot = self.runner.session.state.robot
        if robot is None:
            return state
        rotation = robot.tcp.rotation()
        tcp = {"pos": list(robot.tcp.position), "x_axis": list(rotation[:, 0]),
               "z_axis": list(rotation[:, 2])}  # fmt: skip
        return {**state, "robot": {**state["robot"], "tcp": tcp}}

    def tcp(self, state: dict | None = None) -> np.ndarray:
        return np.array((state or self.state())["robot"]["tcp"]["pos"])

    def tool_axes(self, state: dict | None = None) -> np.ndarray:
        """The TCP's x, y, z axes in the base frame, as the rows of a 3x3 array."""
        tcp = (state or self.state())["robot"]["tcp"]
        x, z = np.array(tcp["x_axis"]), np.array(tcp["z_axis"])
        return np.array([x, np.cross(z, x), z])

    def commands(self, state: dict | None = None) -> int:
        return int((state or self.state())["teleop"]["commands"])

    def _moving_names(self, state: dict) -> list[str]:
        task = state["task"]["name"]
        if self._names[0] != task:
            self._names = (task, [m["name"] for m in self.runner.describe()["task"]["moving"]])
        return self._names[1]

    def geom(self, name: str, state: dict | None = None) -> list[float]:
        """A moving task shape's ``[x, y, z, qw, qx, qy, qz]`` (its body's pose for the
        shapes and the cup's bottom: their geoms sit at the body's frame)."""
        state = state or self.state()
        return state["task"]["geoms"][self._moving_names(state).index(name)]

    def finger_gap(self, state: dict | None = None) -> float:
        state = state or self.state()
        left, right = self.geom("finger_left", state), self.geom("finger_right", state)
        return float(np.linalg.norm(np.subtract(left[:3], right[:3])))

    def task_state(self, state: dict | None = None) -> dict:
        return (state or self.state())["task"]["state"]


class Operator:
    """Completes a task through a :class:`Driver`, closed loop (module docstring)."""

    def __init__(self, runner, driver: Driver, log=print) -> None:
        self.view = ServerView(runner)
        self.driver = driver
        settings = runner.session.mapping.settings
        self.speed = {"linear": settings.linear_speed, "angular": settings.angular_speed}
        self.accel = {"linear": settings.linear_accel, "angular": settings.angular_accel}
        self.log = log
        self.moves = 0
        self.started = time.monotonic()
        self.gain: dict[str, float] = {}  # per kind: how much more to ask of a nudge
        self.lead: dict[str, float] = {}  # per kind: how much earlier (s) to let go a press
        self.stuck = 0  # presses in a row that went nowhere

    # -- one axis, closed loop

    def _kind(self, axis: str) -> str:
        return "angular" if axis in ROTATIONS else "linear"

    def settle(self, timeout_s: float = 60.0) -> dict:
        """Wait until nothing is held and the arm is still (two states in a row)."""
        still = {"n": 0}

        def quiet(s: dict) -> bool:
            if s["safety"]["stopped"]:
                if not _watchdog_stop(s):
                    raise OperatorError(f"the robot stopped: {s['safety']['stops'][-1:]}")
                still["n"] = 0  # a watchdog stop ends by itself once frames flow again
                return False
            ok = s["teleop"]["held"] is None and not s["robot"]["moving"]
            ok = ok and s["robot"]["tcp_speed"] < 5e-4
            still["n"] = still["n"] + 1 if ok else 0
            return still["n"] >= 3

        return self.view.wait(quiet, timeout_s, "the arm to come to rest")

    def _sent(self, count: int, timeout_s: float = 60.0) -> None:
        self.view.wait(lambda s: self.view.commands(s) >= count, timeout_s, "the command")

    def align(
        self,
        axis: str,
        error,
        tol: float,
        timeout_s: float = 120.0,
        presses: bool = True,
        stall_after: int | None = None,
    ) -> None:
        """Drive ``axis`` until ``|error(state)| <= tol``; ``error`` is goal minus now in
        the axis's direction (m or rad), read from the server's state.  ``presses``
        False: short moves only (toward contact, where a held move's overshoot would push
        an object or jam it against a mold's rim).  ``stall_after``: NoProgress after that
        many short moves in a row that brought the error down by less than a tenth of what
        they asked (a held shape that turns in the fingers instead of with them)."""
        stalled = 0
        kind = self._kind(axis)
        v, a = self.speed[kind], self.accel[kind]
        deadline = time.monotonic() + timeout_s
        state = self.settle()
        while True:
            # the shaped stop, the release's way to the server, and what this operator has
            # learnt of how late its releases take effect with this interface
            brake = v * v / (2 * a) + v * (0.12 + self.lead.get(kind, 0.0))
            e = float(error(state))
            if abs(e) <= tol:
                return
            if time.monotonic() > deadline:
                raise OperatorError(f"{axis}: error {e:+.4f} > {tol} after {timeout_s} s")
            sign = 1 if e > 0 else -1
            before = self.view.commands(state)
            self.moves += 1
            self.log(f"{time.monotonic() - self.started:7.2f} s  {axis} {e:+.4f}")
            if presses and abs(e) > 1.5 * brake:
                sent = self.driver.press(axis, sign)
                try:
                    self._sent(before + sent)
                    stuck = self._hold(axis, sign, error, brake, v, timeout_s)
                finally:
                    self.driver.release()
                state = self.settle()
                if not stuck:  # learn from where the arm stopped: let go earlier or later
                    past = -sign * float(error(state))  # > 0: beyond the goal
                    lead = self.lead.get(kind, 0.0) + (past if past > 0 else 0.5 * past) / v
                    self.lead[kind] = float(np.clip(lead, 0.0, 2.0))
                continue
            exact = getattr(self.driver, "exact_nudges", False)
            gain = 1.0 if exact else self.gain.get(kind, 1.0)
            asked = min(abs(e) * gain, abs(e) + 0.1 * brake, 2 * brake)  # bounded overshoot
            self._sent(before + self.driver.nudge(axis, sign, asked))
            state = self.settle()
            done = sign * (e - float(error(state)))  # the way made toward the goal
            stalled = stalled + 1 if done < 0.1 * asked else 0
            if stall_after is not None and stalled >= stall_after:
                raise NoProgress(f"{axis}: {stalled} short moves in a row left it at {e:+.4f}")
            if not exact:  # learn how far a nudge goes: ask for more (less) next time
                change = abs(e) / done if done > 1e-6 else 2.0
                self.gain[kind] = float(np.clip(gain * np.clip(change, 0.7, 1.4), 0.5, 3.0))

    def _hold(self, axis: str, sign: int, error, brake: float, speed: float, timeout_s) -> bool:
        """Keep the press until the goal is within braking distance plus the way the arm
        goes before the release takes effect.  On a loaded machine the session runs its
        ticks in batches (it catches up with the clock) and publishes only between them,
        so the published state may be a second or more old while the arm moves: the
        remaining way is the published one less what the arm's TCP has moved since, read
        from the session's robot state (replaced every tick) on the server.  Returns
        whether the press went nowhere (held back); OperatorError, with the safety layer's
        reasons, when that happens three presses in a row."""
        deadline = time.monotonic() + timeout_s
        last, since = None, time.monotonic()
        while time.monotonic() < deadline:
            state = self.view.state()
            if state["safety"]["stopped"]:
                if not _watchdog_stop(state):
                    raise OperatorError(f"the robot stopped: {state['safety']['stops'][-1:]}")
                # a stall of the stream on a loaded machine: let go, it resumes by itself
                self.log(f"{axis}: {state['safety']['stops'][-1]['reason']}; let go")
                return True
            now = self._measure(axis, self.view.live(state))
            moved = now - self._measure(axis, state)
            if axis in ROTATIONS:
                moved = wrap(moved)
            if sign * (float(error(state)) - moved) <= brake:
                self.stuck = 0
                return False
            if last is None or abs(now - last) > 1e-4:
                last, since = now, time.monotonic()
            elif time.monotonic() - since > 3.0:  # the press went nowhere: let go, again
                held = state.get("safety", {}).get("holding") or []
                self.stuck += 1
                self.log(f"{axis}: no motion while pressed (held back: {held}); let go")
                if self.stuck >= 3:
                    self.stuck = 0
                    raise HeldBack(f"{axis}: held back three presses in a row: {held}")
                return True
            time.sleep(0.01)
        raise OperatorError(f"{axis}: the goal did not come near in {timeout_s} s")

    def _measure(self, axis: str, state: dict) -> float:
        """The TCP's coordinate (m) or angle (rad) along ``axis`` in ``state``."""
        if axis in TRANSLATIONS:
            return float(self.view.tcp(state)[TRANSLATIONS.index(axis)])
        if axis == "rx":
            return self.tilt(state)
        if axis == "rz":
            return self.closing_angle(state)
        raise OperatorError(f"no measure of {axis}")

    def align_xy(self, error, tol: float, passes: int = 4) -> None:
        """Bring both ``error(state)[0]`` (x) and ``[1]`` (y) within ``tol``: y then x,
        again while one drifted (an interface in the tool frame moves along the tool's
        axes, which a turned gripper has off the base's).  An axis held back (a turned
        gripper's key carries the TCP along the diagonal to the edge of the reach, or
        near the base to the elbow's fold limit) is left for the other, as a person does:
        that one brings the TCP back, and the next pass tries it again."""
        held: HeldBack | None = None
        for _ in range(passes):
            for i, axis in ((1, "y"), (0, "x")):
                try:
                    self.align(axis, lambda s, i=i: error(s)[i], tol)
                except HeldBack as exc:
                    held = exc
                    self.log(f"{exc}: the other axis first")
            if np.all(np.abs(error(self.settle())[:2]) <= tol):
                return
        raise OperatorError(f"x, y: error {error(self.view.state())[:2]} > {tol} ({held})")

    def move_tcp(self, axis: str, goal: float, tol: float = 0.002, presses: bool = True) -> None:
        i = TRANSLATIONS.index(axis)
        self.align(axis, lambda s: goal - self.view.tcp(s)[i], tol, presses=presses)

    def gripper(self, close: bool, timeout_s: float = 20.0) -> None:
        """Toggle the gripper to ``close`` and wait until the fingers stop."""
        state = self.settle()
        if bool(state["teleop"]["gripper_closed"]) != close:
            self._sent(self.view.commands(state) + self.driver.gripper())
            self.view.wait(
                lambda s: bool(s["teleop"]["gripper_closed"]) == close, timeout_s, "the gripper"
            )
        last, stable_since = None, time.monotonic()
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            gap = self.view.finger_gap()
            if last is None or abs(gap - last) > 2e-4:
                last, stable_since = gap, time.monotonic()
            elif time.monotonic() - stable_since > 0.6:
                return
            time.sleep(0.05)
        raise OperatorError("the fingers did not come to rest")

    # -- angles read from the state

    def closing_angle(self, state: dict) -> float:
        """Direction (rad, about base z) of the gripper's closing axis (the tool's y)."""
        y = self.view.tool_axes(state)[1]
        return math.atan2(y[1], y[0])

    def tilt(self, state: dict) -> float:
        """The tool's z axis from straight down, signed as a turn about base +x (rad)."""
        z = self.view.tool_axes(state)[2]
        return math.atan2(z[1], -z[2])

    # -- pick and place

    def pick_place(self, travel_z: float = 0.062, grasp_z: float = 0.027, shapes=SHAPES) -> None:
        """Seat every shape in its mold (the order along the rows), retrying a shape
        that did not seat (a person picks it up again).  ``travel_z``: the TCP's height
        while moving over the table (fingertips 10 mm above the tallest shape, a held
        shape's base above the molds' walls); ``grasp_z``: the fingertips' when grasping."""
        for shape in shapes:
            for attempt in range(3):
                try:
                    self._carry(shape, travel_z, grasp_z)
                except Missed as missed:
                    self.log(f"{shape.name}: {missed} (attempt {attempt + 1})")
                    continue
                seated = self._seated(shape.name)
                self.log(f"{shape.name}: seated {seated} (attempt {attempt + 1})")
                if seated:
                    break
            else:
                raise OperatorError(f"{shape.name} would not seat in three attempts")

    def _seated(self, name: str) -> bool:
        time.sleep(0.6)  # the next published measures (every 0.2 s of session time)
        objects = {o["name"]: o for o in self.view.task_state()["objects"]}
        return bool(objects[name]["seated"])

    def _object(self, name: str, state: dict) -> tuple[np.ndarray, float]:
        pose = self.view.geom(name, state)
        return np.array(pose[:3]), quat_yaw(pose[3:])

    def _carry(self, shape, travel_z: float, grasp_z: float) -> None:
        name = shape.name
        obj = lambda s: self._object(name, s)  # noqa: E731 - a short reader
        tcp = self.view.tcp
        state = self.settle()
        if abs(tcp(state)[2] - travel_z) > 0.006:
            self.move_tcp("z", travel_z, 0.006)
        # above the object (the open fingers leave 20 mm either side), the closing axis
        # along one of its face normals (a turn about the TCP: it stays above the object)
        self.align_xy(lambda s: obj(s)[0] - tcp(s), 0.005)
        if shape.symmetry is not None:
            period = math.pi / 3 if shape.sides == 3 else shape.symmetry
            self.align(
                "rz", lambda s: wrap(obj(s)[1] - self.closing_angle(s), period), math.radians(4)
            )
        resting_z = obj(state)[0][2]
        self.move_tcp("z", grasp_z, 0.004, presses=False)  # short moves down to it
        off = np.linalg.norm(obj(self.settle())[0][:2] - tcp(self.view.state())[:2])
        if off > 0.008:  # the fingers pushed it aside on the way down: up, and again
            self.move_tcp("z", travel_z, 0.006)
            raise Missed(f"pushed {1000 * off:.0f} mm off the fingers' centre")
        self.gripper(True)
        self._report(name, "grasped")
        self.move_tcp("z", travel_z, 0.006)  # its base above the molds' walls
        if obj(self.settle())[0][2] < resting_z + 0.015:  # it stayed on the table
            self.gripper(False)
            raise Missed("not lifted by the grasp")
        mold = np.array([ROW_X[SHAPES.index(shape)], MOLD_Y])

        def to_mold(s: dict) -> np.ndarray:
            """The way to the mold, while the shape is still off the table (a shape that
            slipped out of the fingers stays behind: carrying on would drive the empty
            gripper on to the edge of the reach, where the arm stops at a singularity)."""
            position = obj(s)[0]
            if position[2] < resting_z + 0.005:
                raise Dropped(f"dropped at ({position[0]:.3f}, {position[1]:.3f}) on the way")
            return mold - position[:2]

        try:
            self.align_xy(to_mold, 0.006)
            if shape.symmetry is not None:  # (a shape turning in the fingers: grasp again)
                turn = lambda s: -wrap(obj(s)[1], shape.symmetry)  # noqa: E731
                self.align("rz", turn, math.radians(2), stall_after=6)
            self.align_xy(to_mold, 0.0018)  # the pocket's clearance: 3 mm
        except (Dropped, NoProgress) as lost:  # open, up, and pick it up again
            self.gripper(False)
            self.move_tcp("z", travel_z, 0.006)
            raise Missed(str(lost)) from None
        # down until the base is 3 mm above the table, the fingertips above the mold's
        # walls (a finger beside the object stands over the wall), open
        state = self.settle()
        drop = obj(state)[0][2] - (shape.height / 2 + 0.003)
        self.move_tcp("z", max(tcp(state)[2] - drop, MOLD_HEIGHT + 0.006), 0.003, presses=False)
        self._report(name, "lowered")
        self.gripper(False)
        self._report(name, "released")
        self.move_tcp("z", travel_z, 0.006)

    def _report(self, name: str, what: str) -> None:
        state = self.view.state()
        (x, y, z), yaw = self._object(name, state)
        tcp = self.view.tcp(state)
        self.log(
            f"{name} {what}: at ({x:.4f}, {y:.4f}, {z:.4f}) yaw {math.degrees(yaw):.1f} deg,"
            f" TCP ({tcp[0]:.4f}, {tcp[1]:.4f}, {tcp[2]:.4f})"
        )

    # -- pouring

    def pour(self, grasp_z: float = 0.03, carry_z: float = 0.14, pour_y: float = -0.19) -> None:
        """Grasp the cup low, carry it over the container, tilt it about base +x (its rim
        toward -y) until it is empty, and hold it there."""
        cup = lambda s: np.array(self.view.geom("cup_bottom", s)[:3])  # noqa: E731
        self.move_tcp("z", carry_z, 0.01)
        self.align_xy(lambda s: cup(s) - self.view.tcp(s), 0.004)  # 7 mm each side
        self.move_tcp("z", grasp_z, 0.004)
        self.gripper(True)
        self.move_tcp("z", carry_z, 0.01)
        goal = np.array([CONTAINER_XY[0], pour_y])
        self.align_xy(lambda s: goal - self.view.tcp(s)[:2], 0.01)
        measures = self.view.task_state
        for degrees in (95, 108):  # tip it further if the cup does not empty
            self.align("rx", lambda s, d=degrees: math.radians(d) - self.tilt(s), math.radians(6))
            try:
                self.view.wait(
                    lambda s: measures(s)["in_cup"] <= 1 or measures(s)["succeeded"],
                    20,
                    "the cup to empty",
                )
                break
            except OperatorError:
                self.log(f"at {degrees} deg the cup still holds {measures(self.view.state())}")
        self.log(f"poured: {measures(self.view.state())}")


# -- the page's interfaces (Playwright)


def choose(page, selector: str, value: str) -> None:
    """Choose an option of a select as a person does (its change event), in one script
    (``select_option`` waits for a stable frame, a second or more on a busy page)."""
    page.evaluate(
        "([selector, value]) => { const s = document.querySelector(selector);"
        " s.value = value; s.dispatchEvent(new Event('change')); }",
        [selector, value],
    )


class PageDriver:
    """What the page drivers share: the page, the server's view, the interface choice."""

    interface = ""

    def __init__(self, page, view: ServerView) -> None:
        self.page = page
        self.view = view

    def prepare(self) -> None:
        self.page.select_option("#interface", self.interface)
        self.view.wait(
            lambda s: s["teleop"]["interface"] == self.interface, 30, "the interface choice"
        )
        self.page.evaluate("document.activeElement && document.activeElement.blur()")


class KeyboardDriver(PageDriver):
    """The page's keys (``page.keyboard``), tool frame: for a base-frame axis the key of
    the tool axis that best matches it now, with the sign of their alignment."""

    interface = "keyboard"

    def __init__(self, page, view: ServerView, mapping) -> None:
        super().__init__(page, view)
        from wovenskin.teleop.keyboard import key_map

        self.keys = {row.action: row.key for row in key_map(mapping)}
        settings = mapping.settings
        self.speed = {"linear": settings.linear_speed, "angular": settings.angular_speed}
        self.accel = {"linear": settings.linear_accel, "angular": settings.angular_accel}
        self.held: str | None = None

    def key(self, axis: str, sign: int) -> str:
        base = np.eye(3)["xyz".index(axis[-1])]
        dots = self.view.tool_axes() @ base
        k = int(np.argmax(np.abs(dots)))
        kind = "rotate" if axis in ROTATIONS else "translate"
        mark = "+" if sign * dots[k] > 0 else "-"
        return self.keys[f"{kind} {mark}{'xyz'[k]}"]

    def press(self, axis: str, sign: int) -> int:
        self.held = self.key(axis, sign)
        self.page.keyboard.down(self.held)
        return 1

    def release(self) -> None:
        if self.held is not None:
            self.page.keyboard.up(self.held)
            self.held = None

    def nudge(self, axis: str, sign: int, amount: float) -> int:
        """A tap as long as a ramped move of ``amount`` takes: accelerate for half the
        way and brake for the other (``sqrt(amount / accel)``), or ``amount / speed``
        past full speed."""
        key = self.key(axis, sign)
        kind = "angular" if axis in ROTATIONS else "linear"
        speed, accel = self.speed[kind], self.accel[kind]
        held = math.sqrt(amount / accel) if amount < speed * speed / accel else amount / speed
        self.page.keyboard.down(key)
        time.sleep(min(0.6, max(0.02, held)))
        self.page.keyboard.up(key)
        return 1

    def gripper(self) -> int:
        self.page.keyboard.press("g")
        return 1


class PendantDriver(PageDriver):
    """The page's jog panel in the base frame at 100 % speed: a jog button held with the
    mouse for long moves, step mode (10, 5, 1 mm or deg per click) for short ones."""

    interface = "pendant"
    exact_nudges = True  # a step moves its increment: the operator need not learn a gain

    def prepare(self) -> None:
        super().prepare()
        self._choose("#jog-frame", "base")
        self.page.evaluate(
            "(() => { const s = document.getElementById('jog-speed'); s.value = 100;"
            " s.dispatchEvent(new Event('change')); })()"
        )
        self.view.wait(
            lambda s: (
                s["teleop"]["pendant"]["speed_percent"] == 100
                and s["teleop"]["pendant"]["frame"] == "base"
            ),
            30,
            "the pendant's settings",
        )
        self.step: int | None = -1  # unknown: the first _mode sets it
        self._mode(None)

    def _mode(self, size: int | None) -> int:
        """Step mode ``size`` (None: continuous jog); returns the commands it took."""
        if self.step == size:
            return 0
        self._choose("#jog-step", "off" if size is None else str(size))
        self.step = size
        # the person sees the panel in that mode before pressing (a page drawing an older
        # state would set the select back, and a press would then not be held)
        wanted = "null" if size is None else str(size)
        self.page.wait_for_function(
            "window.wovenskin.state.teleop.pendant"
            f" && window.wovenskin.state.teleop.pendant.step_size === {wanted}",
            timeout=60000,
        )
        return 1

    def _choose(self, selector: str, value: str) -> None:
        choose(self.page, selector, value)

    def _at(self, selector: str) -> None:
        """Put the mouse over an element, scrolled into view.  Mouse events, and the
        element's box read by one script: on a page busy drawing its 3D view on the CPU,
        Playwright's click and bounding_box wait a second or more for a stable frame."""
        x, y = self.page.evaluate(
            """(selector) => {
                const element = document.querySelector(selector);
                let r = element.getBoundingClientRect();
                if (r.top < 0 || r.bottom > window.innerHeight) {
                    element.scrollIntoView({ block: "center" });
                    r = element.getBoundingClientRect();
                }
                return [r.left + r.width / 2, r.top + r.height / 2];
            }""",
            selector,
        )
        self.page.mouse.move(x, y)

    def _button(self, axis: str, sign: int) -> None:
        self._at(f'#jog-axes button[data-axis="{axis}"][data-sign="{sign}"]')

    def press(self, axis: str, sign: int) -> int:
        sent = self._mode(None)
        for _ in range(3):  # a press the panel did not take is pressed again, as people do
            self._button(axis, sign)
            self.page.mouse.down()
            try:
                self.view.wait(
                    lambda s: s["teleop"]["pendant"]["jogging"] is not None, 5, "the jog"
                )
                return sent + 1
            except (OperatorError, KeyError, TypeError):
                self.page.mouse.up()
        raise OperatorError(f"the {axis} {sign:+d} jog button did not take three presses")

    def release(self) -> None:
        self.page.mouse.up()

    def nudge(self, axis: str, sign: int, amount: float) -> int:
        unit = amount * (math.degrees(1) if axis in ROTATIONS else 1000.0)
        size = max(s for s in (1, 5, 10) if s <= max(unit, 1.0))
        sent = self._mode(size)
        self._button(axis, sign)
        self.page.mouse.down()
        self.page.mouse.up()
        return sent + 1

    def gripper(self) -> int:
        self._at("#jog-gripper")
        self.page.mouse.down()
        self.page.mouse.up()
        return 1
