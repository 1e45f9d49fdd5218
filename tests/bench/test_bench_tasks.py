"""The task-scene benchmark: both real-time factors measured and reported."""

import json

import pytest

from wovenskin.bench.tasks import _SkinFeed, run_tasks_benchmark
from wovenskin.errors import ConfigError


def test_short_run_reports_the_three_factors():
    result = run_tasks_benchmark("pick_place", seconds=0.2, tick=0.02)
    assert result.physics_rtf > 0.0 and result.control_rtf > 0.0 and result.full_rtf > 0.0
    assert result.task == "pick_place" and result.contacts >= 1
    json.dumps(result.to_dict())
    assert result.table().row_count == 5 and result.resting_rtf > 0.0


def test_the_skin_feed_runs_the_recogniser_on_every_frame_it_is_given():
    feed = _SkinFeed(seconds=1.0, seed=3)
    feed.feed(1.5)
    assert feed.next == 300  # 1.5 s at 200 Hz
    assert feed.pipeline.streaming.windows_predicted > 0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"task": "juggle"}, "unknown task"), ({"seconds": 0.0}, "seconds"), ({"tick": 1.0}, "tick")],
)
def test_bad_arguments_are_one_line(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        run_tasks_benchmark(**kwargs)
