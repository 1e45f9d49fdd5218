"""Tests of the simulator benchmark's plumbing (its figures are printed, never asserted)."""

from rich.console import Console

from wovenskin.bench.sim import FAMILIES, run_sim_benchmark


def test_sim_benchmark_reports_every_family():
    result = run_sim_benchmark(stream_seconds=2.0, repeats=1)
    assert result.stream_x_realtime > 0
    assert set(result.families) == set(FAMILIES)
    assert all(v > 0 for v in result.families.values())
    console = Console(record=True, width=100)
    console.print(result.table())
    assert "simulate_stream" in console.export_text()
