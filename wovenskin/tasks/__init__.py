"""The study's task scenes on the simulated TM5-900 with a gripper, and their registry.

:mod:`.scene` builds the table scene around the gripper arm, :mod:`.shapes` the
pick-and-place shapes and molds, :mod:`.pick_place` and :mod:`.pour` the two tasks on the
:class:`~wovenskin.tasks.base.Task` interface; :func:`make_task` opens one by name.
"""

from wovenskin.errors import ConfigError
from wovenskin.tasks.base import WORKSPACE_LOWER, WORKSPACE_UPPER, Task
from wovenskin.tasks.pick_place import PickPlaceState, PickPlaceTask
from wovenskin.tasks.pour import PourState, PourTask

TASKS: dict[str, type[Task]] = {"pick_place": PickPlaceTask, "pour": PourTask}


def make_task(name: str, **options: object) -> Task:
    """A new task scene by its registry name (``pick_place``, ``pour``); ``options`` go to
    the task's constructor (``objects=("cube",)`` for a pick-and-place of one shape)."""
    try:
        kind = TASKS[name]
    except KeyError:
        known = ", ".join(sorted(TASKS))
        raise ConfigError(f"unknown task {name!r}; known tasks: {known}") from None
    return kind(**options)


__all__ = [
    "TASKS",
    "WORKSPACE_LOWER",
    "WORKSPACE_UPPER",
    "PickPlaceState",
    "PickPlaceTask",
    "PourState",
    "PourTask",
    "Task",
    "make_task",
]
