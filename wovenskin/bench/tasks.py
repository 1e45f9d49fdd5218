"""Real-time factor of a task scene's physics (simulated seconds per wall second).

``wovenskin bench tasks [--task pour]`` resets the scene and measures, on this machine's
wall clock:

- **physics alone**: the scene stepped with the arm standing still, every object kept
  awake (MuJoCo's sleeping off: the cost while the particles move, as in a pour: the worst
  case), and again as the study runs it, resting objects asleep,
- **physics + arm control**: the control loop's share beside it, as the study runs it:
  every ``tick`` (20 ms) a twist (a horizontal circle of the TCP at 0.1 m/s) goes through
  :class:`~wovenskin.control.safety.SafetyLayer` (the task's workspace box), its watchdogs
  are fed and checked, and the :class:`~wovenskin.robots.sim.robot.SimRobot` advances the
  IK (200 Hz) and the physics (500 Hz) by one tick, every object awake, and
- **physics + arm control + recogniser**: the same loop, and every tick the skin frames
  of that tick (200 Hz: 4 per 20 ms, from a simulated person's stream made beforehand)
  go through conditioning, the shipped recogniser (ONNX Runtime, every frame, one thread)
  and the arbiter, as in ``wovenskin run``.

Each is printed with its ratio to 1.0 (real time); >= 1 keeps up.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import mujoco
import numpy as np
from rich.table import Table

from wovenskin.bench.results import BenchResult, figure_table
from wovenskin.control.safety import SafetyLayer
from wovenskin.control.safety_limits import SafetyLimits
from wovenskin.errors import ConfigError
from wovenskin.recognition.pipeline import (
    LivePipeline,
    conditioning_for_model,
    load_recognizer,
    pipeline_settings_for_model,
)
from wovenskin.signal.conditioner import LiveConditioner
from wovenskin.sim.stream import simulate_stream
from wovenskin.tasks import TASKS, WORKSPACE_LOWER, WORKSPACE_UPPER, Task, make_task

CIRCLE_SPEED = 0.1  # m/s
CIRCLE_RADIUS = 0.05  # m


@dataclass
class TasksBenchResult(BenchResult):
    """The two real-time factors of one task scene."""

    task: str
    seconds: float  # simulated seconds each
    tick_s: float
    physics_rtf: float
    control_rtf: float
    contacts: int  # contacts at the end of the run with control
    full_rtf: float  # physics + control + conditioning, recogniser and arbiter
    resting_rtf: float = 0.0  # physics alone, resting objects asleep

    def table(self) -> Table:
        table = figure_table(f"wovenskin bench tasks: the {self.task} scene's physics")
        table.add_row(
            f"physics alone, arm still, all awake ({self.seconds:g} s simulated)",
            f"{self.physics_rtf:.2f} x real time (ratio to 1.0: {self.physics_rtf:.2f})",
        )
        table.add_row(
            "physics alone, arm still, resting objects asleep",
            f"{self.resting_rtf:.2f} x real time (ratio to 1.0: {self.resting_rtf:.2f})",
        )
        table.add_row(
            f"physics + arm control through the safety layer, {1000 * self.tick_s:g} ms ticks",
            f"{self.control_rtf:.2f} x real time (ratio to 1.0: {self.control_rtf:.2f})",
        )
        table.add_row(
            "physics + arm control + conditioning, recogniser (every frame) and arbiter",
            f"{self.full_rtf:.2f} x real time (ratio to 1.0: {self.full_rtf:.2f})",
        )
        table.add_row("contacts in the scene at the end", str(self.contacts))
        return table


class _Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _scene(task_name: str, seed: int, awake: bool) -> Task:
    """``task_name``'s scene reset from ``seed``; ``awake``: nothing ever sleeps."""
    task = make_task(task_name)
    if awake:
        task.physics.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    task.reset(seed)
    return task


