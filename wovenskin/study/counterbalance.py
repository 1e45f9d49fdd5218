"""Counterbalanced run orders: balanced Latin squares (Williams designs) and study plans.

For ``n`` conditions the square's first row is ``0, 1, n-1, 2, n-2, 3, ...`` and row ``i``
adds ``i`` to every entry (mod ``n``): each condition appears once in each position.  For
even ``n`` these ``n`` rows are a Williams design: every ordered pair of conditions follows
directly once (first-order carry-over balanced).  For odd ``n`` no single square can do
that; the standard construction adds the mirror image of each row, ``2n`` rows in which
every ordered pair follows directly twice (Williams 1949, Aust. J. Sci. Res. A 2, 149-168).

A participant's row is their index in ``study.toml`` modulo the number of rows; tasks are
ordered the same way with their own square.  A *full block* is the least common multiple
of the two row counts: a multiple of it gives the balance above for both.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

from wovenskin.io import atomic_write_text
from wovenskin.study.definition import StudyDefinition

PLAN_FILE = "plan.csv"
PLAN_COLUMNS = (
    "participant",
    "expertise",
    "step",
    "task",
    "interface",
    "task_position",
    "interface_position",
    "trials",
)


def williams_rows(n: int) -> list[list[int]]:
    """The rows of the balanced Latin square for ``n`` conditions (``n`` rows if even,
    ``2n`` if odd), each a permutation of ``range(n)``."""
    if n < 1:
        raise ValueError(f"need at least one condition, got {n}")
    first = [0]
    low, high = 1, n - 1
    while len(first) < n:
        first.append(low)
        low += 1
        if len(first) < n:
            first.append(high)
            high -= 1
    rows = [[(c + i) % n for c in first] for i in range(n)]
    if n % 2 == 1 and n > 1:
        rows += [row[::-1] for row in rows]
    return rows


def order_for(index: int, conditions: tuple[str, ...] | list[str]) -> list[str]:
    """The order of ``conditions`` for the participant at position ``index`` (0-based)."""
    rows = williams_rows(len(conditions))
    return [conditions[c] for c in rows[index % len(rows)]]


def block_size(n_interfaces: int, n_tasks: int) -> int:
    """Participants in a full block: both squares' rows used equally often."""
    return math.lcm(len(williams_rows(n_interfaces)), len(williams_rows(n_tasks)))


@dataclass(frozen=True)
class PlanStep:
    """One condition of one participant's session: ``trials`` trials of a task with an
    interface, at ``step`` (1-based) in their run order."""

    participant: str
    expertise: str
    step: int
    task: str
    interface: str
    task_position: int
    interface_position: int
    trials: int


def study_plan(study: StudyDefinition) -> list[PlanStep]:
    """Every participant's run order: their tasks in their task order and, within each
    task, the interfaces in their interface order (the same interface order for every
    task, so each participant learns an interface once)."""
    steps = []
    for index, person in enumerate(study.participants):
        tasks = order_for(index, study.tasks)
        interfaces = order_for(index, study.interfaces)
        step = 0
        for t, task in enumerate(tasks, start=1):
            for i, interface in enumerate(interfaces, start=1):
                step += 1
                steps.append(
                    PlanStep(
                        person.id,
                        person.expertise,
                        step,
                        task,
                        interface,
                        t,
                        i,
                        study.trials_per_condition,
                    )
                )
    return steps


def plan_csv(steps: list[PlanStep]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(PLAN_COLUMNS)
    for s in steps:
        writer.writerow([getattr(s, column) for column in PLAN_COLUMNS])
    return out.getvalue()


def write_plan(directory: str | Path, study: StudyDefinition) -> tuple[Path, list[PlanStep]]:
    """Write ``DIR/plan.csv`` (replaced: it is derived from study.toml); returns it and
    the steps."""
    steps = study_plan(study)
    path = Path(directory) / PLAN_FILE
    atomic_write_text(path, plan_csv(steps))
    return path, steps
