"""A participant's block of trials on one live session: scene resets, runners and the
experimenter's keys (``wovenskin study run``).

:class:`StudyTrials` runs ``trials`` trials of one task with one interface, one after the
other, on a running control session whose scene is the task's: each trial resets the
scene with :func:`trial_seed` (the same participant, task and trial number, the same
scene), stops any held motion, opens the gripper, and records through a
:class:`~wovenskin.study.runner.TrialRunner` from the session's tick callback
(:meth:`StudyTrials.on_tick`).  A trial ends by itself on success, on the task's failure
or at the time limit, or by the experimenter's key (:data:`EXPERIMENTER_KEYS`: ``y``
success, ``n`` give up, ``x`` abort); after the last trial the session is asked to quit.
"""

from __future__ import annotations

import zlib
from pathlib import Path
from typing import Any

from wovenskin.control.session_inputs import InputEvent
from wovenskin.errors import ConfigError
from wovenskin.study.recorder import TrialRecorder, TrialSummary
from wovenskin.study.runner import TrialRunner
from wovenskin.tasks.base import Task

EXPERIMENTER_KEYS = {"y": "success", "n": "give_up", "x": "aborted"}
"""The experimenter's keys and the outcome each gives the running trial."""


def trial_seed(participant: str, task: str, trial: int) -> int:
    """The scene seed of a trial: a stable hash of participant, task and trial number."""
    return zlib.crc32(f"{participant}/{task}/{int(trial)}".encode()) & 0x7FFFFFFF


class StudyTrials:
    """Trials ``first`` .. ``first + trials - 1`` of a participant (module docstring)."""

    def __init__(
        self,
        session: Any,
        task: Task,
        study_dir: str | Path,
        participant: str,
        expertise: str,
        interface: str,
        trials: int,
        *,
        time_limit_s: float | None = None,
        first: int = 1,
        overwrite: bool = False,
        pose_every_s: float = 0.05,
    ) -> None:
        if int(trials) < 1 or int(first) < 1:
            raise ConfigError(f"need at least one trial, numbered from 1 (got {trials}, {first})")
        self.session, self.task = session, task
        self.study_dir = Path(study_dir)
        self.participant, self.expertise, self.interface = participant, expertise, interface
        self.numbers = list(range(int(first), int(first) + int(trials)))
        self.time_limit_s = time_limit_s
        self.overwrite = overwrite
        self.pose_every_s = pose_every_s
        self.runner: TrialRunner | None = None
        self.trial: int | None = None
        self.summaries: list[TrialSummary] = []

    @property
    def done(self) -> bool:
        return len(self.summaries) == len(self.numbers)

    def begin(self, t: float | None = None) -> None:
        """Reset the scene and start the next trial (at session time ``t``)."""
        if self.done:
            raise ConfigError("every trial of this block has run")
        number = self.numbers[len(self.summaries)]
        self.session.apply_input(InputEvent("release", "", "study", counts=False))
        self.session.apply_input(InputEvent("gripper", "open", "study", counts=False))
        self.task.reset(trial_seed(self.participant, self.task.name, number))
        recorder = TrialRecorder(
            self.study_dir, self.participant, self.expertise, self.task.name,
            self.interface, number, time_limit_s=self.time_limit_s, overwrite=self.overwrite,
        )  # fmt: skip
        self.runner = TrialRunner(self.session, self.task, recorder, pose_every_s=self.pose_every_s)
        self.trial = number
        self.runner.start(self.session.now if t is None else t)
        self._say(f"trial {number} ({len(self.summaries) + 1}/{len(self.numbers)}) begins")

    def on_tick(self, session: Any) -> None:
        """The session's tick callback: the first trial begins at the first tick; record,
        and end the trial when it has ended."""
        if self.runner is None and not self.summaries and not self.done:
            self.begin(session.now)
        if self.runner is None:
            return
        verdict = self.runner.tick(session.now)
        if verdict is not None:
            self.end(verdict)

    def keys(self, text: str) -> str:
        """Apply the experimenter's keys in ``text``; returns the other characters."""
        return "".join(char for char in text if not self.key(char))

    def key(self, key: str) -> bool:
        """An experimenter's key; returns whether it was one (then the trial ends)."""
        outcome = EXPERIMENTER_KEYS.get(key.lower())
        if outcome is None or self.runner is None:
            return outcome is not None
        self.end(outcome)
        return True

    def end(self, outcome: str) -> TrialSummary:
        """Finish the running trial with ``outcome``; start the next, or ask the session
        to quit after the last."""
        if self.runner is None:
            raise ConfigError("no trial is running")
        runner, self.runner = self.runner, None
        summary = runner.finish(self.session.now, outcome)
        self.summaries.append(summary)
        self._say(
            f"trial {summary.trial}: {outcome}, {summary.duration_s:.1f} s, "
            f"{summary.commands} commands"
        )
        if self.done:
            self.session.request_quit(f"all {len(self.numbers)} trials done")
        else:
            self.begin()
        return summary

    def status(self) -> str:
        """One line for a view: the trial, its time and commands, the keys."""
        if self.runner is None:
            return f"{len(self.summaries)}/{len(self.numbers)} trials done"
        keys = "  ".join(f"{k}: {v.replace('_', ' ')}" for k, v in EXPERIMENTER_KEYS.items())
        if self.runner.recorder.first_command_t is None:
            clock = "waiting for the first command"
        else:
            clock = f"{self.runner.elapsed(self.session.now):6.1f} s"
        place = f"{len(self.summaries) + 1}/{len(self.numbers)}"
        return f"trial {self.trial} ({place})  {clock}   {keys}"

    def close(self) -> None:
        """Close a trial still running without a summary (it stays incomplete)."""
        if self.runner is not None:
            self.runner.close()
            self.runner = None

    def _say(self, text: str) -> None:
        messages = getattr(getattr(self.session, "state", None), "messages", None)
        if messages is not None:
            messages.append(f"{self.session.now:8.2f} s  {text}")
