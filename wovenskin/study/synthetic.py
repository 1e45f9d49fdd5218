"""Synthetic studies, labelled as such everywhere, to demonstrate and test the report.

``synthetic_study`` writes a new study folder whose ``study.toml`` says ``synthetic = true``
and whose every trial goes through :class:`~wovenskin.study.recorder.TrialRecorder` with
``synthetic=True``: the same files a real study has, each marked.  The numbers are drawn
from made-up distributions (the interface means below are placeholders, not the paper's
results and not measurements); they exist so the report has something to show.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.io import atomic_write_text
from wovenskin.outputs import OutputExistsError, check_writable
from wovenskin.study.counterbalance import write_plan
from wovenskin.study.definition import (
    STUDY_FILE,
    Participant,
    StudyDefinition,
    parse_study,
    participant_block,
)
from wovenskin.study.questionnaires import QuestionnaireRow, record_questionnaire
from wovenskin.study.recorder import TrialRecorder

# Placeholder means (seconds, commands) per task and interface; invented for the demo.
_TIME = {"skin": 45.0, "skin_registered": 42.0, "keyboard": 70.0, "pendant": 90.0}
_COMMANDS = {"skin": 14.0, "skin_registered": 13.0, "keyboard": 30.0, "pendant": 38.0}
_TASK_SCALE = {"pick_place": 1.3, "pour": 1.0}
_KIND = {"skin": "gesture", "skin_registered": "gesture", "keyboard": "key", "pendant": "panel"}
_EXPERT = 0.8  # experts are faster in this made-up world
_EPOCH = 946684800.0  # 2000-01-01 UTC: synthetic wall times are visibly not real ones
POSE_RATE_HZ = 5.0
PARTICIPANTS = 6  # the default synthetic participants, novice and expert in turn
TRIALS_PER_CONDITION = 2  # the default trials per task and interface


SYNTHETIC_HEADER = (
    "# SYNTHETIC STUDY written by `wovenskin study synthetic`: nothing here was measured."
)


def study_text(study: StudyDefinition, header: str = SYNTHETIC_HEADER) -> str:
    """The ``study.toml`` of a generated study (``header``: its first comment line)."""
    lines = [
        header,
        f'name = "{study.name}"',
        f"synthetic = {str(study.synthetic).lower()}",
        f"simulated = {str(study.simulated).lower()}",
        f"tasks = {list(study.tasks)}".replace("'", '"'),
        f"interfaces = {list(study.interfaces)}".replace("'", '"'),
        f"trials_per_condition = {study.trials_per_condition}",
        f"time_limit_s = {study.time_limit_s!r}",
        f"questionnaires = {list(study.questionnaires)}".replace("'", '"'),
        *([f'hands = "{study.hands}"'] if study.hands else []),
        "",
    ]
    return "\n".join(lines) + "\n".join(participant_block(p) + "\n" for p in study.participants)


def _trial(
    rec: TrialRecorder,
    rng: np.random.Generator,
    task: str,
    time_s: float,
    n_commands: int,
    limit: float,
    clock: list[float],
) -> None:
    kind = _KIND.get(rec.interface, "gesture")
    rec.start(0.0)
    t0 = float(rng.uniform(1.0, 3.0))  # the participant's first command
    duration = min(time_s, limit)
    times = np.sort(rng.uniform(t0, t0 + duration, max(n_commands - 1, 0)))
    times = np.concatenate([[t0], times])
    grips = set(rng.choice(len(times), size=min(2, len(times)), replace=False).tolist())
    # A path from the start over the object to the goal, wobblier for slower interfaces.
    start, goal = np.array([0.35, -0.15, 0.35]), np.array([0.45, 0.2, 0.3])
    via = np.array([0.5, -0.05, 0.2]) + rng.normal(0, 0.02, 3)
    samples = int(duration * POSE_RATE_HZ) + 1
    s = np.linspace(0, 1, samples)
    path = np.where(
        (s < 0.5)[:, None],
        start + (via - start) * (2 * s)[:, None],
        via + (goal - via) * (2 * s - 1)[:, None],
    )
    path += (
        np.cumsum(rng.normal(0, 0.002 * duration / 40, path.shape), axis=0)
        * np.sin(math.pi * s)[:, None]
    )
    gripper = 0.0
    pose_times = t0 + s * duration
    events = sorted(
        [(t, "command", i) for i, t in enumerate(times)]
        + [(t, "pose", i) for i, t in enumerate(pose_times)]
    )
    for t, what, i in events:
        if what == "command":
            if i in grips:
                gripper = 1.0 - gripper
                rec.command(t, "synthetic", "gripper", "gripper")
            else:
                rec.command(t, "synthetic", f"{kind}_{int(rng.integers(0, 6))}", kind)
        else:
            rec.pose(t, (*path[i], 1.0, 0.0, 0.0, 0.0), gripper)
    end = t0 + duration
    timed_out = time_s >= limit
    outcome = "timeout" if timed_out else ("success" if rng.random() < 0.9 else "give_up")
    if task == "pour":
        spilled = 0 if outcome == "success" else int(rng.integers(1, 15))
        delivered = 100 - spilled - (0 if outcome == "success" else int(rng.integers(0, 30)))
        measures = {
            "particles_delivered": delivered,
            "particles_spilled": spilled,
            "particles_total": 100,
        }
        rec.task_event(end, {"event": "poured", "delivered": delivered, "spilled": spilled})
    else:
        seated = 3 if outcome == "success" else int(rng.integers(0, 3))
        measures = {"objects_seated": seated, "objects_total": 3}
        rec.task_event(end, {"event": "seated", "objects": seated})
    clock[0] += end  # the synthetic wall clock moves on by the trial's length
    rec.finish(end, outcome, measures)


def synthetic_study(
    directory: str | Path,
    participants: int = PARTICIPANTS,
    seed: int = 0,
    trials: int = TRIALS_PER_CONDITION,
    overwrite: bool = False,
) -> StudyDefinition:
    """Write a synthetic study of ``participants`` people (novice and expert in turn) to
    the new folder ``directory``: study.toml, plan.csv, every trial, questionnaires."""
    if participants < 1 or trials < 1:
        raise ConfigError("a synthetic study needs at least one participant and one trial")
    folder = check_writable(directory, folder=True)
    if folder.exists() and any(folder.iterdir()) and not overwrite:
        raise OutputExistsError(folder, "files")
    people = tuple(
        Participant(f"S{i:02d}", "novice" if i % 2 else "expert", notes="synthetic")
        for i in range(1, participants + 1)
    )
    study = StudyDefinition(
        name=f"synthetic demo (seed {seed})",
        trials_per_condition=trials,
        time_limit_s=180.0,
        questionnaires=("nasa_tlx", "sus"),
        synthetic=True,
        participants=people,
    )
    folder.mkdir(parents=True, exist_ok=True)
    text = study_text(study)
    parse_study(text)  # what we write reads back
    atomic_write_text(folder / STUDY_FILE, text)
    atomic_write_text(
        folder / "SYNTHETIC.md",
        "Everything in this folder is synthetic, "
        "written by `wovenskin study synthetic`; nothing was measured.\n",
    )
    _, steps = write_plan(folder, study)
    rng = np.random.default_rng(seed)
    skill = {p.id: float(rng.lognormal(0, 0.15)) for p in people}
    clock = [_EPOCH]
    for step in steps:
        base = _TIME[step.interface] * _TASK_SCALE[step.task] * skill[step.participant]
        base *= _EXPERT if step.expertise == "expert" else 1.0
        for n in range(1, step.trials + 1):
            time_s = base * 0.9 ** (n - 1) * float(rng.lognormal(0, 0.2))
            n_commands = max(
                1, int(rng.poisson(_COMMANDS[step.interface] * _TASK_SCALE[step.task]))
            )
            rec = TrialRecorder(
                folder,
                step.participant,
                step.expertise,
                step.task,
                step.interface,
                n,
                time_limit_s=study.time_limit_s,
                synthetic=True,
                overwrite=overwrite,
                wall_clock=lambda: clock[0],
            )
            _trial(rec, rng, step.task, time_s, n_commands, study.time_limit_s, clock)
            clock[0] += 60.0  # a minute between trials
    for p in people:
        for interface in study.interfaces:
            load = {"skin": 30, "skin_registered": 30, "keyboard": 45, "pendant": 55}[interface]
            tlx = tuple(float(np.clip(rng.normal(load, 12), 0, 100).round()) for _ in range(6))
            good = {"skin": 4.2, "skin_registered": 4.2, "keyboard": 3.5, "pendant": 3.0}[interface]
            sus = tuple(
                int(np.clip(round(rng.normal(good if i % 2 == 0 else 6 - good, 0.7)), 1, 5))
                for i in range(10)
            )
            record_questionnaire(
                folder, QuestionnaireRow(p.id, p.expertise, interface, "", tlx, sus, synthetic=True)
            )
    return study
