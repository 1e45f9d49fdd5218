"""Stop times for ``wovenskin bench control``: commands through the session's chain, ended
by a release, the stop key or a skin stall, timed until the arm is at rest."""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from wovenskin.control.mapping import ActionMapping, MotionSettings, TwistAction
from wovenskin.control.motion import TwistShaper
from wovenskin.control.safety import SafetyLayer
from wovenskin.control.safety_limits import SafetyLimits
from wovenskin.robots.base import Robot
from wovenskin.robots.registry import make_robot
from wovenskin.robots.sim import SimRobot
from wovenskin.robots.techman.fake_server import FakeListenNode

STOP_REST_LINEAR_M_S = 1e-3  # 1 mm/s: the TCP has stopped
STOP_REST_ANGULAR_RAD_S = 0.01  # 0.57 deg/s: a point 0.1 m from the TCP moves under 1 mm/s
STOP_TARGET_MEDIAN_S = 0.15  # release: median and worst stop time (issue 12)
STOP_TARGET_WORST_S = 0.25
STOP_SAFETY_TARGET_S = 0.1  # after a STOP or a watchdog stop
STOP_ENDINGS = ("release", "stop", "watchdog")
STOP_DURATIONS_S = (0.1, 0.2, 0.3, 0.5, 1.0, 2.0, 3.0)
STOP_LINEAR_SPEEDS = (0.05, 0.125, 0.25)  # m/s, up to the 250 mm/s cap
STOP_ANGULAR_SPEEDS_DEG = (15.0, 30.0, 60.0)  # deg/s, up to the 60 deg/s cap
STOP_TRAVEL_M = 0.25  # a linear case moves at most this far (the arm stays in its range)
STOP_TURN_DEG = 90.0  # an angular case turns at most this far
STOP_OBSERVE_S = 0.6  # how long after the end the arm is watched
STOP_TICK_S = 0.005  # the control tick: the default skin's 200 Hz
AXIS_NAMES = ("+x", "-x", "+y", "-y", "+z", "-z")

STOP_DURATIONS_REAL_TIME_S = (0.1, 0.3, 1.0, 3.0)  # fewer cases where each runs in real time

RobotFactory = Callable[[], Robot]


class FakeTechmanArms:
    """A robot factory for the stop benchmark: each call starts a fresh fake Techman
    controller (the TM5-900 model, at its initial pose) on loopback ports and returns a
    :class:`~wovenskin.robots.techman.TechmanRobot` client for it, so every case starts from
    the same pose. The previous fake is stopped when the next one starts and on ``close``."""

    def __init__(self) -> None:
        self._fake: Any = None

    def __call__(self) -> Robot:
        self.close()
        self._fake = FakeListenNode.tm5_900().start()
        return make_robot(self._fake.spec)

    def close(self) -> None:
        if self._fake is not None:
            self._fake.stop()
            self._fake = None

    def __enter__(self) -> FakeTechmanArms:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True)
class StopCase:
    """One command: ``kind`` along/about the tool-frame ``axis`` at ``speed`` (m/s or rad/s)
    for ``seconds``, ended by ``ending``: ``release`` (the fingers lift: the twist goes to
    zero), ``stop`` (the stop key) or ``watchdog`` (the skin stalls: no more ticks)."""

    kind: str  # "translate" or "rotate"
    axis: str  # one of AXIS_NAMES
    speed: float
    seconds: float
    ending: str = "release"

    def describe(self) -> str:
        unit = f"{1000 * self.speed:.0f} mm/s" if self.kind == "translate" else (
            f"{math.degrees(self.speed):.0f} deg/s")  # fmt: skip
        return f"{self.kind} {self.axis} {unit} {self.seconds:g} s, {self.ending}"


@dataclass
class StopMeasurement:
    """What one case did: ``stop_s`` is the time from the end (the release, or the safety
    stop for ``stop`` and ``watchdog``) until the TCP stays below 1 mm/s and 0.57 deg/s;
    ``None`` when it did not within the observed time. ``moving_at_end`` is False when the
    arm was not moving when the command ended (the workspace or a joint limit had stopped
    it): such a case says nothing about stopping and is left out of the figures."""

    case: StopCase
    speed_at_end: float  # m/s (translate) or rad/s (rotate), measured
    moving_at_end: bool
    stop_s: float | None
    stall_to_rest_s: float | None = None  # watchdog: from the last tick to rest


