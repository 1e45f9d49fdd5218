"""The task registry: tasks by name, a clear error for an unknown one."""

import pytest

from wovenskin.errors import ConfigError
from wovenskin.tasks import TASKS, WORKSPACE_LOWER, PickPlaceTask, PourTask, make_task


def test_registry_names():
    assert {"pick_place": PickPlaceTask, "pour": PourTask} == TASKS
    assert isinstance(make_task("pick_place"), PickPlaceTask)


def test_unknown_task_is_one_line():
    with pytest.raises(ConfigError, match="unknown task 'juggle'.*pick_place, pour"):
        make_task("juggle")


def test_workspace_lets_the_fingertips_reach_the_table():
    assert 0.0 < WORKSPACE_LOWER[2] < 0.02
