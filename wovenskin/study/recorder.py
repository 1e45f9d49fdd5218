"""A trial's logs, written as it runs: commands, TCP trajectory, task events and summary.

A runner makes one :class:`TrialRecorder` per trial and calls ``start``, then ``command``,
``pose`` and ``task_event`` as things happen, then ``finish``.  Every line is appended and
flushed at once (a killed process loses at most the line being written); ``trial.json``,
the summary, is written last and atomically, so a trial without it is known to be
incomplete.  The folder format is docs/study.md's.
"""

from __future__ import annotations

import math
import shutil
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from wovenskin.errors import DataError
from wovenskin.io import dumps, write_json
from wovenskin.outputs import OutputExistsError
from wovenskin.study.definition import check_participant_id
from wovenskin.study.logfiles import LineLog

TRIALS_DIR = "trials"
TRIALS_FILE = "trials.csv"
SUMMARY_FILE = "trial.json"
COMMANDS_FILE = "commands.csv"
TRAJECTORY_FILE = "trajectory.csv"
EVENTS_FILE = "events.jsonl"
TRIAL_FORMAT = "wovenskin-trial/1"

COMMAND_KINDS = ("gesture", "key", "panel", "gripper")
# "failed": the task itself can no longer succeed (a spill, an object off the table).
OUTCOMES = ("success", "give_up", "timeout", "aborted", "failed")
COMMAND_COLUMNS = ("t", "source", "command", "kind")
TRAJECTORY_COLUMNS = ("t", "x", "y", "z", "qw", "qx", "qy", "qz", "gripper")
# The measures the two tasks report, given columns of their own in trials.csv.
MEASURE_COLUMNS = (
    "objects_seated",
    "objects_total",
    "particles_delivered",
    "particles_spilled",
    "particles_total",
)
TRIALS_COLUMNS = (
    "participant",
    "expertise",
    "task",
    "interface",
    "trial",
    "outcome",
    "duration_s",
    "commands",
    "gesture_commands",
    "key_commands",
    "panel_commands",
    "gripper_commands",
    *MEASURE_COLUMNS,
    "started_at",
    "ended_at",
    "synthetic",
    "folder",
    "measures_json",
)


def trial_folder_name(task: str, interface: str, trial: int) -> str:
    return f"{task}-{interface}-{trial}"


def _finite(t: float, what: str = "t") -> float:
    value = float(t)
    if not math.isfinite(value):
        raise DataError(f"{what} must be a finite number, got {t!r}")
    return value


def _wall(clock: Callable[[], float]) -> str:
    return datetime.fromtimestamp(clock(), UTC).isoformat(timespec="milliseconds")


@dataclass
class TrialSummary:
    """What ``trial.json`` holds (and a ``trials.csv`` row): one finished trial."""

    participant: str
    expertise: str
    task: str
    interface: str
    trial: int
    outcome: str
    duration_s: float
    commands: int
    commands_by_kind: dict[str, int]
    measures: dict[str, float]
    started_at: str
    ended_at: str
    first_command_t: float | None
    start_t: float
    end_t: float
    time_limit_s: float | None
    synthetic: bool
    format: str = TRIAL_FORMAT
    notes: dict[str, Any] = field(default_factory=dict)