def stop_cases(
    endings: tuple[str, ...] = STOP_ENDINGS, durations: tuple[float, ...] = STOP_DURATIONS_S
) -> list[StopCase]:
    """The benchmark's commands: each ending x linear/angular x speed up to the caps x
    duration; the axis turns through the six directions, and the speed of a long command
    is reduced where its travel would exceed STOP_TRAVEL_M / STOP_TURN_DEG."""
    cases: list[StopCase] = []
    n = 0
    for ending in endings:
        for kind, speeds, travel in (
            ("translate", STOP_LINEAR_SPEEDS, STOP_TRAVEL_M),
            ("rotate", tuple(math.radians(v) for v in STOP_ANGULAR_SPEEDS_DEG),
             math.radians(STOP_TURN_DEG)),
        ):  # fmt: skip
            for speed in speeds:
                for seconds in durations:
                    axis = AXIS_NAMES[n % len(AXIS_NAMES)]
                    n += 1
                    speed_here = min(speed, travel / seconds)
                    cases.append(StopCase(kind, axis, speed_here, seconds, ending))
    return cases


def measure_stop(
    robot_factory: RobotFactory,
    case: StopCase,
    *,
    tick_s: float = STOP_TICK_S,
    observe_s: float = STOP_OBSERVE_S,
    limits: SafetyLimits | None = None,
    motion: MotionSettings | None = None,
) -> StopMeasurement:
    """Run one command through the session's chain -- mapping (tool frame), TwistShaper,
    SafetyLayer -- into a fresh robot from ``robot_factory`` and time its stop.

    A simulated robot (one with its own ``step``) runs on a simulated clock, stepped by each
    tick as the session steps it; any other robot runs in real time: the loop sleeps to the
    next tick and reads the robot's reported state (a real or emulated controller).
    """
    robot = robot_factory()
    simulated = type(robot).step is not Robot.step
    clock = _TickClock(simulated)
    safety = SafetyLayer(robot, limits, clock=clock.now)
    settings = replace(
        motion or MotionSettings(),
        linear_speed=case.speed if case.kind == "translate" else 0.05,
        angular_speed=case.speed if case.kind == "rotate" else math.radians(15.0),
    )
    axis = np.zeros(3)
    axis["xyz".index(case.axis[1])] = 1.0 if case.axis[0] == "+" else -1.0
    action = TwistAction("translate" if case.kind == "translate" else "rotate", axis)
    mapping = ActionMapping({"bench": action}, settings)
    shaper = TwistShaper(settings)
    part = slice(0, 3) if case.kind == "translate" else slice(3, 6)
    samples: list[tuple[float, float, float]] = []  # time after the end, linear, angular
    end = round(case.seconds / tick_s)
    stop_at: float | None = None  # time of the safety stop after the end
    speed_at_end = 0.0
    safety.connect()
    try:
        state = safety.state()
        clock.start()
        end_t = clock.now() + end * tick_s
        for i in range(end + round(observe_s / tick_s)):
            now = clock.now()
            commanding = i < end
            if i == end:
                speed_at_end = float(np.linalg.norm(np.asarray(state.tcp_twist)[part]))
                if case.ending == "stop":
                    safety.emergency_stop("bench: stop key")
                    shaper.reset()
                    stop_at = now
            if case.ending == "watchdog" and not commanding:
                # the skin stalled: no ticks, the session's idle loop runs only the watchdogs
                if safety.check(now) and stop_at is None:
                    stop_at = now
            elif not safety.stopped:
                safety.heartbeat_skin(now)
                target = mapping.target_twist("bench" if commanding else None, state.tcp)
                safety.send_twist(shaper.update(target, tick_s))
                safety.heartbeat_command(now)
            if simulated:
                safety.step(tick_s)
            clock.tick(tick_s)
            state = safety.state()
            twist = np.asarray(state.tcp_twist, dtype=float)
            linear, angular = float(np.linalg.norm(twist[:3])), float(np.linalg.norm(twist[3:]))
            samples.append((clock.now() - end_t, linear, angular))
    finally:
        try:
            safety.stop()
        finally:
            safety.disconnect()
    reference = None if stop_at is None else stop_at - end_t
    return _stop_measurement(case, samples, speed_at_end, reference)


