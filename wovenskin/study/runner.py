"""Running one trial on a live session: commands, TCP poses and task changes into a TrialRecorder.

A :class:`TrialRunner` joins a control session (anything with ``command_log``, ``state.robot``
and ``gripper_closed``, e.g. :class:`~wovenskin.control.session.ControlSession`), a task
scene (:class:`~wovenskin.tasks.base.Task`) and a :class:`~wovenskin.study.recorder.TrialRecorder`.
The caller (terminal view, dashboard) calls :meth:`TrialRunner.start` once the scene is
reset, :meth:`TrialRunner.tick` from the session's tick callback and
:meth:`TrialRunner.finish` with the outcome; times are the session clock.  ``tick``
records every new command of the session's log, the TCP pose and gripper every
``pose_every_s``, and a ``task`` event whenever a discrete measure of the task changes
(an object seated, particles delivered or spilled, success or failure), checked at the
same pace; it returns the outcome the task has reached, if any.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields, is_dataclass
from typing import Any

from wovenskin.control.session_inputs import CommandRecord
from wovenskin.errors import ConfigError
from wovenskin.study.recorder import OUTCOMES, TrialRecorder, TrialSummary
from wovenskin.tasks.base import Task

VERDICTS = ("success", "failed", "timeout")
"""What :meth:`TrialRunner.tick` may return: the task's own ends and the time limit."""

# Source -> command kind (docs/study.md): a key press, a panel operation, a gesture.
SOURCE_KINDS = {"skin": "gesture", "keyboard": "key", "pendant": "panel"}
# The state fields the two tasks measure, under the names trials.csv gives them columns.
MEASURE_NAMES = {
    "seated": "objects_seated",
    "total": "objects_total",
    "delivered": "particles_delivered",
    "spilled": "particles_spilled",
    "in_cup": "particles_in_cup",
    "airborne": "particles_airborne",
}
PARTICLE_FIELDS = ("delivered", "spilled", "in_cup", "airborne")


def command_kind(record: CommandRecord) -> str:
    """The study's kind of a session command: ``gripper`` for a gripper operation, else
    by source (``skin`` -> ``gesture``, ``keyboard`` -> ``key``, anything else a panel)."""
    if record.kind == "gripper":
        return "gripper"
    if record.kind == "gesture":
        return "gesture"
    return SOURCE_KINDS.get(record.source, "panel")


def task_measures(state: Any) -> dict[str, float]:
    """The numeric measures of a task's state dataclass, under study names.

    A pick-and-place state gives ``objects_seated`` / ``objects_total``; a pouring state
    ``particles_delivered``, ``particles_spilled``, ``particles_in_cup``,
    ``particles_airborne`` and ``particles_total``; other int, float or bool fields keep
    their names (arrays and nested values are left out)."""
    if not is_dataclass(state):
        raise ConfigError(f"a task state must be a dataclass, got {type(state).__name__}")
    values = {f.name: getattr(state, f.name) for f in fields(state)}
    particles = any(name in values for name in PARTICLE_FIELDS)
    out: dict[str, float] = {}
    for name, value in values.items():
        if not isinstance(value, int | float | bool):
            continue
        if name == "total":
            key = "particles_total" if particles else "objects_total"
        else:
            key = MEASURE_NAMES.get(name, name)
        out[key] = float(value)
    return out


def task_signature(task: Task) -> dict[str, Any]:
    """The discrete part of a task's state: counts and verdicts (what a task event reports),
    with per-object flags for objects that have a name (``seated.cube``)."""
    state = task.state()
    out: dict[str, Any] = {"succeeded": bool(task.succeeded()), "failed": bool(task.failed())}
    for f in fields(state):
        value = getattr(state, f.name)
        if isinstance(value, bool | int) and f.name != "total":
            out[f.name] = value
        elif isinstance(value, tuple):
            for item in value:
                if is_dataclass(item) and hasattr(item, "name"):
                    for sub in fields(item):
                        flag = getattr(item, sub.name)
                        if isinstance(flag, bool):
                            out[f"{sub.name}.{item.name}"] = flag
    return out


