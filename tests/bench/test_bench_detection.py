"""Tests for wovenskin.bench.detection: the scoring of detection against ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from wovenskin.bench.detection import (
    PHANTOM_LEAD_S,
    PHANTOM_TAIL_S,
    RELEASE_WINDOW_S,
    DetectionReport,
    SeedDetection,
    evaluate_seed,
    event_mask,
    main,
    phantom_fraction,
    release_latencies,
    touched_fraction,
)

FS = 200.0
T = np.arange(int(10 * FS)) / FS  # 10 s
STARTS, ENDS = [2.0, 6.0], [3.0, 6.5]


def _touched(*spans: tuple[float, float]) -> np.ndarray:
    flag = np.zeros(T.shape, dtype=bool)
    for a, b in spans:
        flag |= (a <= T) & (b > T)
    return flag


def test_event_mask_widens_each_event():
    mask = event_mask(T, STARTS, ENDS, lead_s=0.1, tail_s=0.2)
    assert mask[T == 1.9].all() and not mask[T == 1.85].any()
    assert mask[T == 3.2].all() and not mask[T == 3.25].any()
    assert mask.sum() == int(round((1.3 + 0.8) * FS)) + 2


def test_phantom_fraction_counts_only_touches_outside_the_widened_events():
    inside_only = _touched((2.0 - PHANTOM_LEAD_S, 3.0 + PHANTOM_TAIL_S))
    assert phantom_fraction(inside_only, T, STARTS, ENDS) == 0.0
    outside = ~event_mask(T, STARTS, ENDS, PHANTOM_LEAD_S, PHANTOM_TAIL_S)
    one_second = _touched((8.0, 9.0))
    assert phantom_fraction(one_second, T, STARTS, ENDS) == pytest.approx(FS / outside.sum())
    assert phantom_fraction(np.ones(T.shape, bool), T, STARTS, ENDS) == 1.0
    assert phantom_fraction(np.ones(T.shape, bool), T, [0.0], [10.0]) == 0.0  # no outside


def test_touched_fraction_of_an_event():
    flag = _touched((2.5, 3.5))
    assert touched_fraction(flag, T, 2.0, 3.0) == pytest.approx(101 / 201, abs=1e-9)
    assert touched_fraction(flag, T, 20.0, 21.0) == 0.0


def test_release_latency_runs_from_the_last_lift_off_to_the_first_untouched_frame():
    flag = _touched((2.0, 3.1), (6.0, 9.0))  # second one never releases
    latencies = release_latencies(flag, T, STARTS, ENDS)
    assert latencies == pytest.approx([0.1, RELEASE_WINDOW_S])
    # An event followed too soon by the next one, or not touched at its end, is skipped.
    close = _touched((2.0, 3.1), (3.2, 3.8))
    assert release_latencies(close, T, [2.0, 3.2], [3.0, 3.5]) == [pytest.approx(0.3)]
    assert release_latencies(np.zeros(T.shape, bool), T, STARTS, ENDS) == []


def test_report_pools_seeds_and_lists_weak_events():
    a = SeedDetection(1, True, True, 0.01, ["push", "swipe_up"], [1.0, 0.5], [40.0, 9.0], [0.1])
    b = SeedDetection(2, False, False, 0.03, ["circle_cw_2f"], [0.9], [60.0], [0.2, 0.3])
    report = DetectionReport([a, b])
    assert report.mean_phantom == pytest.approx(0.02) and report.worst_phantom == 0.03
    assert report.median_touched == pytest.approx(0.9)
    assert report.calibration_ok_where_clean  # seed 2 started with a touch
    assert report.weak_events() == [(1, "swipe_up", 0.5, 9.0)]
    assert np.allclose(report.release_latency_s, [0.1, 0.2, 0.3])
    lines = report.lines()
    assert len(lines) == 3 and lines[0].startswith("seed  1 cal_ok True")
    assert "MEAN phantom 0.0200" in lines[-1]


def test_a_short_simulated_stream_scores_sanely(capsys):
    result = evaluate_seed(4, seconds=12.0)
    assert result.calibration_ok and result.contact_free_start
    assert 0.0 <= result.phantom_fraction <= 0.01
    assert result.event_touched and all(0.0 <= f <= 1.0 for f in result.event_touched)
    assert len(result.event_labels) == len(result.event_peak_snr)
    assert min(result.event_peak_snr) > 8  # every gesture rises well above the noise
    assert main(["4", "5"]) == 0
    assert "MEAN phantom" in capsys.readouterr().out
