"""Whole studies run by simulated operators, headless and faster than real time.

``simulate_study`` writes a study folder in the format of a real one (docs/study.md):
``study.toml`` (with ``simulated = true``), ``plan.csv``, every trial's logs, and
``operators.json`` with each simulated participant's drawn profile.  Each trial is a
fresh control session on the task's scene (the simulated TM5-900 with its gripper), the
arm in its initial pose, run as fast as this computer can: a
:class:`~wovenskin.operators.operator.SimulatedOperator` with a novice's or an expert's
profile (:mod:`wovenskin.operators.profiles`) works through the interface's hand; on the
skin it performs gestures that go through the whole pipeline: conditioning, the
recogniser, the arbiter, the mapping, the safety layer.  ``hands`` says whose people and
skins those gestures come from (one per participant): ``independent`` (the default,
:data:`HANDS`: :class:`~wovenskin.operators.independent_skin.IndependentSkin`, people and
skins of :mod:`wovenskin.independent`, strangers to the model) or ``sim``
(:class:`~wovenskin.operators.skin_hand.OperatorSkin`, the simulator the model was trained
on, kinder to the recogniser than a stranger's hand).  Trials are recorded by
:class:`~wovenskin.study.session.StudyTrials` as the dashboard records a person's, so
``wovenskin study report`` reads them as it reads a real study.

A pick-and-place trial moves one object, as the paper's does (the cube, the cylinder and
the prism in turn; ``objects="all"`` seats all three in every trial).

Ctrl-C stops a study at once, one trial at a time or in workers
(:mod:`~wovenskin.study.simulate_jobs`): the finished trials are kept, the ones cut short
removed, and :class:`StudyInterrupted` says how many were kept and where.
:func:`estimate_wall_s` says beforehand roughly how long a study takes.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.io import atomic_write_text
from wovenskin.operators.hands import KeyboardHand, PendantHand, SkinHand
from wovenskin.operators.independent_skin import IndependentSkin
from wovenskin.operators.operator import SimulatedOperator
from wovenskin.operators.profiles import OperatorProfile, sample_profile
from wovenskin.operators.script import ScriptRunner
from wovenskin.operators.skin_hand import OperatorSkin
from wovenskin.outputs import OutputExistsError, check_writable
from wovenskin.runtime.session import open_session
from wovenskin.study.counterbalance import write_plan
from wovenskin.study.definition import (
    HANDS_SOURCES,
    STUDY_FILE,
    TASKS,
    TIME_LIMIT_S,
    Participant,
    StudyDefinition,
    parse_study,
)
from wovenskin.study.recorder import (
    SUMMARY_FILE,
    TRIALS_DIR,
    TRIALS_FILE,
    TrialSummary,
    trial_folder_name,
)
from wovenskin.study.session import StudyTrials
from wovenskin.study.simulate_jobs import StopFlag, ctrl_c_stops, run_jobs
from wovenskin.study.synthetic import study_text
from wovenskin.tasks import make_task
from wovenskin.tasks.shapes import SHAPES

INTERFACES = ("skin", "keyboard", "pendant")
OBJECTS = "one"  # pick_place: one object a trial (the paper's), or "all"
HANDS = "independent"
"""Whose people and skins the operators touch the skin with by default (the one home of
``--hands``): ``independent`` (:mod:`wovenskin.independent`) or ``sim``."""
SKINS = {"independent": IndependentSkin, "sim": OperatorSkin}
"""The operator's skin of each kind of hands (:data:`~wovenskin.study.definition.HANDS_SOURCES`)."""
JOBS = 1  # trials run at once (worker processes)
OPERATORS_FILE = "operators.json"
PARTICIPANTS = 6
"""The default simulated operators: the paper's six, three novices and three experts."""
TRIALS_PER_CONDITION = 2
"""The default trials per task and interface: 72 trials for six operators (the paper ran
10, 360 trials: about 3.5 hours two at a time on a 2-core machine)."""
WALL_S_PER_TRIAL = {"skin": 39.0, "keyboard": 27.0, "pendant": 30.0}
SIM_S_PER_WALL_S = {"skin": 1.9, "keyboard": 2.4, "pendant": 2.4}
"""Wall seconds a trial took on average, and simulated seconds run per wall second, one
trial at a time on the shared 2-core machine (two simulated studies of 48 trials each,
2026-12-07, `--jobs 1`, a 120 s limit: skin 35.5 and 42.7 s, 2.1 and 1.7 x; keyboard 24.9
and 28.2 s, 2.6 and 2.3 x; the pendant, not measured then, is taken as the keyboard, which
its earlier figures matched): the basis of :func:`estimate_wall_s`."""


