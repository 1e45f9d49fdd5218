"""Balanced Latin squares: position balance, first-order carry-over balance, the plan."""

from __future__ import annotations

import csv
import io
from collections import Counter

from hypothesis import given
from hypothesis import strategies as st

from wovenskin.study.counterbalance import (
    block_size,
    order_for,
    plan_csv,
    study_plan,
    williams_rows,
    write_plan,
)
from wovenskin.study.definition import Participant, StudyDefinition


@given(st.integers(2, 6))
def test_every_row_is_a_permutation_and_positions_are_balanced(n):
    rows = williams_rows(n)
    assert len(rows) == (n if n % 2 == 0 else 2 * n)
    assert all(sorted(row) == list(range(n)) for row in rows)
    for position in range(n):
        counts = Counter(row[position] for row in rows)
        assert set(counts.values()) == {len(rows) // n}, (position, counts)


@given(st.integers(2, 6))
def test_first_order_carry_over_is_balanced(n):
    rows = williams_rows(n)
    pairs = Counter((a, b) for row in rows for a, b in zip(row, row[1:], strict=False))
    assert len(pairs) == n * (n - 1)  # every ordered pair of different conditions
    assert set(pairs.values()) == {1 if n % 2 == 0 else 2}


def test_the_square_is_the_documented_one():
    assert williams_rows(4) == [[0, 1, 3, 2], [1, 2, 0, 3], [2, 3, 1, 0], [3, 0, 2, 1]]
    assert williams_rows(3)[:3] == [[0, 1, 2], [1, 2, 0], [2, 0, 1]]
    assert williams_rows(3)[3] == [2, 1, 0]
    assert order_for(7, ["a", "b"]) == ["b", "a"]


def _study(n_participants: int) -> StudyDefinition:
    people = tuple(
        Participant(f"P{i:02d}", "novice" if i % 2 else "expert") for i in range(n_participants)
    )
    return StudyDefinition(name="s", trials_per_condition=2, participants=people)


def test_a_full_block_of_participants_balances_interfaces_and_tasks():
    assert block_size(3, 2) == 6
    plan = study_plan(_study(6))
    assert len(plan) == 6 * 2 * 3
    firsts = Counter(
        s.interface for s in plan if s.interface_position == 1 and s.task_position == 1
    )
    assert set(firsts.values()) == {2}
    first_tasks = Counter(s.task for s in plan if s.step == 1)
    assert set(first_tasks.values()) == {3}


def test_the_plan_is_deterministic_and_written_as_csv(tmp_path):
    study = _study(3)
    assert study_plan(study) == study_plan(study)
    path, steps = write_plan(tmp_path, study)
    rows = list(csv.DictReader(io.StringIO(path.read_text())))
    assert len(rows) == len(steps) == 18
    assert rows[0]["participant"] == "P00" and rows[0]["step"] == "1"
    assert rows[0]["trials"] == "2"
    assert plan_csv(steps) == path.read_text()
    p1 = [r["interface"] for r in rows if r["participant"] == "P01" and r["task_position"] == "1"]
    assert p1 == ["keyboard", "pendant", "skin"]
