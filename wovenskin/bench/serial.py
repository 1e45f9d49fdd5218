"""``wovenskin bench serial``: the serial reader end to end over a real pseudo-terminal.

A :class:`~wovenskin.sim.fake_device.FakeSkinDevice` streams the binary protocol at
200 Hz into a pty; a :class:`~wovenskin.skin.serial_source.SerialSkinSource` reads it.
The device stalls a number of times; the benchmark measures how long after the last
frame before each stall the consumer received the ``stalled`` event (target: within
50 ms), plus frames received and counters.  Timing is wall clock, so figures from a busy
machine are pessimistic.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from rich.table import Table

from wovenskin.bench.results import BenchResult, figure_table
from wovenskin.sim.pty_skin import FakeSkinDevice
from wovenskin.skin.frames import Frame, SourceEvent
from wovenskin.skin.serial_source import SerialSkinSource


@dataclass
class SerialBenchResult(BenchResult):
    frames: int
    bad_frames: int
    dropped_frames: int
    stalls: int
    stall_detect_ms_median: float
    stall_detect_ms_max: float
    stall_ms_setting: float

    def table(self) -> Table:
        table = figure_table("wovenskin bench serial: fake device over a pty, 200 Hz binary")
        table.add_row("frames received", str(self.frames))
        table.add_row("bad / dropped frames", f"{self.bad_frames} / {self.dropped_frames}")
        table.add_row("stalls reported", str(self.stalls))
        table.add_row("stall setting", f"{self.stall_ms_setting:g} ms")
        table.add_row("stall reported, median", f"{self.stall_detect_ms_median:.1f} ms")
        table.add_row("stall reported, max", f"{self.stall_detect_ms_max:.1f} ms")
        ok = self.stall_detect_ms_max <= 50.0
        table.caption = (
            "delay from the last frame before a stall to the consumer's stalled event; "
            f"target within 50 ms: {'met' if ok else 'NOT met'}"
        )
        return table


def run_serial_benchmark(stalls: int = 10, stall_ms: float = 30.0) -> SerialBenchResult:
    device = FakeSkinDevice(rate_hz=200.0, boot_banner=False).start()
    source = SerialSkinSource(device.port, stall_ms=stall_ms)
    delays: list[float] = []
    frames = 0
    last_frame_host = None
    try:
        source.start()
        deadline = time.monotonic() + 10.0 + stalls
        next_pause = time.monotonic() + 1.0
        while len(delays) < stalls and time.monotonic() < deadline:
            for item in source.poll(0.005):
                if isinstance(item, Frame):
                    frames += 1
                    last_frame_host = item.t_host
                elif (
                    isinstance(item, SourceEvent)
                    and item.kind == "stalled"
                    and last_frame_host is not None
                ):
                    delays.append(time.monotonic() - last_frame_host)
            if time.monotonic() >= next_pause and frames:
                device.pause(0.15)
                next_pause = time.monotonic() + 0.4
        stats = source.stats()
    finally:
        source.close()
        device.stop()
    ms = np.array(delays) * 1e3 if delays else np.array([np.nan])
    return SerialBenchResult(
        frames=frames,
        bad_frames=stats.bad_frames,
        dropped_frames=stats.dropped_frames,
        stalls=len(delays),
        stall_detect_ms_median=float(np.median(ms)),
        stall_detect_ms_max=float(np.max(ms)),
        stall_ms_setting=stall_ms,
    )
