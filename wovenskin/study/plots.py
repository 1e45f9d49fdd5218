"""The report's figures as PNG: box plots of time and commands, top-view TCP paths."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from wovenskin.io import atomic_write_with
from wovenskin.study.reader import TrialResult, read_trajectory
from wovenskin.study.tables import counted, metric


def _save(fig: Figure, path: Path) -> None:
    atomic_write_with(path, lambda f: fig.savefig(f, format="png", dpi=110))


def box_plots(
    trials: Sequence[TrialResult],
    task: str,
    interfaces: Sequence[str],
    path: Path,
    synthetic: bool = False,
) -> Path:
    """Time and commands per interface for ``task``, one box per interface (trials)."""
    fig = Figure(figsize=(9, 3.8), layout="constrained")
    for ax, (name, label) in zip(
        fig.subplots(1, 2), (("time", "time (s)"), ("commands", "commands")), strict=True
    ):
        data = [
            [metric(t, name) for t in counted(trials) if t.task == task and t.interface == i]
            for i in interfaces
        ]
        ax.boxplot(data, tick_labels=list(interfaces))
        ax.set_ylabel(label)
        ax.grid(axis="y", alpha=0.3)
    title = f"{task}: time and commands per interface"
    fig.suptitle(title + (" (SYNTHETIC DATA)" if synthetic else ""))
    _save(fig, path)
    return path


def trajectory_participant(
    trials: Sequence[TrialResult], task: str, interfaces: Sequence[str]
) -> str | None:
    """The first participant (by id) with a counted trial of ``task`` on every interface."""
    have = {(t.participant, t.interface) for t in counted(trials) if t.task == task}
    people = sorted({p for p, _ in have})
    return next((p for p in people if all((p, i) in have for i in interfaces)), None)


def trajectory_plot(
    trials: Sequence[TrialResult],
    task: str,
    interfaces: Sequence[str],
    path: Path,
    synthetic: bool = False,
) -> tuple[Path, str] | None:
    """Write :func:`trajectory_figure` to ``path``; returns it and the participant, or
    None when no participant has a trial on every interface."""
    drawn = trajectory_figure(trials, task, interfaces, synthetic)
    if drawn is None:
        return None
    _save(drawn[0], path)
    return path, drawn[1]


def trajectory_figure(
    trials: Sequence[TrialResult],
    task: str,
    interfaces: Sequence[str],
    synthetic: bool = False,
) -> tuple[Figure, str] | None:
    """Top view (x, y) of one participant's first trial of ``task`` with each interface,
    and the participant; None when no participant has all of them."""
    who = trajectory_participant(trials, task, interfaces)
    if who is None:
        return None
    shown = []
    for interface in interfaces:
        trial = min(
            (
                t
                for t in counted(trials)
                if t.participant == who and t.task == task and t.interface == interface
            ),
            key=lambda t: t.trial,
        )
        shown.append((interface, trial, read_trajectory(trial.folder)[:, 1:3]))
    fig = Figure(figsize=(3.4 * len(interfaces), 3.9), layout="constrained")
    axes = fig.subplots(1, len(interfaces), sharex=True, sharey=True, squeeze=False)[0]
    for ax, (interface, trial, xy) in zip(axes, shown, strict=True):
        if len(xy):
            ax.plot(xy[:, 0], xy[:, 1], lw=1.2)
            ax.plot(xy[0, 0], xy[0, 1], "o", color="green", label="start")
            ax.plot(xy[-1, 0], xy[-1, 1], "s", color="red", label="end")
        ax.set_title(f"{interface} (trial {trial.trial})")
        ax.set_xlabel("x (m)")
        ax.grid(alpha=0.3)
    _square_view(axes, [xy for _, _, xy in shown])
    axes[0].set_ylabel("y (m)")
    handles, labels = axes[0].get_legend_handles_labels()
    if handles:  # beside the paths, not over them
        fig.legend(handles, labels, loc="outside lower center", ncols=2, fontsize="small")
    title = f"{task}: TCP path seen from above, participant {who}"
    fig.suptitle(title + (" (SYNTHETIC DATA)" if synthetic else ""))
    return fig, who


def _square_view(axes: Sequence, paths: Sequence[np.ndarray], margin: float = 0.08) -> None:
    """The same square, equal-scale window on every (shared) axis, around all ``paths``,
    with few ticks: a path that is narrow in x keeps a readable x axis (no crowded labels)."""
    points = [xy for xy in paths if len(xy)]
    if not points:
        return
    every = np.concatenate(points)
    low, high = every.min(axis=0), every.max(axis=0)
    half = max(float((high - low).max()) / 2 * (1 + margin), 0.01)
    centre = (low + high) / 2
    axes[0].set_xlim(centre[0] - half, centre[0] + half)
    axes[0].set_ylim(centre[1] - half, centre[1] + half)
    for ax in axes:
        ax.set_aspect("equal", adjustable="box")
        ax.xaxis.set_major_locator(MaxNLocator(nbins=4))
        ax.yaxis.set_major_locator(MaxNLocator(nbins=5))
