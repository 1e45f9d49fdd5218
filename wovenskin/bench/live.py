"""``wovenskin bench live``: how much faster than real time the live path runs, on one core.

The live path is everything between the skin's raw frames and the commands: conditioning
(:class:`~wovenskin.signal.conditioner.LiveConditioner`), the network's windows, the touch
reader's tracking and reading, and the arbiter.  Independent mixed streams
(:func:`~wovenskin.independent.mixed_stream`, gestures and incidental touches with idle
gaps between them) are fed in blocks of 4 frames, as a live skin polled every 20 ms
delivers them, with ONNX Runtime on one thread and the process pinned to one CPU.

Three runs per stream split the cost: conditioning alone, the pipeline with the window
reader (the paper's), and the pipeline with the touch reader, each with its model's
recommended settings (the touch reader runs the network on every second window).  The
headline is stream seconds per second of wall-clock time for the pipeline with the
model's own reader.
"""

from __future__ import annotations

import platform
import time
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any

from rich.table import Table

from wovenskin.bench.results import BenchResult
from wovenskin.errors import ConfigError
from wovenskin.independent import mixed_stream
from wovenskin.recognition.pipeline import (
    conditioning_for_model,
    model_reader,
    pipeline_settings_for_model,
    run_pipeline,
)
from wovenskin.recognition.touch_reader import READERS
from wovenskin.signal.conditioner import LiveConditioner
from wovenskin.signal.config import ConditioningConfig
from wovenskin.training.timing import one_core

DEFAULT_STREAMS = 2
DEFAULT_SECONDS = 60.0
DEFAULT_SEED = 23000
BLOCK_FRAMES = 4  # frames between two 20 ms polls at 200 Hz
TARGET_X = 20.0  # the live path's target: 20x real time on one core


@dataclass
class LiveBenchResult(BenchResult):
    model: str
    reader: str
    streams: int
    seconds: float
    seed: int
    conditioning_x: float = 0.0
    readers_x: dict[str, float] = field(default_factory=dict)
    every: dict[str, int] = field(default_factory=dict)
    touched_share: float = 0.0
    cpu: str = ""
    date: str = ""

    @property
    def headline_x(self) -> float:
        return self.readers_x.get(self.reader, 0.0)

    def to_dict(self) -> dict:
        return {**super().to_dict(), "headline_x": self.headline_x, "target_x": TARGET_X}

    def table(self) -> Table:
        title = (
            f"wovenskin bench live: {self.streams} independent streams of {self.seconds:g} s, "
            f"blocks of {BLOCK_FRAMES} frames, one core"
        )
        table = Table(title=title)
        table.add_column("what")
        table.add_column("x real time", justify="right")
        table.add_row("conditioning alone", f"{self.conditioning_x:.1f}")
        for name, ratio in self.readers_x.items():
            own = " (the model's)" if name == self.reader else ""
            every = self.every.get(name, 1)
            table.add_row(
                f"conditioning + network (every {every}) + {name} reader + arbiter{own}",
                f"{ratio:.1f}",
            )
        verdict = "met" if self.headline_x >= TARGET_X else "missed"
        table.caption = (
            f"{100 * self.touched_share:.0f} % of the frames touched; target "
            f">= {TARGET_X:g}x with the model's reader: {verdict} ({self.headline_x:.1f}x)"
        )
        return table


def _condition_only(frames: Any, config: ConditioningConfig) -> tuple[float, float]:
    """Seconds to condition ``frames`` in live blocks, and the share of touched frames."""
    conditioner = LiveConditioner(config, frames.shape[1], frames.shape[2])
    touched = n = 0
    t0 = time.perf_counter()
    for start in range(0, frames.shape[0], BLOCK_FRAMES):
        out = conditioner.feed(frames[start : start + BLOCK_FRAMES])
        if out is not None and len(out):
            touched += int(out.touched.sum())
            n += len(out)
    return time.perf_counter() - t0, touched / max(n, 1)


def run_live_benchmark(
    recognizer: Any,
    streams: int = DEFAULT_STREAMS,
    seconds: float = DEFAULT_SECONDS,
    seed: int = DEFAULT_SEED,
) -> LiveBenchResult:
    """The live path's speed on ``streams`` independent streams (see the module doc)."""
    if not (isinstance(streams, int) and 1 <= streams <= 100):
        raise ConfigError(f"--streams must be an integer in [1, 100], got {streams!r}")
    if not 10.0 <= seconds <= 3600.0:
        raise ConfigError(f"--seconds must lie in [10, 3600], got {seconds:g}")
    config = conditioning_for_model(recognizer)
    settings = {name: pipeline_settings_for_model(recognizer, reader=name) for name in READERS}
    result = LiveBenchResult(
        model=str(getattr(recognizer, "checkpoint_dir", "given recogniser")),
        reader=model_reader(recognizer),
        streams=streams,
        seconds=seconds,
        seed=seed,
        every={name: s.every for name, s in settings.items()},
        cpu=platform.processor() or platform.machine(),
        date=datetime.now(UTC).date().isoformat(),
    )
    made = [mixed_stream(seconds, seed + k) for k in range(streams)]
    total = streams * seconds
    spent = dict.fromkeys(READERS, 0.0)
    conditioning = touched = 0.0
    with one_core():
        for stream in made:
            frames = stream.frames
            cfg = config or ConditioningConfig(sample_rate_hz=float(stream.sample_rate_hz))
            seconds_spent, share = _condition_only(frames, cfg)
            conditioning += seconds_spent
            touched += share / streams
            for name in READERS:
                run = run_pipeline(stream, recognizer, settings[name], block_frames=BLOCK_FRAMES)
                spent[name] += run.elapsed_s
    result.conditioning_x = total / conditioning
    result.readers_x = {name: total / spent[name] for name in READERS}
    result.touched_share = touched
    return result
