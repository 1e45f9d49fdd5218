"""The paper's published figures that the report sets its own beside.

Tables I (pick-and-place) and II (pouring) of the paper's evaluation: mean and standard
deviation of the completion time (s) and of the command count, per interface and
expertise, over 10 trials of each of 3 novices and 3 experts; for pouring also the success
rate (% of trials without spillage).  The paper prints the command column as "12+0.3",
read here as mean 12, standard deviation 0.3.  Its recognition figures: the
convolution-transformer near 100 % accuracy on its validation windows, the BiLSTM
baseline 96.7 %; 15 ms against 12 ms per window.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PaperCell:
    """One row of Table I or II."""

    time_mean: float
    time_std: float
    commands_mean: float
    commands_std: float
    success_rate: float | None = None  # percent; pouring only


PAPER_TABLES: dict[str, dict[tuple[str, str], PaperCell]] = {
    "pick_place": {
        ("skin", "novice"): PaperCell(85.4, 3.4, 12, 0.3),
        ("skin", "expert"): PaperCell(72.3, 2.1, 7, 0.1),
        ("keyboard", "novice"): PaperCell(146.7, 9.5, 32, 1.7),
        ("keyboard", "expert"): PaperCell(102.1, 5.1, 26, 1.2),
        ("pendant", "novice"): PaperCell(182.7, 12.2, 38, 2.4),
        ("pendant", "expert"): PaperCell(132.4, 7.8, 29, 2.0),
    },
    "pour": {
        ("skin", "novice"): PaperCell(62.4, 2.1, 11, 0.4, 98.7),
        ("skin", "expert"): PaperCell(51.5, 1.9, 8, 0.2, 99.2),
        ("keyboard", "novice"): PaperCell(105.4, 3.8, 18, 1.6, 94.3),
        ("keyboard", "expert"): PaperCell(74.3, 2.8, 12, 1.3, 96.6),
        ("pendant", "novice"): PaperCell(132.9, 7.6, 23, 2.5, 91.2),
        ("pendant", "expert"): PaperCell(94.1, 5.3, 15, 2.1, 93.4),
    },
}
PAPER_REDUCTION_TEXT = (
    "completion time reduced by 35-57 % for novices and 23-50 % for experts against the "
    "keyboard and the teach pendant"
)
PAPER_PARTICIPANTS = "6 (3 novices, 3 experts), 10 trials per task and interface"


def paper_reduction(task: str, expertise: str, baseline: str) -> float:
    """The paper's relative time reduction (%) of the skin against ``baseline``."""
    skin = PAPER_TABLES[task][("skin", expertise)].time_mean
    other = PAPER_TABLES[task][(baseline, expertise)].time_mean
    return 100.0 * (other - skin) / other
