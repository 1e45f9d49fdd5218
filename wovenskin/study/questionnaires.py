"""NASA-TLX (raw) and SUS: scoring, and the answers kept in ``questionnaires.csv``.

Raw TLX (Hart 2006, "NASA-Task Load Index (NASA-TLX); 20 years later") is the mean of the
six subscales, each 0-100; *performance* runs from 0 = perfect to 100 = failure, as on
the official form, so no subscale is reversed.  SUS (Brooke 1996, "SUS: a quick and
dirty usability scale") has ten items answered 1-5: odd items give ``answer - 1``, even
items ``5 - answer``, and the sum times 2.5 is the score, 0-100.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from wovenskin.errors import DataError
from wovenskin.study.definition import check_participant_id
from wovenskin.study.logfiles import LineLog, read_csv_rows

QUESTIONNAIRES_FILE = "questionnaires.csv"
TLX_SCALES = ("mental", "physical", "temporal", "performance", "effort", "frustration")
TLX_COLUMNS = tuple(f"tlx_{name}" for name in TLX_SCALES)
SUS_COLUMNS = tuple(f"sus_{i}" for i in range(1, 11))
QUESTIONNAIRE_COLUMNS = (
    "participant",
    "expertise",
    "interface",
    "task",
    *TLX_COLUMNS,
    "tlx_raw",
    *SUS_COLUMNS,
    "sus_score",
    "synthetic",
)


def _numbers(values: Sequence[float], n: int, low: float, high: float, what: str) -> list[float]:
    answers = [float(v) for v in values]
    if len(answers) != n:
        raise DataError(f"{what} takes {n} answers, got {len(answers)}")
    for i, v in enumerate(answers, start=1):
        if not math.isfinite(v) or not low <= v <= high:
            raise DataError(f"{what} answer {i} must be {low:g}-{high:g}, got {v:g}")
    return answers


def tlx_raw(subscales: Sequence[float]) -> float:
    """Raw NASA-TLX: the mean of the six subscales (mental, physical, temporal,
    performance, effort, frustration), each 0-100."""
    return sum(_numbers(subscales, 6, 0, 100, "NASA-TLX")) / 6


def sus_score(items: Sequence[int]) -> float:
    """The SUS score 0-100 of ten answers 1-5 (item 1 first)."""
    answers = _numbers(items, 10, 1, 5, "SUS")
    if any(a != int(a) for a in answers):
        raise DataError(f"SUS answers are whole numbers 1-5, got {answers}")
    odd = sum(a - 1 for a in answers[0::2])
    even = sum(5 - a for a in answers[1::2])
    return (odd + even) * 2.5


@dataclass(frozen=True)
class QuestionnaireRow:
    """One participant's answers after using one interface (for one task, or "" for all)."""

    participant: str
    expertise: str
    interface: str
    task: str
    tlx: tuple[float, ...] | None
    sus: tuple[int, ...] | None
    synthetic: bool = False

    @property
    def tlx_raw(self) -> float | None:
        return None if self.tlx is None else tlx_raw(self.tlx)

    @property
    def sus_score(self) -> float | None:
        return None if self.sus is None else sus_score(self.sus)


def record_questionnaire(study_dir: str | Path, row: QuestionnaireRow) -> None:
    """Append ``row`` (scored) to ``DIR/questionnaires.csv``; answers are checked first."""
    check_participant_id(row.participant)
    if row.tlx is None and row.sus is None:
        raise DataError("a questionnaire row needs NASA-TLX or SUS answers")
    tlx = list(row.tlx) if row.tlx is not None else [None] * 6
    sus = list(row.sus) if row.sus is not None else [None] * 10
    values = (
        row.participant,
        row.expertise,
        row.interface,
        row.task,
        *tlx,
        row.tlx_raw,
        *sus,
        row.sus_score,
        int(row.synthetic),
    )
    log = LineLog(Path(study_dir) / QUESTIONNAIRES_FILE, QUESTIONNAIRE_COLUMNS)
    try:
        log.write_row(values)
        log.sync()
    finally:
        log.close()


def read_questionnaires(study_dir: str | Path) -> tuple[list[QuestionnaireRow], list[str]]:
    """The rows of ``DIR/questionnaires.csv`` (none if absent) and warning lines for rows
    that were torn or hold bad answers (left out)."""
    path = Path(study_dir) / QUESTIONNAIRES_FILE
    if not path.exists():
        return [], []
    raw, torn = read_csv_rows(path)
    warnings = [f"{path}: a torn last line was left out"] if torn else []
    rows = []
    for n, cells in enumerate(raw, start=2):
        try:
            tlx = [cells[c] for c in TLX_COLUMNS]
            sus = [cells[c] for c in SUS_COLUMNS]
            row = QuestionnaireRow(
                participant=cells["participant"],
                expertise=cells["expertise"],
                interface=cells["interface"],
                task=cells["task"],
                tlx=tuple(float(v) for v in tlx) if all(tlx) else None,
                sus=tuple(int(float(v)) for v in sus) if all(sus) else None,
                synthetic=cells["synthetic"] == "1",
            )
            row.tlx_raw, row.sus_score  # noqa: B018 - scoring checks the answers
        except (ValueError, KeyError) as exc:
            warnings.append(f"{path} line {n}: left out ({exc})")
            continue
        rows.append(row)
    return rows, warnings