@dataclass(frozen=True)
class TrialRun:
    """One simulated trial's summary and what it cost."""

    summary: TrialSummary
    wall_s: float
    misread: int  # gestures the recogniser read as something else or nothing
    wrong_way: int  # moves started the wrong way
    gave_up: str  # why the operator gave up ("" if it did not)


class TrialStopped(Exception):
    """A trial was stopped (``stopped()`` turned true) before it ended; nothing was kept."""


class StudyInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a simulated study: ``kept`` of ``total`` trials are in ``folder``."""

    def __init__(self, folder: Path, kept: int, total: int) -> None:
        self.folder, self.kept, self.total = folder, kept, total
        super().__init__(self.message())

    def message(self) -> str:
        """One line: what was kept, and where."""
        if not self.kept:
            return f"no trial of {self.total} finished; {self.folder} holds the study's plan only"
        verb = "was" if self.kept == 1 else "were"
        return (
            f"{self.kept} of {self.total} trials {verb} written to {self.folder / TRIALS_DIR} "
            f"(listed in {self.folder / TRIALS_FILE}); the unfinished ones were discarded"
        )


def check_hands(hands: str) -> str:
    """``hands`` if simulated operators have such hands; one ConfigError line otherwise."""
    if hands not in HANDS_SOURCES:
        known = " or ".join(repr(h) for h in HANDS_SOURCES)
        raise ConfigError(f"hands must be {known}, got {hands!r}")
    return hands


def trial_objects(trial: int, objects: str) -> tuple[str, ...] | None:
    """The shapes of pick-and-place trial ``trial``: one, in turn, or all (``None``)."""
    if objects == "all":
        return None
    if objects != "one":
        raise ConfigError(f"objects must be 'one' or 'all', got {objects!r}")
    return (SHAPES[(int(trial) - 1) % len(SHAPES)].name,)


def run_trial(
    folder: str | Path,
    participant: Participant,
    profile: OperatorProfile,
    task_name: str,
    interface: str,
    trial: int,
    *,
    time_limit_s: float,
    objects: str = "one",
    model: str | Path | None = None,
    overwrite: bool = False,
    log: Callable[[str], None] | None = None,
    stopped: Callable[[], bool] | None = None,
    hands: str = HANDS,
) -> TrialRun:
    """Run trial ``trial`` of one condition in a fresh session; returns its summary.
    ``hands``: whose people and skins touch the skin (:data:`HANDS`).

    When ``stopped()`` turns true the session ends at its next step and, unless the trial
    had just ended, its unfinished folder is removed and :class:`TrialStopped` raised."""
    if interface not in INTERFACES:
        raise ConfigError(f"simulated operators use {', '.join(INTERFACES)}, not {interface!r}")
    skin_of_hands = SKINS[check_hands(hands)]
    started = time.perf_counter()
    options = {"objects": trial_objects(trial, objects)} if task_name == "pick_place" else {}
    task = make_task(task_name, **options)
    seed = profile.seed * 1000 + trial
    skin: Any = "none:speed=0"
    if interface == "skin":  # the participant's skin and hand; this trial's performances
        skin = skin_of_hands(profile.seed, gesture_seed=seed)
    hooks: list[Callable[[Any], None]] = []
    session = open_session(
        skin, "sim", model, task=task, on_tick=lambda s: hooks[0](s) if hooks else None
    )
    rng = np.random.default_rng([seed, 0x0A1])
    if interface == "skin":
        hand: Any = SkinHand(session, profile, rng, skin)
    elif interface == "keyboard":
        hand = KeyboardHand(session, profile, rng)
    else:
        hand = PendantHand(session, profile, rng)
    session.add_input(hand)
    block = StudyTrials(
        session, task, folder, participant.id, participant.expertise, interface, 1,
        time_limit_s=time_limit_s, first=trial, overwrite=overwrite,
    )  # fmt: skip
    operator = SimulatedOperator(session, task, hand, profile, rng, log=log)
    script = ScriptRunner()
    gave_up = [""]

    def on_tick(s: Any) -> None:
        block.on_tick(s)
        if block.runner is None:
            return
        if not script.running and script.error is None and not gave_up[0]:
            script.start(operator.run(trial), s.now)
        script.tick(s.now)
        if script.error is not None and not gave_up[0]:
            gave_up[0] = f"{type(script.error).__name__}: {script.error}"
            hand.release_now()
            block.end("give_up")

    hooks.append(on_tick)
    going_on = None if stopped is None else (lambda: not stopped())
    try:
        session.run(seconds=time_limit_s + 120.0, should_continue=going_on)
    finally:
        block.close()
        session.close()
    if not block.summaries and stopped is not None and stopped():
        _discard_unfinished(Path(folder), participant.id, task_name, interface, trial)
        raise TrialStopped(f"trial {trial} of {participant.id} {task_name}/{interface}")
    if not block.summaries:
        raise ConfigError(f"trial {trial} of {participant.id} {task_name}/{interface} did not end")
    misread = len(getattr(hand, "misread", []))
    wall_s = time.perf_counter() - started
    return TrialRun(block.summaries[0], wall_s, misread, hand.wrong, gave_up[0])


def estimate_wall_s(
    participants: int,
    trials: int,
    tasks: int,
    interfaces: tuple[str, ...],
    jobs: int,
    time_limit_s: float = TIME_LIMIT_S,
) -> float:
    """Roughly how long a simulated study takes, in wall seconds: each trial its
    interface's measured mean (:data:`WALL_S_PER_TRIAL`), or less when ``time_limit_s``
    ends it sooner (:data:`SIM_S_PER_WALL_S`), the trials spread over ``jobs`` processes,
    at most as many as there are cores."""
    per_condition = participants * trials * tasks
    total = 0.0
    for name in interfaces:  # an interface not measured: the slowest measured
        speed = SIM_S_PER_WALL_S.get(name, min(SIM_S_PER_WALL_S.values()))
        mean = WALL_S_PER_TRIAL.get(name, max(WALL_S_PER_TRIAL.values()))
        total += per_condition * min(mean, time_limit_s / speed)
    return total / max(1, min(int(jobs), os.cpu_count() or 1))


def simulated_participants(n: int, seed: int) -> list[tuple[Participant, OperatorProfile]]:
    """``n`` simulated participants, novices and experts in turn (3 + 3 for six, as the
    paper's), each with a profile drawn from ``seed`` and its number."""
    people = []
    for i in range(1, int(n) + 1):
        expertise = "novice" if i % 2 else "expert"
        pid = f"S{i:02d}"
        profile = sample_profile(pid, expertise, int(seed) * 100 + i)
        people.append((Participant(pid, expertise, notes="simulated operator"), profile))
    return people


SIMULATED_HEADER = (
    "# SIMULATED STUDY written by `wovenskin study simulate`: simulated operators on the "
    "simulated arm and skin, not people."
)


@dataclass(frozen=True)
class _Job:
    folder: str
    participant: Participant
    profile: OperatorProfile
    task: str
    interface: str
    trial: int
    time_limit_s: float
    objects: str
    model: str | None
    overwrite: bool
    hands: str = HANDS


def _run_job(job: _Job, stopped: Callable[[], bool] | None = None) -> TrialRun | None:
    try:
        return run_trial(
            job.folder, job.participant, job.profile, job.task, job.interface, job.trial,
            time_limit_s=job.time_limit_s, objects=job.objects, model=job.model,
            overwrite=job.overwrite, stopped=stopped, hands=job.hands,
        )  # fmt: skip
    except TrialStopped:
        return None


def _discard_unfinished(folder: Path, participant: str, task: str, interface: str, n: int) -> None:
    """Remove a trial's folder that holds no summary (a trial cut short)."""
    trial_dir = folder / TRIALS_DIR / participant / trial_folder_name(task, interface, n)
    if trial_dir.is_dir() and not (trial_dir / SUMMARY_FILE).exists():
        shutil.rmtree(trial_dir, ignore_errors=True)
        for empty in (trial_dir.parent, trial_dir.parent.parent):  # participant, trials/
            with contextlib.suppress(OSError):  # not empty: kept
                empty.rmdir()


def simulate_study(
    directory: str | Path,
    participants: int = PARTICIPANTS,
    seed: int = 0,
    trials: int = TRIALS_PER_CONDITION,
    *,
    tasks: tuple[str, ...] = TASKS,
    interfaces: tuple[str, ...] = INTERFACES,
    time_limit_s: float = TIME_LIMIT_S,
    objects: str = OBJECTS,
    model: str | Path | None = None,
    jobs: int = JOBS,
    overwrite: bool = False,
    progress: Callable[[TrialRun], None] | None = None,
    hands: str = HANDS,
) -> tuple[StudyDefinition, list[TrialRun]]:
    """Run a whole study of simulated operators into the new folder ``directory``
    (module docstring); ``jobs`` trials run at once in worker processes; ``hands``: whose
    people and skins touch the skin (:data:`HANDS`, recorded in ``study.toml``,
    ``operators.json`` and so in the report).

    Ctrl-C stops it within a step of every running trial: the trials cut short are
    removed, no further trial starts, and :class:`StudyInterrupted` says what was kept."""
    if participants < 1 or trials < 1:
        raise ConfigError("a simulated study needs at least one participant and one trial")
    for interface in interfaces:
        if interface not in INTERFACES:
            raise ConfigError(f"simulated operators use {', '.join(INTERFACES)}, not {interface!r}")
    check_hands(hands)
    folder = check_writable(directory, folder=True)  # refused now, not after the trials
    if folder.exists() and any(folder.iterdir()) and not overwrite:
        raise OutputExistsError(folder, "files")
    people = simulated_participants(participants, seed)
    study = StudyDefinition(
        name=f"simulated operators (seed {seed})",
        tasks=tuple(tasks),  # type: ignore[arg-type]
        interfaces=tuple(interfaces),  # type: ignore[arg-type]
        trials_per_condition=trials,
        time_limit_s=time_limit_s,
        questionnaires=(),
        simulated=True,
        hands=hands,  # type: ignore[arg-type]
        participants=tuple(p for p, _ in people),
    )
    flag = StopFlag()
    with ctrl_c_stops(flag):  # Ctrl-C from here on stops the study cleanly
        work = _write_study(folder, study, people, seed, objects, model, overwrite, hands)
        runs = run_jobs(work, _run_job, jobs, flag, progress)
    if flag():
        for job in work:
            _discard_unfinished(folder, job.participant.id, job.task, job.interface, job.trial)
        raise StudyInterrupted(folder, len(runs), len(work))
    return study, runs


def _write_study(
    folder: Path,
    study: StudyDefinition,
    people: list[tuple[Participant, OperatorProfile]],
    seed: int,
    objects: str,
    model: str | Path | None,
    overwrite: bool,
    hands: str,
) -> list[_Job]:
    """Write the study's files (definition, banner, operators, plan); its trials, in order."""
    folder.mkdir(parents=True, exist_ok=True)
    text = study_text(study, SIMULATED_HEADER)
    parse_study(text)
    atomic_write_text(folder / STUDY_FILE, text)
    atomic_write_text(
        folder / "SIMULATED.md",
        "Every trial in this folder was run by a simulated operator (wovenskin.operators) on "
        "the simulated arm and skin by `wovenskin study simulate`; no person took part. "
        f"On the skin they touched with the {HANDS_SOURCES[hands]} (hands = {hands}).\n",
    )
    info = {
        "simulated": True,
        "seed": seed,
        "objects": objects,
        "model": str(model) if model is not None else "shipped",
        "hands": hands,
        "hands_source": HANDS_SOURCES[hands],
        "operators": [profile.to_dict() for _, profile in people],
    }
    atomic_write_text(folder / OPERATORS_FILE, json.dumps(info, indent=2) + "\n")
    _, steps = write_plan(folder, study)
    profiles = {p.id: profile for p, profile in people}
    by_id = {p.id: p for p, _ in people}
    return [
        _Job(
            str(folder),
            by_id[step.participant],
            profiles[step.participant],
            step.task,
            step.interface,
            n,
            study.time_limit_s,
            objects,
            None if model is None else str(model),
            overwrite,
            hands,
        )  # fmt: skip
        for step in steps
        for n in range(1, step.trials + 1)
    ]
