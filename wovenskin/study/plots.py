"""The report's figures as PNG: box plots of time and commands, top-view TCP paths."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from matplotlib.figure import Figure

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
    """Top view (x, y) of one participant's first trial of ``task`` with each interface;
    None when no participant has all of them."""
    who = trajectory_participant(trials, task, interfaces)
    if who is None:
        return None
    fig = Figure(figsize=(3.4 * len(interfaces), 3.6), layout="constrained")
    axes = fig.subplots(1, len(interfaces), sharex=True, sharey=True, squeeze=False)[0]
    for ax, interface in zip(axes, interfaces, strict=True):
        trial = min(
            (
                t
                for t in counted(trials)
                if t.participant == who and t.task == task and t.interface == interface
            ),
            key=lambda t: t.trial,
        )
        xy = read_trajectory(trial.folder)[:, 1:3]
        if len(xy):
            ax.plot(xy[:, 0], xy[:, 1], lw=1.2)
            ax.plot(xy[0, 0], xy[0, 1], "o", color="green", label="start")
            ax.plot(xy[-1, 0], xy[-1, 1], "s", color="red", label="end")
        ax.set_title(f"{interface} (trial {trial.trial})")
        ax.set_xlabel("x (m)")
        ax.set_aspect("equal", adjustable="box")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("y (m)")
    axes[0].legend(loc="best", fontsize="small")
    title = f"{task}: TCP path seen from above, participant {who}"
    fig.suptitle(title + (" (SYNTHETIC DATA)" if synthetic else ""))
    _save(fig, path)
    return path, who
