"""Tests of the I/O benchmark's plumbing (its figures are printed, never asserted)."""

from rich.console import Console

from wovenskin.bench.io import run_io_benchmark


def test_io_benchmark_runs_and_reports_every_stage():
    result = run_io_benchmark(n_frames=400)
    assert result.frames == 400
    for value in (result.decode_fps, result.condition_live_fps, result.condition_batch_fps):
        assert value > 0
    assert result.ratio_realtime == result.combined_fps / 200.0
    console = Console(record=True, width=120)
    console.print(result.table())
    assert "decode + conditioning" in console.export_text()
    assert set(result.to_dict()) >= {"decode_fps", "ratio_realtime", "date"}
