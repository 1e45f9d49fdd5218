"""The experimenter's study panel: trials run from the page into a study folder.

:class:`StudyPanel` holds the study folder (``DIR/study.toml`` from ``wovenskin study
init``; participants from ``wovenskin study add-participant``) and at most one running
trial: a :class:`~wovenskin.study.runner.TrialRunner` over the session, its task and a
:class:`~wovenskin.study.recorder.TrialRecorder` writing
``DIR/trials/<participant>/<task>-<interface>-<n>/``, ``n`` the next free trial number.
Starting a trial resets the task's scene from the seed ``n`` (the trial number: trial 2
of every participant starts from the same placements).  The experimenter starts a trial
and ends it (success, give up, abort); it also ends by
itself when the task succeeds or fails or the study's time limit passes.  Everything runs
on the dashboard's session thread.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from wovenskin.errors import ConfigError
from wovenskin.study.definition import load_study
from wovenskin.study.recorder import TRIALS_DIR, TrialRecorder, trial_folder_name
from wovenskin.study.runner import TrialRunner

ENDINGS = {"success": "success", "give_up": "give_up", "abort": "aborted"}


def next_trial(study_dir: Path, participant: str, task: str, interface: str) -> int:
    """The first trial number without a folder for this participant, task and interface."""
    n = 1
    while (study_dir / TRIALS_DIR / participant / trial_folder_name(task, interface, n)).exists():
        n += 1
    return n


class StudyPanel:
    """The study folder and the running trial (see the module docstring)."""

    def __init__(self, study_dir: str | Path | None) -> None:
        self.study_dir = None if study_dir is None else Path(study_dir)
        self.trial: TrialRunner | None = None
        self.recorder: TrialRecorder | None = None
        self.last: dict | None = None  # the last finished trial, for the page

    @property
    def running(self) -> bool:
        return self.trial is not None

    def start(self, session: Any, task: Any, interface: str, participant: object, t: float) -> str:
        """Start the next trial of ``participant`` on ``task`` with ``interface``; returns
        a line for the page.  One :class:`ConfigError` line when it cannot start."""
        if self.study_dir is None:
            raise ConfigError("no study folder: start the dashboard with one (--study DIR)")
        if self.trial is not None:
            raise ConfigError("a trial is running: end it first")
        if task is None:
            raise ConfigError("choose a task first")
        if not isinstance(participant, str) or not participant.strip():
            raise ConfigError("enter the participant's id first")
        study = load_study(self.study_dir)
        person = study.participant(participant.strip())
        n = next_trial(self.study_dir, person.id, task.name, interface)
        recorder = TrialRecorder(
            self.study_dir, person.id, person.expertise, task.name, interface, n,
            time_limit_s=study.time_limit_s,
        )  # fmt: skip
        try:
            task.reset(n)
            session.gripper_was_opened()  # the reset opened it: a toggle closes it
            runner = TrialRunner(session, task, recorder, time_limit_s=study.time_limit_s)
            runner.start(t)
        except Exception:
            recorder.close()
            raise
        self.trial, self.recorder, self.last = runner, recorder, None
        return f"trial {n} of {person.id}: {task.name} with the {interface} started"

    def tick(self, t: float) -> str | None:
        """Advance the running trial; a line for the page when it ended by itself."""
        if self.trial is None:
            return None
        outcome = self.trial.tick(t)
        return None if outcome is None else self._end(t, outcome)

    def end(self, t: float, how: str) -> str:
        """End the running trial as the experimenter says: success, give_up or abort."""
        if how not in ENDINGS:
            raise ConfigError(f"unknown trial ending {how!r}: use success, give_up or abort")
        if self.trial is None:
            raise ConfigError("no trial is running")
        return self._end(t, ENDINGS[how])

    def _end(self, t: float, outcome: str) -> str:
        trial, recorder = self.trial, self.recorder
        assert trial is not None and recorder is not None
        self.trial = self.recorder = None
        if recorder.summary is None:  # the runner may have finished it itself
            trial.finish(t, outcome)
        summary = recorder.summary
        self.last = {
            "folder": str(recorder.folder),
            "outcome": summary.outcome if summary is not None else outcome,
            "duration_s": None if summary is None else round(summary.duration_s, 2),
            "commands": None if summary is None else summary.commands,
        }
        return f"trial ended: {self.last['outcome']} ({recorder.folder.name})"

    def abandon(self, t: float) -> None:
        """Abort a running trial (the session is closing or switching)."""
        if self.trial is not None:
            self._end(t, "aborted")

    def part(self, t: float) -> dict:
        """The snapshot's share: folder, running trial, timer, last result."""
        out: dict[str, Any] = {
            "folder": None if self.study_dir is None else str(self.study_dir),
            "running": self.trial is not None,
            "last": self.last,
        }
        if self.trial is not None and self.recorder is not None:
            rec = self.recorder
            out.update(
                participant=rec.participant, task=rec.task, interface=rec.interface,
                trial=rec.trial, elapsed_s=round(float(self.trial.elapsed(t)), 2),
                time_limit_s=rec.time_limit_s, started=rec.first_command_t is not None,
            )  # fmt: skip
        return out
