"""What the live path costs per grid and rate: ``python -m wovenskin.bench.grids``.

The measurement behind the supported range of :mod:`wovenskin.skin.layout`
(``docs/skins.md``).  For each grid, on one pinned core:

- conditioning: :class:`~wovenskin.signal.conditioner.LiveConditioner` fed two seconds of a
  noisy skin with one pressed channel in blocks of 10 frames (as a live skin delivers them),
  after calibration; microseconds per frame at each rate, the least of three passes (load
  from other processes only ever adds time);
- recognition: the shipped model's architecture and hyperparameters built for the grid,
  exported to ONNX and timed through ``predict_proba`` at batch 1 (median of interleaved
  calls, :func:`~wovenskin.training.timing.measure_latency`); weights do not change the
  cost of a forward pass, so they are freshly initialised.

Each cost is also shown as the share of one core it takes in real time when every frame
is conditioned and, while the skin is touched, every frame's window is classified.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from rich.console import Console
from rich.table import Table

from wovenskin.recognition.checkpoint_meta import ONNX_FILE, read_meta, write_meta
from wovenskin.recognition.onnx_runtime import OnnxRecognizer, export_onnx
from wovenskin.recognition.shipped import default_model_dir
from wovenskin.signal.conditioner import LiveConditioner
from wovenskin.signal.config import ConditioningConfig
from wovenskin.training.models import build_model
from wovenskin.training.timing import measure_latency, one_core

GRIDS = ((2, 2), (8, 8), (10, 10), (16, 12), (32, 32), (64, 64))
RATES_HZ = (200.0, 2000.0)
BLOCK_FRAMES = 10
CONDITIONING_PASSES = 3
WINDOW_REPEATS = 100


@dataclass(frozen=True)
class GridCost:
    """Measured cost of one grid at one rate."""

    rows: int
    cols: int
    rate_hz: float
    conditioning_us: float  # per frame
    window_ms: float  # per classified window, batch 1

    @property
    def conditioning_share(self) -> float:
        """Share of one core that conditioning every frame takes in real time."""
        return self.conditioning_us * 1e-6 * self.rate_hz

    @property
    def recognition_share(self) -> float:
        """Share of one core that classifying every frame's window takes in real time."""
        return self.window_ms * 1e-3 * self.rate_hz


def conditioning_us(rows: int, cols: int, rate_hz: float, seconds: float = 2.0) -> float:
    """Microseconds per frame of live conditioning (module docstring)."""
    config = ConditioningConfig(sample_rate_hz=rate_hz)
    rng = np.random.default_rng(0)
    calibration = config.calibration_frames
    n = calibration + int(seconds * rate_hz)
    frames = (20.0 + 0.01 * rng.standard_normal((n, rows, cols))).astype(np.float32)
    frames[n // 2 :, rows // 2, cols // 2] += 1.0  # a fingertip in the second half
    passes = []
    for _ in range(CONDITIONING_PASSES):
        conditioner = LiveConditioner(config, rows, cols)
        conditioner.feed(frames[:calibration])
        start = time.perf_counter()
        for i in range(calibration, n, BLOCK_FRAMES):
            conditioner.feed(frames[i : i + BLOCK_FRAMES])
        passes.append(time.perf_counter() - start)
    return 1e6 * min(passes) / (n - calibration)


def window_ms(rows: int, cols: int, repeats: int = WINDOW_REPEATS) -> float:
    """Median milliseconds per window of the shipped architecture built for the grid."""
    shipped = read_meta(default_model_dir())
    meta = shipped.with_updates(rows=rows, cols=cols)
    torch.manual_seed(0)
    model = build_model(meta.model_name, rows, cols, meta.window, meta.n_classes, **meta.hparams)
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        export_onnx(model, meta, directory / ONNX_FILE)
        write_meta(directory, meta)
        recognizer = OnnxRecognizer(directory, threads=1)
        pool = np.random.default_rng(0).standard_normal((8, 1, *meta.input_shape))
        times = measure_latency({"onnx": recognizer.predict_proba}, pool.astype(np.float32),
                                repeats)  # fmt: skip
    return 1e3 * float(np.median(times["onnx"]))


def measure(grids=GRIDS, rates_hz=RATES_HZ, repeats: int = WINDOW_REPEATS) -> list[GridCost]:
    """Every grid at every rate, on one pinned core."""
    torch.set_num_threads(1)
    out = []
    with one_core():
        for rows, cols in grids:
            per_window = window_ms(rows, cols, repeats)
            for rate in rates_hz:
                out.append(GridCost(rows, cols, rate, conditioning_us(rows, cols, rate),
                                    per_window))  # fmt: skip
    return out


def table(costs: list[GridCost]) -> Table:
    t = Table(title="live path cost per grid, one core (python -m wovenskin.bench.grids)")
    for name in ("grid", "rate", "conditioning", "share", "window (ONNX)", "share"):
        t.add_column(name, justify="right")
    for c in costs:
        t.add_row(
            f"{c.rows}x{c.cols}",
            f"{c.rate_hz:g} Hz",
            f"{c.conditioning_us:.0f} us/frame",
            f"{100 * c.conditioning_share:.1f} %",
            f"{c.window_ms:.2f} ms",
            f"{100 * c.recognition_share:.0f} %",
        )
    return t


def main() -> None:
    Console().print(table(measure()))


if __name__ == "__main__":
    main()
