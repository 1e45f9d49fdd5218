"""``wovenskin bench io``: decode and conditioning throughput for a skin, on one core.

The input is a simulated stream (a simulated person performing gestures on a simulated
10 x 10 skin), encoded as binary-protocol FRAME messages.  Three stages are timed:

- decode: ``StreamDecoder.feed`` over 4 KiB chunks plus the device-order to ``[row, col]``
  conversion, as the serial reader does it;
- conditioning frame by frame: ``Conditioner.process`` called once per frame (the
  worst case, and the per-frame cost);
- conditioning in 20 ms blocks: what the live pipeline does (``LiveSkin`` polls the
  source every 20 ms and conditions the 4 frames that arrived);
- conditioning of the whole recording in one call (offline).

The headline ratio is decode plus conditioning in 20 ms blocks (the live path) against
the skin's sample rate (200 Hz); decode plus frame-by-frame conditioning is printed
beside it.  The process is pinned to one CPU while it runs.
"""

from __future__ import annotations

import platform
import time
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np
from rich.table import Table

from wovenskin.bench.results import BenchResult
from wovenskin.signal.calibration import calibrate
from wovenskin.signal.conditioner import Conditioner
from wovenskin.signal.config import ConditioningConfig
from wovenskin.sim.stream import simulate_stream
from wovenskin.skin.layout import ROW_MAJOR, SkinLayout
from wovenskin.skin.messages import FrameMessage
from wovenskin.skin.protocol import StreamDecoder, encode_message
from wovenskin.training.timing import one_core

CHUNK_BYTES = 4096
LIVE_BLOCK_FRAMES = 4  # frames that arrive between two 20 ms polls at 200 Hz


@dataclass
class IoBenchResult(BenchResult):
    frames: int
    rows: int
    cols: int
    sample_rate_hz: float
    decode_fps: float
    condition_live_fps: float
    condition_live_us_median: float
    condition_live_us_p99: float
    condition_block_fps: float
    condition_batch_fps: float
    combined_fps: float
    combined_frame_by_frame_fps: float
    ratio_realtime: float
    ratio_realtime_frame_by_frame: float
    cpu: str
    date: str

    def table(self) -> Table:
        table = Table(title=f"wovenskin bench io: {self.rows}x{self.cols} skin, one core")
        table.add_column("stage")
        table.add_column("frames/s", justify="right")
        table.add_column("x real time", justify="right")
        rt = self.sample_rate_hz
        for name, fps in (
            ("decode (COBS + CRC + parse + reorder)", self.decode_fps),
            ("conditioning, frame by frame", self.condition_live_fps),
            ("conditioning, 20 ms blocks (live)", self.condition_block_fps),
            ("conditioning, whole recording", self.condition_batch_fps),
            ("decode + conditioning, frame by frame", self.combined_frame_by_frame_fps),
            ("decode + conditioning, live path", self.combined_fps),
        ):
            table.add_row(name, f"{fps:,.0f}", f"{fps / rt:,.1f}")
        table.caption = (
            f"{self.frames} frames; live conditioning per frame: median "
            f"{self.condition_live_us_median:.1f} us, p99 {self.condition_live_us_p99:.1f} us; "
            f"target >= 100x real time ({rt:g} Hz) on the live path: "
            f"{'met' if self.ratio_realtime >= 100 else 'NOT met'} ({self.ratio_realtime:.0f}x; "
            f"frame by frame {self.ratio_realtime_frame_by_frame:.0f}x)"
        )
        return table


def bench_frames(n_frames: int, layout: SkinLayout, seed: int = 0) -> tuple[np.ndarray, float]:
    """A simulated stream long enough for ``n_frames`` frames (raw pF, ``[row, col]``)."""
    rate = 200.0
    stream = simulate_stream(n_frames / rate + 0.01, seed, layout=layout)
    return np.asarray(stream.frames[:n_frames], dtype=np.float32), stream.sample_rate_hz


def encode_frames(frames: np.ndarray) -> bytes:
    rows, cols = frames.shape[1:]
    parts = [
        encode_message(
            FrameMessage(i, i * 5000, rows, cols, ROW_MAJOR.to_samples(f, SkinLayout(rows, cols)))
        )
        for i, f in enumerate(frames)
    ]
    return b"\x00" + b"".join(parts)


def time_decode(wire: bytes, layout: SkinLayout) -> tuple[int, float]:
    decoder = StreamDecoder()
    n = 0
    start = time.perf_counter()
    for i in range(0, len(wire), CHUNK_BYTES):
        for msg in decoder.feed(wire[i : i + CHUNK_BYTES]):
            if isinstance(msg, FrameMessage):
                ROW_MAJOR.to_frames(msg.samples, layout)
                n += 1
    return n, time.perf_counter() - start


def run_io_benchmark(n_frames: int = 20000, rows: int = 10, cols: int = 10) -> IoBenchResult:
    layout = SkinLayout(rows, cols)
    frames, rate = bench_frames(n_frames, layout)
    wire = encode_frames(frames)
    config = ConditioningConfig(sample_rate_hz=rate)
    n_cal = int(round(config.calibration_s * rate))
    calibration = calibrate(frames[:n_cal], config)
    with one_core():
        decoded, decode_s = time_decode(wire, layout)
        if decoded != len(frames):
            raise RuntimeError(f"decoder returned {decoded} of {len(frames)} frames")
        live = Conditioner(calibration, config)
        per_frame = np.empty(len(frames))
        clock = time.perf_counter
        for i in range(len(frames)):
            t0 = clock()
            live.process(frames[i])
            per_frame[i] = clock() - t0
        blocks = Conditioner(calibration, config)
        t0 = clock()
        for i in range(0, len(frames), LIVE_BLOCK_FRAMES):
            blocks.process(frames[i : i + LIVE_BLOCK_FRAMES])
        block_s = clock() - t0
        batch = Conditioner(calibration, config)
        t0 = clock()
        batch.process(frames)
        batch_s = clock() - t0
    decode_fps = len(frames) / decode_s
    live_fps = len(frames) / per_frame.sum()
    block_fps = len(frames) / block_s
    combined = 1.0 / (1.0 / decode_fps + 1.0 / block_fps)
    combined_single = 1.0 / (1.0 / decode_fps + 1.0 / live_fps)
    return IoBenchResult(
        frames=len(frames),
        rows=rows,
        cols=cols,
        sample_rate_hz=rate,
        decode_fps=decode_fps,
        condition_live_fps=live_fps,
        condition_live_us_median=float(np.median(per_frame) * 1e6),
        condition_live_us_p99=float(np.percentile(per_frame, 99) * 1e6),
        condition_block_fps=block_fps,
        condition_batch_fps=len(frames) / batch_s,
        combined_fps=combined,
        combined_frame_by_frame_fps=combined_single,
        ratio_realtime=combined / rate,
        ratio_realtime_frame_by_frame=combined_single / rate,
        cpu=platform.processor() or platform.machine(),
        date=datetime.now(UTC).date().isoformat(),
    )
