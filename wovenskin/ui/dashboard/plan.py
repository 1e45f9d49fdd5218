"""Where a participant stands in the study's counterbalanced plan, for the study panel.

:func:`next_step` reads the study (``DIR/study.toml``), derives every participant's run
order exactly as ``wovenskin study plan`` writes it to ``plan.csv``
(:func:`~wovenskin.study.counterbalance.study_plan`: Williams-design orders of tasks and
interfaces) and finds the participant's first condition with fewer trial folders than
the study's ``trials_per_condition``.  The page shows it and offers to choose that task and
interface, so trials run from the dashboard follow the counterbalanced order.
"""

from __future__ import annotations

from pathlib import Path

from wovenskin.errors import ConfigError
from wovenskin.study.counterbalance import study_plan
from wovenskin.study.definition import load_study
from wovenskin.ui.dashboard.trials import next_trial


def next_step(study_dir: str | Path | None, participant: object) -> dict | None:
    """The participant's next planned condition (``step``, ``steps``, ``task``,
    ``interface``, ``trial``, ``trials``), ``{"done": True, ...}`` when every condition
    has its trials, or None without a study or for an unknown participant."""
    if study_dir is None or not isinstance(participant, str) or not participant.strip():
        return None
    try:
        study = load_study(study_dir)
        person = study.participant(participant.strip())
    except ConfigError:
        return None
    steps = [s for s in study_plan(study) if s.participant == person.id]
    for step in steps:
        done = next_trial(Path(study_dir), person.id, step.task, step.interface) - 1
        if done < step.trials:
            return {
                "participant": person.id,
                "step": step.step,
                "steps": len(steps),
                "task": step.task,
                "interface": step.interface,
                "trial": done + 1,
                "trials": step.trials,
                "done": False,
            }
    return {"participant": person.id, "steps": len(steps), "done": True}
