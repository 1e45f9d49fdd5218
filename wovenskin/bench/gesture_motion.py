"""What single independent gestures make the simulated TM5-900 do (``wovenskin bench gestures``).

Each stream of :func:`wovenskin.independent.gesture_stream` (one flick or one held
swipe on its own person and skin) runs through a full
:class:`~wovenskin.control.session.ControlSession` (:func:`wovenskin.runtime.session.open_session`:
replayed as fast as possible into the simulated arm with the default mapping, its clock
the stream's).  Every control tick records the commanded twist (the shaped twist the
session sends) and the measured TCP.  Per stream, with *release* the last fingertip
leaving the skin (the event's ``lift_end_s``):

- *travel*: the TCP's path length over the whole stream; the arm *moved* when it exceeds
  :data:`MOVED_MM` (0.2 mm);
- *brake start*: the first tick at which the commanded twist is lower than at the tick
  before, at the start of the final fall to zero, minus the release (negative: the
  command ended while the finger was still on the skin);
- *at rest*: the first tick after the last one with the TCP moving at 1 mm/s or
  0.57 deg/s or more, minus the release;
- *still moving*: streams whose commanded twist had not fallen to zero when they ended.

Brake and rest times are taken over the streams that moved the arm.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin.bench.stops import STOP_REST_ANGULAR_RAD_S, STOP_REST_LINEAR_M_S
from wovenskin.control.mapping import MotionSettings
from wovenskin.control.session import ControlSession
from wovenskin.independent import gesture_stream
from wovenskin.recognition.pipeline import PipelineSettings
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.runtime.session import open_session

MOVED_MM = 0.2
"""A stream moved the arm when the TCP travelled further than this (mm)."""
DIRECTIONS = ("up", "down", "right", "left")


@dataclass
class GestureMotion:
    """What one single-gesture stream made the arm do."""

    kind: str  # "flick" or "held_swipe"
    label: str
    seed: int
    release_s: float  # the last fingertip leaves the skin (stream clock)
    commands: list[str]  # the recogniser's commands, in order (repeats merged)
    travel_mm: float
    brake_after_release_s: float | None
    rest_after_release_s: float | None
    still_moving: bool  # the commanded twist was not zero at the stream's end

    @property
    def moved(self) -> bool:
        return self.travel_mm > MOVED_MM

    @property
    def recognised(self) -> bool:
        return bool(self.commands) and self.commands[0] == self.label

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "label": self.label,
            "seed": self.seed,
            "release_s": self.release_s,
            "commands": list(self.commands),
            "travel_mm": self.travel_mm,
            "moved": self.moved,
            "brake_after_release_s": self.brake_after_release_s,
            "rest_after_release_s": self.rest_after_release_s,
            "still_moving": self.still_moving,
        }


def _twist_level(twist: np.ndarray, motion: MotionSettings) -> float:
    """A commanded twist's size: linear and angular parts as shares of the default speeds."""
    twist = np.asarray(twist, dtype=float)
    return float(
        np.linalg.norm(twist[:3]) / motion.linear_speed
        + np.linalg.norm(twist[3:]) / motion.angular_speed
    )


def analyse_ticks(
    t: np.ndarray,
    level: np.ndarray,
    position: np.ndarray,
    linear: np.ndarray,
    angular: np.ndarray,
    release_s: float,
) -> tuple[float, float | None, float | None, bool]:
    """Travel (mm), brake start and rest time after ``release_s`` (s), still moving.

    ``t`` tick times, ``level`` the commanded twist's size, ``position`` ``(n, 3)`` TCP
    positions (m), ``linear``/``angular`` measured TCP speeds (m/s, rad/s)."""
    travel = 1000.0 * float(np.linalg.norm(np.diff(position, axis=0), axis=1).sum())
    commanded = np.flatnonzero(level > 1e-9)
    still_moving = bool(commanded.size) and bool(commanded[-1] == len(level) - 1)
    if travel <= MOVED_MM or not commanded.size:
        return travel, None, None, still_moving
    j = int(commanded[-1]) + 1 if not still_moving else len(level) - 1  # the twist is zero
    while j > 0 and level[j - 1] > level[j] + 1e-12:
        j -= 1  # back to the top of the final fall
    brake = None
    if not still_moving and j + 1 < len(t):
        brake = float(t[j + 1] - release_s)
    moving = np.flatnonzero((linear >= STOP_REST_LINEAR_M_S) | (angular >= STOP_REST_ANGULAR_RAD_S))
    rest = None
    if moving.size and moving[-1] + 1 < len(t):
        rest = float(t[moving[-1] + 1] - release_s)
    return travel, brake, rest, still_moving