class TrialRunner:
    """One trial of a task on a running session, logged by ``recorder`` (module docstring).

    ``time_limit_s`` (default: the recorder's) ends the trial "timeout" that long after
    the first command; ``pose_every_s`` is the pace of poses and task checks.  Commands
    already in the session's log when the runner is made are not the trial's.
    """

    def __init__(
        self,
        session: Any,
        task: Task,
        recorder: TrialRecorder,
        *,
        time_limit_s: float | None = None,
        pose_every_s: float = 0.05,
    ) -> None:
        if not pose_every_s > 0:
            raise ConfigError(f"pose_every_s must be positive, got {pose_every_s}")
        limit = recorder.time_limit_s if time_limit_s is None else time_limit_s
        if limit is not None and not limit > 0:
            raise ConfigError(f"the time limit must be positive, got {limit}")
        self.session = session
        self.task = task
        self.recorder = recorder
        self.time_limit_s = limit
        self.pose_every_s = float(pose_every_s)
        self._seen = len(session.command_log)
        self._next_check: float | None = None
        self._signature: dict[str, Any] = {}
        self._last_sample: float | None = None
        self.verdict: str | None = None
        self.summary: TrialSummary | None = None

    @property
    def started(self) -> bool:
        return self._next_check is not None

    def start(self, t: float) -> None:
        """The scene is reset: the trial begins at ``t`` (its commands count from now)."""
        self.recorder.start(t)
        self._seen = len(self.session.command_log)
        self._signature = task_signature(self.task)
        self.recorder.task_event(t, {"event": "task", "state": dict(self._signature)})
        self._next_check = float(t)
        self._sample(float(t))

    def tick(self, t: float) -> str | None:
        """Record what happened up to ``t``; returns ``success``, ``failed`` (the task can
        no longer succeed), ``timeout`` or ``None`` while the trial goes on."""
        if self._next_check is None:
            raise ConfigError("the trial is not started: call start(t) first")
        if self.summary is not None:
            return self.verdict
        t = float(t)
        log = self.session.command_log
        for record in log[self._seen :]:
            self.recorder.command(record.t, record.source, record.name, command_kind(record))
        self._seen = len(log)
        if t >= self._next_check:
            self._sample(t)
        if self.verdict is None and self._timed_out(t):
            self.verdict = "timeout"
        return self.verdict

    def elapsed(self, t: float) -> float:
        """Seconds the trial has run at ``t``: from its first command (0 before it)."""
        return self.recorder.elapsed(t)

    def finish(
        self, t: float, outcome: str, extra: Mapping[str, float] | None = None
    ) -> TrialSummary:
        """End the trial with ``outcome`` (one of the recorder's: success, give_up,
        timeout, aborted, failed); the measures come from ``task.state()`` (and ``extra``)."""
        if outcome not in OUTCOMES:
            raise ConfigError(f"outcome {outcome!r} is not one of {', '.join(OUTCOMES)}")
        if self._next_check is not None and self.summary is None:
            self.tick(t)  # the last commands
            if self._last_sample != float(t):
                self._sample(float(t))  # and the final state
        measures = {**task_measures(self.task.state()), **dict(extra or {})}
        self.summary = self.recorder.finish(t, outcome, measures)
        return self.summary

    def close(self) -> None:
        """Close the logs; a trial not finished stays incomplete (abandoned)."""
        self.recorder.close()

    # -- inside

    def _timed_out(self, t: float) -> bool:
        limit = self.time_limit_s
        started = self.recorder.first_command_t is not None
        return limit is not None and started and self.elapsed(t) >= limit

    def _sample(self, t: float) -> None:
        """The pose, and the task's state: an event when it changed, and the verdict."""
        assert self._next_check is not None
        self._last_sample = t
        while self._next_check <= t:
            self._next_check += self.pose_every_s
        robot = self.session.state.robot
        if robot is not None:
            tcp = (*robot.tcp.position, *robot.tcp.quat)
            closed = robot.gripper.closed if robot.gripper is not None else None
            closed = self.session.gripper_closed if closed is None else closed
            self.recorder.pose(t, tcp, 1.0 if closed else 0.0)
        signature = task_signature(self.task)
        changed = {k: v for k, v in signature.items() if self._signature.get(k) != v}
        if changed:
            self._signature = signature
            self.recorder.task_event(t, {"event": "task", "changed": changed})
        if self.verdict is None:
            if signature["succeeded"]:
                self.verdict = "success"
            elif signature["failed"]:
                self.verdict = "failed"
