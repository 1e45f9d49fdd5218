"""``wovenskin bench ros2``: a labelled stream replayed through ``run --robot ros2:`` against
the stand-in MoveIt Servo in another process, on a loopback-only Cyclone DDS configuration.

Two runs, each two processes (``wovenskin ros2 servo-standin`` and ``wovenskin run``):

1. the whole stream in real time: every twist checked on the wire
   (:func:`~wovenskin.bench.ros2_checks.wire_report`);
2. the stream again, with the stand-in's joint states stopped once the arm has moved for a
   while: how soon the client stopped the arm (:func:`~wovenskin.bench.ros2_checks.
   silence_report`).

Discovery stays on loopback (:func:`wovenskin.ros2.node.loopback_config`) on a random ROS
domain, so a run never reaches another machine nor another run.
"""

from __future__ import annotations

import os
import random
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.table import Table

from wovenskin.bench.results import BenchResult, figure_table
from wovenskin.bench.ros2_checks import silence_report, wire_report
from wovenskin.control.mapping import ActionMapping
from wovenskin.recording.formats import read_labelled_stream, write_labelled_stream
from wovenskin.recording.native import read_recording
from wovenskin.robots.ros2.standin import read_log
from wovenskin.robots.sim import tm5_900
from wovenskin.ros2.node import loopback_config
from wovenskin.sim.stream import simulate_stream

SEED = 24000


@dataclass
class Ros2BenchResult(BenchResult):
    stream_seconds: float
    events: int
    wire: dict[str, Any] = field(default_factory=dict)
    silence: dict[str, Any] = field(default_factory=dict)
    wall_s: float = 0.0

    def table(self) -> Table:
        table = figure_table(
            f"ros2: {self.stream_seconds:g} s stream ({self.events} gestures) replayed through "
            "run --robot ros2: against the stand-in Servo"
        )
        w, s = self.wire, self.silence

        def ms(stats: dict[str, Any]) -> str:
            if not stats or not stats.get("n"):
                return "-"
            return f"median {stats['median']:.1f}, max {stats['max']:.1f} ms (n={stats['n']})"

        table.add_row("twists received (rate)", f"{w['twists']} ({w['rate_hz']:.0f} Hz)")
        table.add_row("decoded by rosbags as TwistStamped", f"{w['decoded']} of {w['twists']}")
        table.add_row("stamp to receipt", ms(w["stamp_lag_ms"]))
        table.add_row(
            "moving twists outside commands", f"{w['moving_outside_commands']} of {w['moving']}"
        )
        table.add_row("moving twists finishing a flick's nudge", str(w["moving_in_nudges"]))
        table.add_row("along the mapped axis", f"{w['aligned']} (off axis: {w['misaligned']})")
        table.add_row("lift-off tick to zero twist", ms(w["lift_to_zero_ms"]))
        table.add_row("lift-off to zero twist after a nudge", ms(w["nudge_lift_to_zero_ms"]))
        table.add_row("true lift-off (label) to zero twist", ms(w["true_lift_to_zero_ms"]))
        zero = s.get("to_zero_ms")
        table.add_row("joint states stop -> zero twist", "-" if zero is None else f"{zero:.1f} ms")
        table.add_row(
            "moving twists / joint travel after it",
            f"{s.get('moving_after_zero')} / {s.get('moved_after_zero_rad', 0.0):.2g} rad",
        )
        table.add_row("wall time", f"{self.wall_s:.0f} s")
        return table


def _environment(config: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["CYCLONEDDS_URI"] = config.resolve().as_uri()
    env.pop("ROS_DOMAIN_ID", None)
    return env


def _start_standin(
    domain: int, log: Path, env: dict[str, str], extra: list[str]
) -> subprocess.Popen:
    command = [sys.executable, "-m", "wovenskin.cli", "ros2", "servo-standin",
               "--domain", str(domain), "--log", str(log), *extra]  # fmt: skip
    process = subprocess.Popen(
        command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert process.stdout is not None
    line = process.stdout.readline()  # "ready: ..." once the node is up, "" if it died
    if not line.startswith("ready"):
        process.kill()
        raise RuntimeError(f"the stand-in Servo did not start: {line}{process.stderr.read()}")
    return process


def _stop(process: subprocess.Popen) -> None:
    process.terminate()
    try:
        process.wait(timeout=10)
    except subprocess.TimeoutExpired:
        process.kill()


def replay_through_ros2(
    stream: Path,
    workdir: Path,
    domain: int,
    *,
    silence_after_s: float | None = None,
    seconds: float | None = None,
) -> tuple[list[dict[str, Any]], Path, subprocess.CompletedProcess]:
    """Replay ``stream`` in real time through ``wovenskin run --robot ros2:`` against a
    stand-in Servo; returns the stand-in's log, the run's recording and its process."""
    workdir.mkdir(parents=True, exist_ok=True)
    env = _environment(loopback_config(workdir / "cyclonedds.xml"))
    tag = "silence" if silence_after_s is not None else "wire"
    log, record = workdir / f"standin-{tag}.jsonl", workdir / f"run-{tag}.wsrec"
    extra = [] if silence_after_s is None else ["--silence-after", str(silence_after_s)]
    standin = _start_standin(domain, log, env, extra)
    try:
        command = [sys.executable, "-m", "wovenskin.cli", "run", "--headless",
                   "--robot", f"ros2:?domain={domain}", "--skin", f"replay:{stream}?speed=1",
                   "--record", str(record), "--overwrite"]  # fmt: skip
        if seconds is not None:
            command += ["--seconds", str(seconds)]
        run = subprocess.run(command, env=env, capture_output=True, text=True, timeout=600)
    finally:
        _stop(standin)
    return read_log(log), record, run


def run_ros2_benchmark(
    workdir: Path,
    stream_seconds: float = 30.0,
    seed: int = SEED,
    progress: Callable[[str], None] = lambda _what: None,
) -> Ros2BenchResult:
    """Both runs (module docstring) on a simulated stream of ``stream_seconds``."""
    started = time.monotonic()
    workdir.mkdir(parents=True, exist_ok=True)
    stream_path = workdir / "stream.npz"
    progress("simulating the stream")
    write_labelled_stream(
        stream_path, simulate_stream(stream_seconds, seed, invalid_fraction=0.0), overwrite=True
    )
    stream = read_labelled_stream(stream_path)
    domain = random.Random(seed ^ os.getpid()).randrange(100, 200)
    progress("replaying through ros2: (1 of 2)")
    log, record, run = replay_through_ros2(stream_path, workdir, domain)
    if run.returncode != 0:
        raise RuntimeError(f"wovenskin run failed: {run.stderr.strip().splitlines()[-1:]}")
    report = wire_report(
        log, read_recording(record), tm5_900.urdf_chain(), ActionMapping.load(),
        [float(end) for end in stream.event_end_s],
    )  # fmt: skip
    progress("joint states stopping (2 of 2)")
    log, _, _ = replay_through_ros2(
        stream_path, workdir, domain, silence_after_s=0.3, seconds=min(stream_seconds, 12.0)
    )
    silence = silence_report(log)
    return Ros2BenchResult(
        stream_seconds=stream_seconds,
        events=len(stream.event_labels),
        wire=report.to_dict(),
        silence=silence.to_dict(),
        wall_s=time.monotonic() - started,
    )
