"""``wovenskin bench control``: IK step time, control-loop rate and jitter, end-to-end
latency, stop times.

Four measurements on the simulated TM5-900 (:class:`~wovenskin.robots.sim.SimRobot`):

- IK step: the wall time of one differential-IK step (``step(1 / ik_rate_hz)``) while the
  arm follows twists that change direction every 0.2 s, median and p99.
- Control loop: a :class:`~wovenskin.control.session.ControlSession` on the simulated
  skin paced at real time (200 Hz) for a few seconds: ticks per second, the spread of the
  wall-clock intervals between blocks, the compute time per block (recogniser, control
  and IK, without the wait for frames) and how far the ticks lag behind the skin clock.
- End-to-end latency: sessions replaying simulated labelled streams (every gesture, no
  invalid touches) as fast as possible; for each gesture whose first command is the right
  one, the time from its first contact
  (the stream's event start) to the arm's first motion (TCP faster than 0.1 mm/s or
  0.05 deg/s, the arm at rest before).  The target is 200 ms including the 0.1 s dwell.
- Stop times: commands of 0.1-3 s (translations up to 250 mm/s, rotations up to 60 deg/s,
  all six directions) through the session's chain -- mapping, twist shaper, safety layer,
  robot -- ended by a release, the stop key or a skin stall; the time from the end (or the
  safety stop) until the TCP stays below 1 mm/s and 0.57 deg/s: median, p99 and worst.
  Targets: release median <= 0.15 s, worst <= 0.25 s; after a STOP or watchdog <= 0.1 s.
  :func:`bench_stops` takes any robot factory (a real-time robot runs paced to the tick);
  the stop measurement lives in :mod:`.stops`.

The loop and latency need a recogniser: the shipped model or ``--model DIR``.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rich.table import Table

from wovenskin.bench.results import BenchResult, figure_table
from wovenskin.bench.stops import (
    STOP_DURATIONS_REAL_TIME_S,
    FakeTechmanArms,
    bench_stops,
    stop_cases,
    stop_row,
    summarise_stops,
)
from wovenskin.control.session import ControlSession
from wovenskin.errors import ConfigError
from wovenskin.gestures import GESTURE_NAMES
from wovenskin.recognition.pipeline import load_recognizer
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.robots.sim import SimRobot
from wovenskin.runtime.session import open_session
from wovenskin.sim.stream import simulate_stream

LATENCY_TARGET_S = 0.2
MOTION_LINEAR_M_S = 1e-4  # 0.1 mm/s: the arm has started to move
MOTION_ANGULAR_RAD_S = np.deg2rad(0.05)


@dataclass
class ControlBenchResult(BenchResult):
    ik_steps: int
    ik_step_median_ms: float
    ik_step_p99_ms: float
    ik_rate_hz: float
    loop_seconds: float = 0.0
    loop_ticks: int = 0
    loop_rate_hz: float = 0.0
    loop_interval_median_ms: float = 0.0
    loop_interval_p99_ms: float = 0.0
    loop_jitter_ms: float = 0.0  # standard deviation of the intervals between blocks
    loop_compute_median_ms: float = 0.0
    loop_compute_p99_ms: float = 0.0
    loop_lag_p99_ms: float = 0.0
    latency_gestures: int = 0
    latency_moved: int = 0
    latency_median_ms: float = 0.0
    latency_p90_ms: float = 0.0
    latency_max_ms: float = 0.0
    command_median_ms: float = 0.0  # first contact to the command (recognition + dwell)
    latency_within_target: float = 0.0
    latency_per_gesture_ms: dict[str, float] = field(default_factory=dict)
    stop_times: dict[str, dict[str, Any]] = field(default_factory=dict)  # per ending
    stop_robot: str = "sim"  # the arm behind the stop times: "sim" or "techman-fake"
    model: str = ""
    notes: list[str] = field(default_factory=list)

    def table(self) -> Table:
        table = figure_table("wovenskin bench control: simulated TM5-900")
        table.add_row(
            f"IK step ({self.ik_steps} steps at {self.ik_rate_hz:g} Hz)",
            f"median {self.ik_step_median_ms:.3f} ms, p99 {self.ik_step_p99_ms:.3f} ms",
        )
        table.add_row(
            "IK budget used (median step x rate)",
            f"{self.ik_step_median_ms * self.ik_rate_hz / 10:.1f} %",
        )
        if self.loop_ticks:
            table.add_row(
                f"control loop ({self.loop_seconds:g} s, sim skin at real time)",
                f"{self.loop_rate_hz:.1f} ticks/s",
            )
            table.add_row(
                "block interval",
                f"median {self.loop_interval_median_ms:.2f} ms, p99 "
                f"{self.loop_interval_p99_ms:.2f} ms, jitter (sd) {self.loop_jitter_ms:.2f} ms",
            )
            table.add_row(
                "compute per block (recogniser, control, IK)",
                f"median {self.loop_compute_median_ms:.2f} ms, p99 "
                f"{self.loop_compute_p99_ms:.2f} ms",
            )
            table.add_row("tick lag behind the skin clock", f"p99 {self.loop_lag_p99_ms:.1f} ms")
        if self.latency_gestures:
            table.add_row("first contact -> command (median)", f"{self.command_median_ms:.0f} ms")
            table.add_row(
                f"first contact -> first motion ({self.latency_moved} of "
                f"{self.latency_gestures} gestures, recognised, from rest)",
                f"median {self.latency_median_ms:.0f} ms, p90 {self.latency_p90_ms:.0f} ms, "
                f"max {self.latency_max_ms:.0f} ms",
            )
            table.add_row(
                f"within the {1000 * LATENCY_TARGET_S:.0f} ms target",
                f"{100 * self.latency_within_target:.0f} % "
                f"(median / target = {self.latency_median_ms / (1000 * LATENCY_TARGET_S):.2f})",
            )
            for name, value in self.latency_per_gesture_ms.items():
                table.add_row(f"  {name}", f"{value:.0f} ms")
        for ending, summary in self.stop_times.items():
            label, text = stop_row(ending, summary)
            if self.stop_robot != "sim":
                label += f" [{self.stop_robot}]"
            table.add_row(label, text)
        for note in self.notes:
            table.add_row("note", note)
        return table


def bench_ik(steps: int = 1000, ik_rate_hz: float = 250.0) -> tuple[np.ndarray, float]:
    """Wall times (s) of ``steps`` IK steps of a SimRobot following changing twists."""
    robot = SimRobot(ik_rate_hz=ik_rate_hz)
    robot.connect()
    rng = np.random.default_rng(0)
    dt = 1.0 / ik_rate_hz
    per_twist = max(1, int(round(0.2 * ik_rate_hz)))
    times = np.empty(steps)
    try:
        for i in range(steps):
            if i % per_twist == 0:
                direction = rng.normal(size=6)
                twist = np.concatenate(
                    [0.05 * direction[:3] / np.linalg.norm(direction[:3]),
                     np.deg2rad(15) * direction[3:] / np.linalg.norm(direction[3:])]
                )  # fmt: skip
                robot.send_twist(twist if (i // per_twist) % 2 == 0 else -twist)
            t0 = time.perf_counter()
            robot.step(dt)
            times[i] = time.perf_counter() - t0
    finally:
        robot.disconnect()
    return times, ik_rate_hz


class _LoopTimer:
    """Wall time and compute time of each block of a paced session."""

    def __init__(self) -> None:
        self.block_wall: list[float] = []
        self.compute: list[float] = []
        self.lag: list[float] = []
        self.origin: tuple[float, float] | None = None

    def run(self, session: ControlSession, seconds: float) -> None:
        session.start()
        ticks_at_start = None
        end_wall = None
        while True:
            ticks = session.step()
            t1 = time.perf_counter()
            if ticks:
                if ticks_at_start is None:  # the first block after calibration
                    ticks_at_start = session.state.ticks
                    end_wall = t1 + seconds
                    self.origin = (t1, session.state.t)
                    continue
                self.block_wall.append(t1)
                self.compute.append(session.last_block_compute_s)
                self.lag.append((t1 - self.origin[0]) - (session.state.t - self.origin[1]))
            if end_wall is not None and t1 >= end_wall:
                break
            if session.state.ended:
                break
        self.ticks = session.state.ticks - (ticks_at_start or 0)


def bench_loop(model: Any, seconds: float) -> dict:
    """Rate, jitter, compute and lag of a session on the real-time simulated skin."""
    session = open_session("sim:seed=3", "sim", recognizer=model)
    timer = _LoopTimer()
    try:
        timer.run(session, seconds)
    finally:
        session.close()
    walls = np.asarray(timer.block_wall)
    if len(walls) < 3:
        raise ValueError("the simulated skin delivered too few blocks to time the loop")
    intervals = np.diff(walls)
    span = walls[-1] - walls[0]
    lag = np.asarray(timer.lag)
    return {
        "loop_seconds": seconds,
        "loop_ticks": int(timer.ticks),
        "loop_rate_hz": float(timer.ticks / span) if span > 0 else 0.0,
        "loop_interval_median_ms": 1000 * float(np.median(intervals)),
        "loop_interval_p99_ms": 1000 * float(np.percentile(intervals, 99)),
        "loop_jitter_ms": 1000 * float(np.std(intervals)),
        "loop_compute_median_ms": 1000 * float(np.median(timer.compute)),
        "loop_compute_p99_ms": 1000 * float(np.percentile(timer.compute, 99)),
        "loop_lag_p99_ms": 1000 * float(np.percentile(lag - lag.min(), 99)),
    }


@dataclass
class GestureLatency:
    gesture: str
    contact_s: float
    command_s: float | None
    motion_s: float | None
    at_rest: bool
    commanded: str | None = None  # the first command during the gesture

    @property
    def recognised(self) -> bool:
        return self.commanded == self.gesture


def measure_latencies(
    model: Any, stream_path: Path, events: list[tuple[str, float, float]]
) -> list[GestureLatency]:
    """Replay ``stream_path`` through a session; per event, command and first-motion times."""
    ticks: list[tuple[float, float, float]] = []  # t, linear speed, angular speed
    commands: list[tuple[float, str | None]] = []

    def on_tick(session: ControlSession) -> None:
        robot = session.state.robot
        twist = np.asarray(robot.tcp_twist, dtype=float)
        ticks.append((session.state.t, np.linalg.norm(twist[:3]), np.linalg.norm(twist[3:])))
        since = session.state.gesture_since
        if since is not None and (not commands or commands[-1][0] != since):
            commands.append((since, session.state.gesture))

    session = open_session(
        f"replay:{stream_path}", "sim", recognizer=model, fast_replay=True, on_tick=on_tick
    )
    try:
        session.run()
    finally:
        session.close()
    t = np.array([x[0] for x in ticks])
    moving = np.array(
        [v > MOTION_LINEAR_M_S or w > MOTION_ANGULAR_RAD_S for _, v, w in ticks], dtype=bool
    )
    out = []
    for label, start, end in events:
        i0 = int(np.searchsorted(t, start))
        at_rest = i0 < len(t) and not moving[max(i0 - 1, 0)]
        after = np.flatnonzero(moving[i0:] & (t[i0:] <= end + 0.5))
        motion = float(t[i0 + after[0]]) if at_rest and after.size else None
        started = [(c, g) for c, g in commands if g is not None and start <= c <= end]
        command_s, commanded = started[0] if started else (None, None)
        out.append(GestureLatency(label, start, command_s, motion, at_rest, commanded))
    return out


def run_control_benchmark(
    model_dir: str | Path | None = None,
    loop_seconds: float = 5.0,
    streams: int = 2,
    stream_seconds: float = 40.0,
    ik_steps: int = 1000,
    recognizer: Any = None,
    gestures: list[str] | None = None,
    stops: bool = True,
    stop_robot: str = "sim",
) -> ControlBenchResult:
    """All four measurements; without a usable model only the IK and stop figures are
    measured (``loop_seconds=0`` and ``streams=0`` leave out the loop and the latency).

    ``gestures``: what the simulated streams of the latency figures hold (default: all);
    ``stops``: measure the stop times (about 40 s on a laptop core); ``stop_robot``: on the
    simulated arm (``sim``, simulated clock) or through the Techman client against the fake
    Techman controller (``techman-fake``, real time over loopback TCP, about 3 minutes).
    """
    times, rate = bench_ik(ik_steps)
    result = ControlBenchResult(
        ik_steps=len(times),
        ik_step_median_ms=1000 * float(np.median(times)),
        ik_step_p99_ms=1000 * float(np.percentile(times, 99)),
        ik_rate_hz=rate,
    )
    if stops:
        result.stop_robot = stop_robot
        if stop_robot == "sim":
            result.stop_times = summarise_stops(bench_stops())
        elif stop_robot == "techman-fake":
            with FakeTechmanArms() as arms:
                cases = stop_cases(durations=STOP_DURATIONS_REAL_TIME_S)
                result.stop_times = summarise_stops(bench_stops(arms, cases))
        else:
            raise ConfigError(f"stop robot {stop_robot!r} is neither 'sim' nor 'techman-fake'")
    if loop_seconds <= 0 and streams <= 0:
        return result
    if recognizer is None:
        try:
            recognizer = load_recognizer(model_dir)
        except FileNotFoundError as exc:
            if model_dir is not None:
                raise
            result.notes.append(f"control loop and latency not measured: {exc}")
            return result
    result.model = str(getattr(recognizer, "checkpoint_dir", "given recogniser"))
    if loop_seconds > 0:
        for key, value in bench_loop(recognizer, loop_seconds).items():
            setattr(result, key, value)
    latencies: list[GestureLatency] = []
    with tempfile.TemporaryDirectory(prefix="wovenskin-bench-control-") as tmp:
        for seed in range(streams):
            stream = simulate_stream(
                stream_seconds, seed=100 + seed, gestures=gestures or list(GESTURE_NAMES),
                invalid_fraction=0.0, idle_s=(1.0, 1.5),
            )  # fmt: skip
            path = Path(tmp) / f"stream{seed}.npz"
            write_labelled_stream(path, stream)
            events = list(
                zip(
                    [str(x) for x in stream.event_labels],
                    stream.event_start_s.tolist(),
                    stream.event_end_s.tolist(),
                    strict=True,
                )
            )
            latencies += measure_latencies(recognizer, path, events)
    _summarise_latencies(result, latencies)
    return result


def _summarise_latencies(result: ControlBenchResult, latencies: list[GestureLatency]) -> None:
    result.latency_gestures = len(latencies)
    moved = [x for x in latencies if x.motion_s is not None and x.recognised]
    result.latency_moved = len(moved)
    commanded = [x.command_s - x.contact_s for x in latencies if x.recognised]
    wrong = sum(x.command_s is not None and not x.recognised for x in latencies)
    if wrong:
        result.notes.append(f"{wrong} gesture(s) started another command first: not counted")
    if commanded:
        result.command_median_ms = 1000 * float(np.median(commanded))
    if not moved:
        result.notes.append("no gesture moved the arm: no end-to-end latency")
        return
    delays = np.array([x.motion_s - x.contact_s for x in moved])
    result.latency_median_ms = 1000 * float(np.median(delays))
    result.latency_p90_ms = 1000 * float(np.percentile(delays, 90))
    result.latency_max_ms = 1000 * float(delays.max())
    result.latency_within_target = float(np.mean(delays <= LATENCY_TARGET_S))
    per: dict[str, list[float]] = {}
    for x in moved:
        per.setdefault(x.gesture, []).append(x.motion_s - x.contact_s)
    result.latency_per_gesture_ms = {
        name: 1000 * float(np.median(values)) for name, values in sorted(per.items())
    }
    not_at_rest = sum(not x.at_rest for x in latencies)
    if not_at_rest:
        result.notes.append(f"{not_at_rest} gesture(s) began while the arm still moved: skipped")