class TrialRecorder:
    """Writes one trial's folder ``DIR/trials/<participant>/<task>-<interface>-<n>/``.

    Times ``t`` are the runner's clock in seconds (any origin, never going back, e.g. the
    simulation time); wall-clock times are added for the record.  ``synthetic=True`` marks
    every file as synthetic (``wovenskin study synthetic`` only).  An existing trial folder
    is refused unless ``overwrite`` (a rerun of the trial replaces it).
    """

    def __init__(
        self,
        study_dir: str | Path,
        participant: str,
        expertise: str,
        task: str,
        interface: str,
        trial: int,
        *,
        time_limit_s: float | None = None,
        synthetic: bool = False,
        overwrite: bool = False,
        wall_clock: Callable[[], float] = time.time,
    ) -> None:
        check_participant_id(participant)
        if int(trial) < 1:
            raise DataError(f"trial numbers start at 1, got {trial}")
        self.study_dir = Path(study_dir)
        self.participant, self.expertise = participant, expertise
        self.task, self.interface, self.trial = task, interface, int(trial)
        self.time_limit_s = time_limit_s
        self.synthetic = synthetic
        self._clock = wall_clock
        self.folder = (
            self.study_dir / TRIALS_DIR / participant / trial_folder_name(task, interface, trial)
        )
        if self.folder.exists():
            if not overwrite:
                raise OutputExistsError(self.folder, "a recorded trial")
            shutil.rmtree(self.folder)
        self.folder.mkdir(parents=True)
        extra = ("synthetic",) if synthetic else ()
        self._commands = LineLog(self.folder / COMMANDS_FILE, COMMAND_COLUMNS + extra)
        self._trajectory = LineLog(self.folder / TRAJECTORY_FILE, TRAJECTORY_COLUMNS + extra)
        self._events = LineLog(self.folder / EVENTS_FILE)
        self._mark = (1,) if synthetic else ()
        self.start_t: float | None = None
        self.first_command_t: float | None = None
        self.counts = dict.fromkeys(COMMAND_KINDS, 0)
        self.started_at = ""
        self.summary: TrialSummary | None = None

    # -- what a runner calls ---------------------------------------------------------
    def start(self, t: float) -> None:
        """The scene is reset and the trial begins (the timer starts at the first command)."""
        self._check_open()
        if self.start_t is not None:
            raise DataError(f"trial {self.folder.name} was already started")
        self.start_t = _finite(t)
        self.started_at = _wall(self._clock)
        self._event(self.start_t, {"event": "start", "wall": self.started_at})

    def command(self, t: float, source: str, name: str, kind: str) -> None:
        """One discrete input: a gesture activation, key press, panel operation or gripper
        toggle (``kind``); each counts as one command."""
        t = self._running(t)
        if kind not in COMMAND_KINDS:
            raise DataError(f"command kind {kind!r} is not one of {', '.join(COMMAND_KINDS)}")
        if self.first_command_t is None:
            self.first_command_t = t
            self._event(t, {"event": "first_command"})
        self.counts[kind] += 1
        self._commands.write_row((t, source, name, kind, *self._mark))

    def pose(self, t: float, tcp: Sequence[float], gripper: float) -> None:
        """The TCP pose ``(x, y, z, qw, qx, qy, qz)`` (metres, base frame) and the gripper
        (0 open .. 1 closed)."""
        t = self._running(t)
        values = [float(v) for v in tcp]
        if len(values) != 7:
            raise DataError(f"a TCP pose is x y z qw qx qy qz (7 numbers), got {len(values)}")
        values.append(float(gripper))
        if not all(math.isfinite(v) for v in values):
            raise DataError(f"a TCP pose or gripper value is not finite: {values}")
        self._trajectory.write_row((t, *values, *self._mark))

    def task_event(self, t: float, event: Mapping[str, Any]) -> None:
        """A task state change (e.g. ``{"event": "seated", "object": "cube"}``)."""
        t = self._running(t)
        if "t" in event:
            raise DataError("a task event's 't' is the recorder's: pass the time as t")
        self._event(t, dict(event))

    def elapsed(self, t: float) -> float:
        """Seconds the trial has run at ``t``: from the first command (0 before it)."""
        return 0.0 if self.first_command_t is None else float(t) - self.first_command_t

    def timed_out(self, t: float) -> bool:
        """Whether the time limit has passed at ``t`` (the runner then finishes "timeout")."""
        return self.time_limit_s is not None and self.elapsed(t) >= self.time_limit_s

    def finish(
        self, t: float, outcome: str, measures: Mapping[str, float] | None = None
    ) -> TrialSummary:
        """End the trial: write ``trial.json`` and its ``trials.csv`` row; returns it.

        The duration runs from the first command to ``t`` (from ``start`` when no command
        was given), capped at the time limit for a "timeout"."""
        t = self._running(t)
        if outcome not in OUTCOMES:
            raise DataError(f"outcome {outcome!r} is not one of {', '.join(OUTCOMES)}")
        clean = {str(k): _finite(v, f"measure {k!r}") for k, v in (measures or {}).items()}
        begin = self.first_command_t if self.first_command_t is not None else self.start_t
        duration = t - begin
        if outcome == "timeout" and self.time_limit_s is not None:
            duration = min(duration, self.time_limit_s)
        ended_at = _wall(self._clock)
        self._event(t, {"event": "finish", "outcome": outcome, "wall": ended_at})
        for log in (self._commands, self._trajectory, self._events):
            log.sync()
            log.close()
        summary = TrialSummary(
            participant=self.participant,
            expertise=self.expertise,
            task=self.task,
            interface=self.interface,
            trial=self.trial,
            outcome=outcome,
            duration_s=duration,
            commands=sum(self.counts.values()),
            commands_by_kind=dict(self.counts),
            measures=clean,
            started_at=self.started_at,
            ended_at=ended_at,
            first_command_t=self.first_command_t,
            start_t=self.start_t,
            end_t=t,
            time_limit_s=self.time_limit_s,
            synthetic=self.synthetic,
        )
        write_json(self.folder / SUMMARY_FILE, summary)
        _append_trial_row(self.study_dir / TRIALS_FILE, summary, self.folder)
        self.summary = summary
        return summary

    def close(self) -> None:
        """Close the logs without a summary (an abandoned trial stays incomplete)."""
        for log in (self._commands, self._trajectory, self._events):
            log.close()

    def __enter__(self) -> TrialRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- inside ------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self.summary is not None:
            raise DataError(f"trial {self.folder.name} is finished")

    def _running(self, t: float) -> float:
        self._check_open()
        if self.start_t is None:
            raise DataError(f"trial {self.folder.name} is not started: call start(t) first")
        return _finite(t)

    def _event(self, t: float, event: dict[str, Any]) -> None:
        record = {"t": t, **event}
        if self.synthetic:
            record["synthetic"] = True
        self._events.write_json(record)


def _append_trial_row(path: Path, s: TrialSummary, folder: Path) -> None:
    by_kind = [s.commands_by_kind.get(kind, 0) for kind in COMMAND_KINDS]
    measures = [s.measures.get(name) for name in MEASURE_COLUMNS]
    others = {k: v for k, v in s.measures.items() if k not in MEASURE_COLUMNS}
    log = LineLog(path, TRIALS_COLUMNS)
    try:
        log.write_row(
            (
                s.participant,
                s.expertise,
                s.task,
                s.interface,
                s.trial,
                s.outcome,
                s.duration_s,
                s.commands,
                *by_kind,
                *measures,
                s.started_at,
                s.ended_at,
                int(s.synthetic),
                folder.relative_to(path.parent).as_posix(),
                _json_cell(others),
            )
        )
        log.sync()
    finally:
        log.close()


def _json_cell(values: dict[str, float]) -> str:
    return dumps(values, sort_keys=True) if values else ""