def _stop_measurement(
    case: StopCase,
    samples: list[tuple[float, float, float]],
    speed_at_end: float,
    stop_after_end: float | None,
) -> StopMeasurement:
    """Time to rest from the samples ``(seconds after the end, linear, angular speed)``."""
    t = np.array([s[0] for s in samples])
    moving = np.array(
        [v >= STOP_REST_LINEAR_M_S or w >= STOP_REST_ANGULAR_RAD_S for _, v, w in samples]
    )
    threshold = STOP_REST_LINEAR_M_S if case.kind == "translate" else STOP_REST_ANGULAR_RAD_S
    moving_at_end = speed_at_end >= threshold
    after = np.flatnonzero(t > 0.0)
    last = [i for i in after if moving[i]]
    rest: float | None
    if not after.size or (last and last[-1] == len(t) - 1):
        rest = None  # still moving when the observation ended
    else:
        rest = float(t[last[-1] + 1]) if last else float(t[after[0]])
    if case.ending == "release":
        return StopMeasurement(case, speed_at_end, moving_at_end, rest)
    if stop_after_end is None or rest is None:  # no safety stop came, or no rest
        return StopMeasurement(case, speed_at_end, moving_at_end, None, rest)
    stall = rest if case.ending == "watchdog" else None
    return StopMeasurement(case, speed_at_end, moving_at_end, max(0.0, rest - stop_after_end),
                           stall)  # fmt: skip


class _TickClock:
    """The bench loop's clock: simulated seconds, or the wall clock paced to the ticks."""

    def __init__(self, simulated: bool) -> None:
        self.simulated = simulated
        self.origin = 0.0
        self._t = 0.0

    def start(self) -> None:
        self._t = time.monotonic() if not self.simulated else 0.0
        self.origin = self._t

    def now(self) -> float:
        return self._t

    def tick(self, dt: float) -> None:
        self._t += dt
        if not self.simulated:
            time.sleep(max(0.0, self._t - time.monotonic()))


def bench_stops(
    robot_factory: RobotFactory | None = None,
    cases: list[StopCase] | None = None,
    **options: Any,
) -> list[StopMeasurement]:
    """Measure every case (default: :func:`stop_cases`) on robots from ``robot_factory``
    (default: the simulated TM5-900); ``options`` go to :func:`measure_stop`."""
    if robot_factory is None:
        robot_factory = SimRobot
    safety_log = logging.getLogger("wovenskin.control.safety")
    level = safety_log.level
    safety_log.setLevel(logging.ERROR)  # every stop and watchdog case logs a warning
    try:
        return [measure_stop(robot_factory, case, **options) for case in (cases or stop_cases())]
    finally:
        safety_log.setLevel(level)


def summarise_stops(measurements: list[StopMeasurement]) -> dict[str, dict[str, Any]]:
    """Per ending: how many cases, how many moved at the end, and their stop times (ms:
    median, p99, worst, with the worst case named); never-stopped cases count as failures."""
    out: dict[str, dict[str, Any]] = {}
    for ending in STOP_ENDINGS:
        mine = [m for m in measurements if m.case.ending == ending]
        if not mine:
            continue
        moved = [m for m in mine if m.moving_at_end]
        timed = [m for m in moved if m.stop_s is not None]
        summary: dict[str, Any] = {
            "cases": len(mine),
            "moving_at_end": len(moved),
            "never_stopped": len(moved) - len(timed),
        }
        if timed:
            times = np.array([m.stop_s for m in timed], dtype=float)
            worst = max(timed, key=lambda m: m.stop_s or 0.0)
            summary.update(
                median_ms=1000 * float(np.median(times)),
                p99_ms=1000 * float(np.percentile(times, 99)),
                worst_ms=1000 * float(times.max()),
                worst_case=worst.case.describe(),
            )
            stalls = [m.stall_to_rest_s for m in timed if m.stall_to_rest_s is not None]
            if stalls:
                summary["stall_to_rest_worst_ms"] = 1000 * float(max(stalls))
        out[ending] = summary
    return out


def stop_row(ending: str, summary: dict[str, Any]) -> tuple[str, str]:
    """The result table's label and figures for one ending's summary."""
    what = {
        "release": "release -> TCP at rest",
        "stop": "STOP key -> TCP at rest",
        "watchdog": "watchdog stop (skin stall) -> TCP at rest",
    }[ending]
    label = f"{what} ({summary['moving_at_end']} commands, 0.1-3 s)"
    if "median_ms" not in summary:
        return label, "not measured"
    text = (
        f"median {summary['median_ms']:.0f} ms, p99 {summary['p99_ms']:.0f} ms, "
        f"worst {summary['worst_ms']:.0f} ms"
    )
    if summary["never_stopped"]:
        text += f", {summary['never_stopped']} never at rest"
    return label, text
