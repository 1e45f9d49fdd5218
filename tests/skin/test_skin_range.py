"""Grids and sample rates wovenskin cannot use are one line, never a traceback (issue 23).

The supported range (:func:`wovenskin.skin.layout.check_supported`, docs/skins.md) is
checked once for every source: replayed files (``run --skin replay:``, ``replay``,
``eval-stream``), the simulated skin, the idle skin, a serial device's options and its
INFO message, and the simulated data set's grid.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pytest
from paths import REPO
from typer.testing import CliRunner

from wovenskin.bench.grids import measure, table
from wovenskin.cli import app
from wovenskin.errors import ConfigError
from wovenskin.recording.writer import RecordingWriter
from wovenskin.runtime.sources import open_source
from wovenskin.sim.pty_skin import FakeSkinDevice
from wovenskin.skin.frames import SkinInfo, SourceEvent
from wovenskin.skin.layout import (
    MAX_GRID_SIDE,
    MAX_SAMPLE_RATE_HZ,
    MIN_GRID_SIDE,
    MIN_SAMPLE_RATE_HZ,
    SkinLayout,
    UnsupportedSkinError,
    check_supported,
)

runner = CliRunner()

UNUSABLE = {  # name: (rows, cols, sample rate)
    "1x1": (1, 1, 200.0),
    "64x64": (64, 64, 200.0),
    "1x10": (1, 10, 200.0),
    "1e12 Hz": (10, 10, 1e12),
    "10 Hz": (10, 10, 10.0),
}


def _stream(path: Path, rows: int, cols: int, rate: float, seconds: float = 2.0) -> Path:
    n = max(int(seconds * min(rate, 1000.0)), 2)
    rng = np.random.default_rng(0)
    np.savez(
        path,
        frames=(20 + 0.01 * rng.standard_normal((n, rows, cols))).astype(np.float32),
        t=np.arange(n) / rate,
        sample_rate_hz=np.float64(rate),
        event_start_s=np.array([0.5 * n / rate]),
        event_end_s=np.array([0.6 * n / rate]),
        event_labels=np.array(["push"]),
    )
    return path


def _recording(path: Path, rows: int, cols: int, rate: float) -> Path:
    n = 50
    with RecordingWriter(path, SkinInfo(rows=rows, cols=cols, sample_rate_hz=rate)) as writer:
        writer.append_frames(
            np.arange(n, dtype=np.int64),
            np.arange(n) / rate,
            np.full((n, rows, cols), 20.0, dtype=np.float32),
        )
    return path


def _one_line(args: list[str]) -> str:
    result = runner.invoke(app, args)
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


def test_the_range_is_what_the_docs_say() -> None:
    assert (MIN_GRID_SIDE, MAX_GRID_SIDE) == (2, 32)
    assert (MIN_SAMPLE_RATE_HZ, MAX_SAMPLE_RATE_HZ) == (25.0, 2000.0)
    docs = (REPO / "docs" / "skins.md").read_text(encoding="utf-8")
    assert "2-32 rows and columns at 25-2000 Hz" in docs
    for rows, cols, rate in [(2, 2, 25.0), (32, 32, 2000.0), (8, 8, 200.0), (16, 12, 54.0)]:
        check_supported(rows, cols, rate)
    assert SkinLayout(16, 12).check_supported(200.0).shape == (16, 12)


@pytest.mark.parametrize(("rows", "cols", "rate"), list(UNUSABLE.values()), ids=list(UNUSABLE))
def test_check_supported_names_what_is_wrong_in_one_line(rows, cols, rate) -> None:
    with pytest.raises(UnsupportedSkinError) as caught:
        check_supported(rows, cols, rate, "skin X")
    message = str(caught.value)
    assert isinstance(caught.value, ConfigError) and "\n" not in message
    assert message.startswith("skin X: ") and "2-32 rows and columns at 25-2000 Hz" in message
    assert (f"{rows}x{cols} grid" in message) == ((rows, cols) != (10, 10))
    assert (f"{rate:g} Hz cannot" in message) == (rate != 200.0)


@pytest.mark.parametrize("name", list(UNUSABLE))
@pytest.mark.parametrize("kind", ["npz", "wsrec"])
def test_run_replay_and_eval_stream_refuse_the_file_in_one_line(tmp_path, name, kind) -> None:
    rows, cols, rate = UNUSABLE[name]
    if kind == "npz":
        path = _stream(tmp_path / "bad.npz", rows, cols, rate)
    else:
        path = _recording(tmp_path / "bad.wsrec", rows, cols, rate)
    run = ["run", "--skin", f"replay:{path}", "--robot", "sim", "--headless"]
    for args in (run, ["replay", str(path)], ["eval-stream", str(path)]):
        line = _one_line(args)
        assert str(path) in line and "cannot be used" in line, line


@pytest.mark.parametrize(
    ("skin", "words"),
    [
        ("sim:rows=1,cols=1,speed=0", "sim: a 1x1 grid"),
        ("sim:rows=40,cols=10,speed=0", "sim: a 40x10 grid"),
        ("none:rows=64,cols=64,speed=0", "a 64x64 grid"),
        ("none:rate=1e12,speed=0", "a sample rate of 1e+12 Hz"),
        ("serial:/dev/null?format=text&rows=1&cols=1", "serial:/dev/null: a 1x1 grid"),
        ("serial:/dev/null?format=text&rate=5", "a sample rate of 5 Hz"),
    ],
)
def test_live_sources_refuse_an_unusable_grid_or_rate(tmp_path, skin, words) -> None:
    with pytest.raises(UnsupportedSkinError, match=re.escape(words)):
        open_source(skin)
    line = _one_line(["record", "--out", str(tmp_path / "r.wsrec"), "--skin", skin])
    assert words in line


def test_the_dataset_and_simulate_refuse_an_unusable_grid(tmp_path) -> None:
    line = _one_line(["dataset", "--out", str(tmp_path / "d"), "--rows", "1", "--cols", "1"])
    assert "--rows/--cols: a 1x1 grid cannot be used" in line
    line = _one_line(["simulate", "--out", str(tmp_path / "s.npz"), "--rows", "64"])
    assert "--rows/--cols: a 64x10 grid cannot be used" in line
    stream = _stream(tmp_path / "s.npz", 8, 8, 200.0)
    line = _one_line(["dataset", "--out", str(tmp_path / "d"), "--streams", str(stream),
                      "--rows", "8"])  # fmt: skip
    assert "streams bring their own" in line


def test_a_device_declaring_an_unusable_grid_is_one_error_event() -> None:
    device = FakeSkinDevice(layout=SkinLayout(40, 40), rate_hz=50.0).start()
    source = open_source(f"serial:{device.port}")
    try:
        source.start()
        events: list[SourceEvent] = []
        deadline = time.monotonic() + 10.0  # only guards against a hang
        while not any(e.kind == "error" for e in events) and time.monotonic() < deadline:
            events += [item for item in source.poll(0.05) if isinstance(item, SourceEvent)]
        errors = [e for e in events if e.kind == "error"]
        assert len(errors) == 1, [(e.kind, e.message) for e in events]
        assert "a 40x40 grid cannot be used" in errors[0].message
        assert "\n" not in errors[0].message
        assert (source.info.rows, source.info.cols) == (10, 10)  # the INFO was not taken
    finally:
        source.close()
        device.stop()


def test_the_grid_benchmark_measures_both_stages() -> None:
    (cost,) = measure(grids=((4, 6),), rates_hz=(100.0,), repeats=3)
    assert (cost.rows, cost.cols, cost.rate_hz) == (4, 6, 100.0)
    assert cost.conditioning_us > 0 and cost.window_ms > 0  # never compared with a clock
    assert cost.recognition_share == pytest.approx(cost.window_ms * 1e-3 * 100.0)
    assert table([cost]).row_count == 1