def physics_rtf(task_name: str, seconds: float, seed: int = 0, awake: bool = True) -> float:
    """Simulated seconds per wall second of the scene alone (the arm still); ``awake``:
    no object sleeps."""
    task = _scene(task_name, seed, awake)
    physics = task.physics
    q = physics.data.qpos[physics.arm_qpos].copy()
    start = time.perf_counter()
    physics.advance(q, q, seconds)
    return seconds / (time.perf_counter() - start)


class _SkinFeed:
    """A simulated person's skin stream fed tick by tick through the live recognition path."""

    def __init__(self, seconds: float, seed: int) -> None:
        self.stream = simulate_stream(seconds + 1.0, seed)
        recognizer = load_recognizer()
        conditioning = conditioning_for_model(recognizer)
        _, rows, cols = self.stream.frames.shape
        rate = float(self.stream.sample_rate_hz)
        self.conditioner = LiveConditioner(conditioning, rows, cols)
        self.pipeline = LivePipeline(
            recognizer, rows, cols, rate, conditioning, pipeline_settings_for_model(recognizer)
        )
        self.rate = rate
        self.next = 0

    def feed(self, seconds: float) -> None:
        """The next ``seconds`` of raw frames through conditioning, recogniser and arbiter."""
        stop = min(self.next + round(seconds * self.rate), len(self.stream.frames))
        out = self.conditioner.feed(self.stream.frames[self.next : stop])
        if out is not None and len(out):
            t = self.stream.t[stop - len(out) : stop]
            self.pipeline.process(t, out.signal, out.active, out.touched)
        self.next = stop


def control_rtf(
    task_name: str, seconds: float, tick: float = 0.02, seed: int = 0, recognise: bool = False
) -> tuple[float, int]:
    """Simulated seconds per wall second of the scene with the arm under control (and, with
    ``recognise``, a skin stream through the recogniser each tick), and the number of
    contacts at the end.  Every object is kept awake (the worst case)."""
    task = _scene(task_name, seed, awake=True)
    skin = _SkinFeed(seconds, seed) if recognise else None
    if skin is not None:
        skin.feed(1.0)  # calibration (the first second is contact-free), before the clock
    clock = _Clock()
    limits = SafetyLimits(workspace_lower=WORKSPACE_LOWER, workspace_upper=WORKSPACE_UPPER)
    robot = SafetyLayer(task.robot(), limits, clock=clock)
    robot.connect()
    omega = CIRCLE_SPEED / CIRCLE_RADIUS
    ticks = max(1, round(seconds / tick))
    start = time.perf_counter()
    for i in range(ticks):
        angle = omega * i * tick
        twist = np.array([-math.sin(angle), math.cos(angle), 0.0, 0.0, 0.0, 0.0]) * CIRCLE_SPEED
        if skin is not None:
            skin.feed(tick)
        robot.heartbeat_skin(clock.now)
        robot.send_twist(twist)
        robot.check(clock.now)
        robot.step(tick)
        clock.now += tick
    wall = time.perf_counter() - start
    return ticks * tick / wall, int(task.physics.data.ncon)


def run_tasks_benchmark(
    task: str = "pour", seconds: float = 5.0, tick: float = 0.02, seed: int = 0
) -> TasksBenchResult:
    """Both real-time factors of ``task``'s scene (module docstring)."""
    if task not in TASKS:
        raise ConfigError(f"unknown task {task!r}; known tasks: {', '.join(sorted(TASKS))}")
    if not (math.isfinite(seconds) and seconds > 0.0):
        raise ConfigError(f"seconds must be positive, got {seconds}")
    if not (math.isfinite(tick) and 0.0 < tick <= 0.1):
        raise ConfigError(f"tick must be in (0, 0.1] s, got {tick}")
    alone = physics_rtf(task, seconds, seed)
    resting = physics_rtf(task, seconds, seed, awake=False)
    controlled, contacts = control_rtf(task, seconds, tick, seed)
    full, _ = control_rtf(task, seconds, tick, seed, recognise=True)
    return TasksBenchResult(task, seconds, tick, alone, controlled, contacts, full, resting)
