"""The report's numbers: per task, interface and expertise; participant means; reductions.

Times and commands are summarised over trials (mean +/- sample std), every counted trial
included: a time-out counts at the time limit (censored, so an interface that fails is not
flattered by leaving its failures out); "aborted" trials (an experimenter's stop, e.g. a
fault) are not counted.  The paired tests use one value per participant: their mean over
the counted trials of a condition.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from wovenskin.study.reader import TrialResult

ALL = "all"
METRICS = {"time": "duration_s", "commands": "commands"}
TASK_MEASURES = {
    "pick_place": ("objects_seated",),
    "pour": ("particles_delivered", "particles_spilled"),
}


def counted(trials: Sequence[TrialResult]) -> list[TrialResult]:
    """The trials that enter the tables: complete and not aborted."""
    return [t for t in trials if t.complete and t.outcome != "aborted"]


def metric(trial: TrialResult, name: str) -> float:
    return float(getattr(trial, METRICS[name]))


@dataclass(frozen=True)
class CellSummary:
    """One row of a task's table: an interface and an expertise level (or "all")."""

    task: str
    interface: str
    expertise: str
    participants: int
    trials: int
    time_mean: float
    time_std: float
    commands_mean: float
    commands_std: float
    success_rate: float
    measures: dict[str, float]


def _mean_std(values: Sequence[float]) -> tuple[float, float]:
    if not values:
        return math.nan, math.nan
    std = float(np.std(values, ddof=1)) if len(values) > 1 else math.nan
    return float(np.mean(values)), std


def summarise(
    trials: Sequence[TrialResult], task: str, interface: str, expertise: str = ALL
) -> CellSummary:
    cell = [
        t
        for t in counted(trials)
        if t.task == task and t.interface == interface and expertise in (ALL, t.expertise)
    ]
    time_mean, time_std = _mean_std([t.duration_s for t in cell])
    commands_mean, commands_std = _mean_std([float(t.commands) for t in cell])
    success = sum(t.outcome == "success" for t in cell) / len(cell) if cell else math.nan
    measures = {}
    for name in TASK_MEASURES.get(task, ()):
        values = [t.measures[name] for t in cell if name in t.measures]
        measures[name] = float(np.mean(values)) if values else math.nan
    return CellSummary(
        task,
        interface,
        expertise,
        len({t.participant for t in cell}),
        len(cell),
        time_mean,
        time_std,
        commands_mean,
        commands_std,
        success,
        measures,
    )


def task_table(
    trials: Sequence[TrialResult], task: str, interfaces: Sequence[str]
) -> list[CellSummary]:
    """The paper's layout for one task: each interface by each expertise, then all."""
    levels = sorted({t.expertise for t in counted(trials) if t.task == task})
    rows = []
    for interface in interfaces:
        rows += [summarise(trials, task, interface, level) for level in levels]
        if len(levels) != 1:
            rows.append(summarise(trials, task, interface, ALL))
    return rows


def participant_means(
    trials: Sequence[TrialResult], task: str, name: str
) -> dict[str, dict[str, float]]:
    """``{participant: {interface: mean of metric name}}`` over the task's counted trials."""
    values: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for t in counted(trials):
        if t.task == task:
            values[t.participant][t.interface].append(metric(t, name))
    return {p: {i: float(np.mean(v)) for i, v in by.items()} for p, by in values.items()}


def reduction(skin: float, other: float) -> float:
    """How much less the skin needs than ``other``, in percent of ``other``."""
    if not (math.isfinite(skin) and math.isfinite(other)) or other == 0:
        return math.nan
    return 100.0 * (other - skin) / other


def fmt(value: float, digits: int = 1) -> str:
    return "n/a" if not math.isfinite(value) else f"{value:.{digits}f}"


def fmt_mean_std(mean: float, std: float, digits: int = 1) -> str:
    if not math.isfinite(mean):
        return "n/a"
    return fmt(mean, digits) if not math.isfinite(std) else f"{mean:.{digits}f} ± {std:.{digits}f}"
