"""``wovenskin bench dashboard`` runs the real server and socket and reports its figures."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from wovenskin.bench.dashboard import _mouse_path, run_dashboard_benchmark
from wovenskin.cli import app


@pytest.mark.slow
def test_the_benchmark_measures_the_page_rate_and_the_swipes() -> None:
    result = run_dashboard_benchmark(idle_seconds=1.0, swipes=2)
    assert result.states_per_s > 0 and result.state_bytes > 1000
    assert result.swipes == 2 and len(result.commands) == 2
    assert 0 <= result.moved <= result.recognised <= 2
    if result.recognised:
        assert 0 < result.command_median_ms <= result.command_p90_ms
    if result.moved:  # a swipe that moved the arm stopped it after its lift-off
        assert 0 < result.lift_off_median_ms <= result.lift_off_p90_ms
        assert result.lift_off_median_ms <= result.lift_still_median_ms
        assert 0 <= result.lift_travel_median_mm <= result.lift_travel_max_mm < 100
    assert "page states" in str(result.table().columns[0]._cells)
    assert "lift-off -> no command" in str(result.table().columns[0]._cells)
    json.dumps(result.to_dict())


@pytest.mark.slow
def test_gestures_drawn_as_on_a_touch_screen_are_scored_by_their_first_command() -> None:
    result = run_dashboard_benchmark(
        idle_seconds=0.5, swipes=1, gesture_rounds=1, gestures=("pinch_out_5f", "push")
    )
    assert result.drawn_total == 2 and set(result.drawn) == {"pinch_out_5f", "push"}
    for name, firsts in result.drawn.items():
        assert len(firsts) == 1
        assert len(result.drawn_latency_ms.get(name, [])) == (firsts[0] == name)
    assert result.to_dict()["drawn_right"] == result.drawn_right
    assert "touch screen" in str(result.table().columns[0]._cells)


def test_the_command_refuses_bad_options() -> None:
    outcome = CliRunner().invoke(app, ["bench", "dashboard", "--swipes", "0"])
    assert outcome.exit_code == 2 and "--swipes 0: Input should be greater" in outcome.stderr


@pytest.mark.slow
def test_gestures_drawn_with_a_mouse_are_scored_per_gesture_and_sampling() -> None:
    result = run_dashboard_benchmark(
        idle_seconds=0.5, swipes=1, mouse_rounds=1, mouse_gestures=("swipe_left", "push")
    )
    assert set(result.mouse) == {"dense", "sparse"}
    for sampling in ("dense", "sparse"):
        success = result.mouse_success(sampling)
        assert set(success) == {"swipe_left", "push"}
        assert all(n == 1 and 0 <= right <= ended <= 1 for right, ended, n in success.values())
    assert result.to_dict()["mouse_success"]["sparse"]["push"][2] == 1
    assert "drawn with a mouse, sparse samples" in str(result.table().columns[0]._cells)


def test_a_sparse_mouse_stroke_sends_3_to_13_samples_along_the_drawn_path() -> None:
    import numpy as np

    rng = np.random.default_rng(3)
    t, xy, _ = _mouse_path("swipe_left", rng)
    travel = float(np.linalg.norm(xy[-1] - xy[0]))
    assert 40.0 <= travel <= 90.0 and 70.0 <= travel / t[-1] <= 250.0 + 1e-6
    assert xy[-1, 0] < xy[0, 0] and abs(xy[-1, 1] - xy[0, 1]) < 1e-9
