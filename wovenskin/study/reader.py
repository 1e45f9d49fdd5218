"""Reading a study folder back: trial summaries, command logs and trajectories."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from wovenskin.study.logfiles import read_csv_rows, read_jsonl
from wovenskin.study.recorder import (
    COMMANDS_FILE,
    EVENTS_FILE,
    SUMMARY_FILE,
    TRAJECTORY_COLUMNS,
    TRAJECTORY_FILE,
    TRIALS_DIR,
)


@dataclass
class TrialResult:
    """One trial folder as read back.  ``complete`` is False without a valid
    ``trial.json``; such a trial is reported with a warning and left out of the tables."""

    participant: str
    task: str
    interface: str
    trial: int
    folder: Path
    complete: bool
    expertise: str = ""
    outcome: str = ""
    duration_s: float = float("nan")
    commands: int = 0
    measures: dict[str, float] = field(default_factory=dict)
    synthetic: bool = False
    problem: str = ""


def _from_folder_name(folder: Path) -> tuple[str, str, int]:
    task, interface, number = (
        folder.name.rsplit("-", 2) if folder.name.count("-") >= 2 else (folder.name, "", "0")
    )
    try:
        return task, interface, int(number)
    except ValueError:
        return task, interface, 0


def read_trial(folder: str | Path) -> TrialResult:
    """The trial in ``folder``: its summary if ``trial.json`` is there and whole, else an
    incomplete result that says why."""
    folder = Path(folder)
    task, interface, number = _from_folder_name(folder)
    partial = TrialResult(folder.parent.name, task, interface, number, folder, complete=False)
    summary_path = folder / SUMMARY_FILE
    if not summary_path.exists():
        commands, _ = (
            read_csv_rows(folder / COMMANDS_FILE)
            if (folder / COMMANDS_FILE).exists()
            else ([], False)
        )
        partial.commands = len(commands)
        partial.problem = "no trial.json (the trial did not finish: crash or abort)"
        return partial
    try:
        s = json.loads(summary_path.read_text(encoding="utf-8"))
        return TrialResult(
            participant=str(s["participant"]),
            task=str(s["task"]),
            interface=str(s["interface"]),
            trial=int(s["trial"]),
            folder=folder,
            complete=True,
            expertise=str(s["expertise"]),
            outcome=str(s["outcome"]),
            duration_s=float(s["duration_s"]),
            commands=int(s["commands"]),
            measures={str(k): float(v) for k, v in s.get("measures", {}).items()},
            synthetic=bool(s.get("synthetic", False)),
        )
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        partial.problem = f"unreadable trial.json ({type(exc).__name__}: {exc})"
        return partial


def trial_folders(study_dir: str | Path) -> list[Path]:
    """Every trial folder ``DIR/trials/<participant>/<task>-<interface>-<n>/``, sorted."""
    root = Path(study_dir) / TRIALS_DIR
    if not root.is_dir():
        return []
    return sorted(p for p in root.glob("*/*") if p.is_dir())


def read_trials(study_dir: str | Path) -> tuple[list[TrialResult], list[str]]:
    """The complete trials of the study and one warning line per incomplete one."""
    complete, warnings = [], []
    for folder in trial_folders(study_dir):
        trial = read_trial(folder)
        if trial.complete:
            complete.append(trial)
        else:
            where = folder.relative_to(Path(study_dir)).as_posix()
            warnings.append(f"{where}: incomplete, left out of the report: {trial.problem}")
    return complete, warnings


def read_commands(folder: str | Path) -> list[dict[str, str]]:
    """The whole rows of a trial's ``commands.csv`` (a torn last line is dropped)."""
    return read_csv_rows(Path(folder) / COMMANDS_FILE)[0]


def read_trajectory(folder: str | Path) -> np.ndarray:
    """A trial's ``trajectory.csv`` as an ``(n, 9)`` array: t, x, y, z, qw, qx, qy, qz,
    gripper (a torn last line is dropped)."""
    rows, _ = read_csv_rows(Path(folder) / TRAJECTORY_FILE)
    if not rows:
        return np.zeros((0, len(TRAJECTORY_COLUMNS)))
    return np.array([[float(r[c]) for c in TRAJECTORY_COLUMNS] for r in rows])


def read_events(folder: str | Path) -> list[dict]:
    """A trial's task events (``events.jsonl``), a torn last record dropped."""
    return read_jsonl(Path(folder) / EVENTS_FILE)[0]
