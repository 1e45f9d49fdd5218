"""Tests of the serial benchmark's plumbing over a real pty (figures are not asserted)."""

from wovenskin.bench.serial import run_serial_benchmark


def test_serial_benchmark_sees_frames_and_every_stall():
    result = run_serial_benchmark(stalls=2)
    assert result.frames > 100
    assert result.stalls == 2
    assert result.bad_frames == 0 and result.dropped_frames == 0
    assert result.stall_detect_ms_median > 0
