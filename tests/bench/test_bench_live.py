"""Tests of the live-path benchmark's plumbing (its figures are printed, never asserted)."""

import pytest
from rich.console import Console

from wovenskin.bench.live import TARGET_X, run_live_benchmark
from wovenskin.errors import ConfigError
from wovenskin.recognition.pipeline import load_recognizer
from wovenskin.recognition.touch_reader import READERS


def test_live_benchmark_times_both_readers_and_names_the_models_own():
    recognizer = load_recognizer(None, threads=1)
    result = run_live_benchmark(recognizer, streams=1, seconds=10.0, seed=5)
    assert set(result.readers_x) == set(READERS)
    assert result.reader == "touch" and result.every == {"touch": 4, "window": 1}
    assert result.conditioning_x > 0 and all(x > 0 for x in result.readers_x.values())
    assert 0.0 < result.touched_share < 1.0
    figures = result.to_dict()
    assert figures["headline_x"] == result.readers_x["touch"] and figures["target_x"] == TARGET_X
    console = Console(record=True, width=120)
    console.print(result.table())
    assert "conditioning alone" in console.export_text()


@pytest.mark.parametrize("options", [{"streams": 0}, {"seconds": 5.0}])
def test_live_benchmark_refuses_a_bad_option_in_one_line(options):
    with pytest.raises(ConfigError):
        run_live_benchmark(load_recognizer(None, threads=1), **options)
