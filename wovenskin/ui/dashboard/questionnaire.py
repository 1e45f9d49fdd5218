"""The questionnaires a participant answers in the page after a condition: NASA-TLX and SUS.

:func:`forms` is what the page shows for the study's ``questionnaires`` (``study.toml``):
the six raw NASA-TLX subscales (0-100 in steps of 5; *performance* from 0 = perfect to
100 = failure, as on the official form) and the ten SUS statements (1 = strongly
disagree .. 5 = strongly agree), worded as the published instruments are, since changing
the wording changes what they measure.  :func:`record_answers` checks a page's answers
and appends them, scored, to ``DIR/questionnaires.csv``
(:func:`~wovenskin.study.questionnaires.record_questionnaire`), where ``wovenskin study
report`` reads them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from wovenskin.errors import ConfigError, DataError
from wovenskin.study.definition import INTERFACES, TASKS, load_study
from wovenskin.study.questionnaires import TLX_SCALES, QuestionnaireRow, record_questionnaire

# Hart & Staveland (1988), the NASA-TLX rating scale definitions: (subscale, label, question)
TLX_ITEMS: tuple[tuple[str, str, str], ...] = (
    ("mental", "Mental demand", "How mentally demanding was the task?"),
    ("physical", "Physical demand", "How physically demanding was the task?"),
    ("temporal", "Temporal demand", "How hurried or rushed was the pace of the task?"),
    (
        "performance",
        "Performance",
        "How successful were you in accomplishing what you were asked to do? "
        "(0 = perfect, 100 = failure)",
    ),
    (
        "effort",
        "Effort",
        "How hard did you have to work to accomplish your level of performance?",
    ),
    (
        "frustration",
        "Frustration",
        "How insecure, discouraged, irritated, stressed, and annoyed were you?",
    ),
)
assert tuple(item[0] for item in TLX_ITEMS) == TLX_SCALES

# Brooke (1996), the System Usability Scale's ten statements, in order.
SUS_ITEMS: tuple[str, ...] = (
    "I think that I would like to use this system frequently.",
    "I found the system unnecessarily complex.",
    "I thought the system was easy to use.",
    "I think that I would need the support of a technical person to be able to use this system.",
    "I found the various functions in this system were well integrated.",
    "I thought there was too much inconsistency in this system.",
    "I would imagine that most people would learn to use this system very quickly.",
    "I found the system very cumbersome to use.",
    "I felt very confident using the system.",
    "I needed to learn a lot of things before I could get going with this system.",
)


def forms(study_dir: str | Path | None) -> dict[str, Any]:
    """The questionnaires the study asks for, as the page draws them (none without a
    study folder or a readable ``study.toml``)."""
    if study_dir is None:
        return {}
    try:
        wanted = load_study(study_dir).questionnaires
    except ConfigError:
        return {}
    out: dict[str, Any] = {}
    if "nasa_tlx" in wanted:
        out["nasa_tlx"] = [{"key": k, "label": label, "question": q} for k, label, q in TLX_ITEMS]
    if "sus" in wanted:
        out["sus"] = list(SUS_ITEMS)
    return out


def _answers(value: object, n: int, what: str) -> tuple[float, ...] | None:
    if value is None:
        return None
    if not isinstance(value, list | tuple) or len(value) != n:
        raise DataError(f"{what}: {n} answers expected")
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        raise DataError(f"{what}: answers must be numbers")
    return tuple(float(v) for v in value)


def record_answers(study_dir: str | Path | None, message: dict) -> str:
    """Check the page's answers (``participant``, ``task``, ``interface``, ``tlx``: six
    0-100 or null, ``sus``: ten 1-5 or null) and append them to the study's
    ``questionnaires.csv``; returns a line for the page.  A bad answer or an unknown
    participant is one :class:`~wovenskin.errors.WovenskinError` line; nothing is written."""
    if study_dir is None:
        raise ConfigError("no study folder: start the dashboard with one (--study DIR)")
    study = load_study(study_dir)
    participant = study.participant(str(message.get("participant") or "").strip())
    task, interface = message.get("task") or "", message.get("interface")
    if task not in ("", *TASKS):
        raise DataError(f"unknown task {task!r}")
    if interface not in INTERFACES:
        raise DataError(f"unknown interface {interface!r}")
    tlx = _answers(message.get("tlx"), len(TLX_SCALES), "NASA-TLX")
    sus = _answers(message.get("sus"), len(SUS_ITEMS), "SUS")
    if sus is not None and any(v != int(v) for v in sus):
        raise DataError("SUS: answers are whole numbers 1-5")
    row = QuestionnaireRow(
        participant.id,
        participant.expertise,
        str(interface),
        str(task),
        tlx,
        None if sus is None else tuple(int(v) for v in sus),
    )
    record_questionnaire(study_dir, row)  # scores first: a bad answer writes nothing
    scores = []
    if row.tlx_raw is not None:
        scores.append(f"TLX {row.tlx_raw:.1f}")
    if row.sus_score is not None:
        scores.append(f"SUS {row.sus_score:.1f}")
    return f"questionnaire of {participant.id} after the {interface} saved ({', '.join(scores)})"