def run_gesture_stream(
    recognizer: Any,
    request: str,
    seed: int,
    kind: str,
    folder: Path,
    settings: PipelineSettings | None = None,
):
    """One single-gesture stream through a session on the simulated arm."""
    stream = gesture_stream(request, seed)
    event = stream.metadata["events"][0]
    path = folder / f"{kind}-{seed}.npz"
    write_labelled_stream(path, stream, overwrite=True)
    ticks: list[tuple[float, float, np.ndarray, float, float]] = []
    commands: list[str] = []
    motion = MotionSettings()

    def on_tick(session: ControlSession) -> None:
        state = session.state
        robot = state.robot
        twist = np.asarray(robot.tcp_twist, dtype=float)
        ticks.append(
            (state.t, _twist_level(state.twist, motion), np.asarray(robot.tcp.position, float),
             float(np.linalg.norm(twist[:3])), float(np.linalg.norm(twist[3:])))
        )  # fmt: skip

    session = open_session(
        f"replay:{path}", "sim", recognizer=recognizer, fast_replay=True, on_tick=on_tick,
        pipeline_settings=settings,
    )  # fmt: skip
    try:
        session.run()
    finally:
        session.close()
    # From the recogniser's own log: a command may start and end within one control tick.
    for change in session.pipeline.changes:
        if change.gesture is not None and (not commands or commands[-1] != change.gesture):
            commands.append(change.gesture)
    release = float(event["phases"]["lift_end_s"])
    t = np.array([x[0] for x in ticks])
    travel, brake, rest, still = analyse_ticks(
        t,
        np.array([x[1] for x in ticks]),
        np.array([x[2] for x in ticks]).reshape(-1, 3),
        np.array([x[3] for x in ticks]),
        np.array([x[4] for x in ticks]),
        release,
    )
    return GestureMotion(kind, str(stream.event_labels[0]), seed, release, commands, travel,
                         brake, rest, still)  # fmt: skip


@dataclass
class MotionSummary:
    """Figures of one kind of single-gesture stream."""

    kind: str
    streams: int = 0
    recognised: int = 0  # the first command was the gesture's own
    moved: int = 0
    still_moving: int = 0
    travel_mm: dict[str, float | None] = field(default_factory=dict)  # median, p90
    brake_s: dict[str, float | None] = field(default_factory=dict)
    rest_s: dict[str, float | None] = field(default_factory=dict)

    @property
    def moved_share(self) -> float:
        return self.moved / self.streams if self.streams else 0.0


def _median_p90(values: list[float]) -> dict[str, float | None]:
    if not values:
        return {"median": None, "p90": None, "n": 0}
    return {
        "median": float(np.median(values)),
        "p90": float(np.percentile(values, 90)),
        "n": len(values),
    }


def summarise(kind: str, runs: list[GestureMotion]) -> MotionSummary:
    moved = [r for r in runs if r.moved]
    return MotionSummary(
        kind=kind,
        streams=len(runs),
        recognised=sum(r.recognised for r in runs),
        moved=len(moved),
        still_moving=sum(r.still_moving for r in runs),
        travel_mm=_median_p90([r.travel_mm for r in runs]),
        brake_s=_median_p90(
            [r.brake_after_release_s for r in moved if r.brake_after_release_s is not None]
        ),
        rest_s=_median_p90(
            [r.rest_after_release_s for r in moved if r.rest_after_release_s is not None]
        ),
    )


def run_motion(
    recognizer: Any,
    flicks: int,
    held: int,
    seed: int,
    hold_s: float = 2.5,
    progress: Callable[[str], None] | None = None,
    save_dir: Path | None = None,
    settings: PipelineSettings | None = None,
) -> list[GestureMotion]:
    """``flicks`` flicks and ``held`` held swipes (directions in turn), each its own stream
    (seeds ``seed + 1000 + k`` and ``seed + 2000 + k``), through sessions run with
    ``settings`` (default: the model's own)."""
    plan = [("flick", f"swipe_{DIRECTIONS[k % 4]}:flick", seed + 1000 + k) for k in range(flicks)]
    plan += [
        ("held_swipe", f"swipe_{DIRECTIONS[k % 4]}:held={hold_s:g}", seed + 2000 + k)
        for k in range(held)
    ]
    runs = []
    with tempfile.TemporaryDirectory(prefix="wovenskin-bench-gestures-") as tmp:
        folder = save_dir if save_dir is not None else Path(tmp)
        for k, (kind, request, stream_seed) in enumerate(plan):
            if progress is not None:
                progress(f"{kind} {k + 1} of {len(plan)} through the simulated arm")
            runs.append(
                run_gesture_stream(recognizer, request, stream_seed, kind, folder, settings)
            )
    return runs
