"""The report's numbers on hand-made trials: cells, participant means, reductions."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from wovenskin.study.reader import TrialResult
from wovenskin.study.tables import (
    fmt_mean_std,
    participant_means,
    reduction,
    summarise,
    task_table,
)


def _t(p, expertise, interface, n, time, commands, outcome="success", **measures):
    return TrialResult(
        p, "pour", interface, n, Path("."), True, expertise, outcome, time, commands, measures
    )


TRIALS = [
    _t("P1", "novice", "skin", 1, 10.0, 4, particles_spilled=0),
    _t("P1", "novice", "skin", 2, 20.0, 6, "timeout", particles_spilled=4),
    _t("P2", "expert", "skin", 1, 12.0, 5),
    _t("P2", "expert", "skin", 2, 99.0, 50, "aborted"),
    _t("P1", "novice", "keyboard", 1, 30.0, 10),
]


def test_a_cell_counts_timeouts_and_leaves_aborted_out():
    cell = summarise(TRIALS, "pour", "skin")
    assert (cell.participants, cell.trials) == (2, 3)
    assert cell.time_mean == pytest.approx(14.0) and cell.commands_mean == 5.0
    assert cell.success_rate == pytest.approx(2 / 3)
    assert cell.measures["particles_spilled"] == 2.0
    assert math.isnan(cell.measures["particles_delivered"])
    novice = summarise(TRIALS, "pour", "skin", "novice")
    assert novice.time_std == pytest.approx(math.sqrt(50))


def test_the_task_table_has_interface_by_expertise_then_all():
    rows = task_table(TRIALS, "pour", ["skin", "keyboard"])
    assert [(r.interface, r.expertise) for r in rows] == [
        ("skin", "expert"),
        ("skin", "novice"),
        ("skin", "all"),
        ("keyboard", "expert"),
        ("keyboard", "novice"),
        ("keyboard", "all"),
    ]
    assert rows[3].trials == 0 and fmt_mean_std(rows[3].time_mean, rows[3].time_std) == "n/a"


def test_participant_means_and_reduction():
    assert participant_means(TRIALS, "pour", "time") == {
        "P1": {"skin": 15.0, "keyboard": 30.0},
        "P2": {"skin": 12.0},
    }
    assert reduction(15.0, 30.0) == 50.0
    assert reduction(40.0, 30.0) == pytest.approx(-100 / 3)
    assert math.isnan(reduction(1.0, 0.0))
    assert fmt_mean_std(1.25, 0.5) == "1.2 ± 0.5" and fmt_mean_std(3.0, math.nan) == "3.0"
