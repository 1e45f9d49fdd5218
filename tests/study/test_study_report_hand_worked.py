"""The study report's tables against numbers worked out by hand.

Six participants (three novices, three experts) each did one pick-and-place trial with
each of three interfaces.  The numbers are chosen so every figure can be checked on paper:

- times (s), per participant P1..P6:
  skin     10, 12, 14, 16, 18, 20
  keyboard 11, 14, 17, 20, 23, 26          (skin + 1..6)
  pendant  9.5, 14.2, 17.9, 20.1, 23.7, 26.3
- commands: skin 4..9, keyboard 5, 7, .., 15, pendant 3, 8, 12, 15, 18, 21.

No two differences of a pair tie and none is zero, so each Wilcoxon signed-rank p is exact:
with W the smaller rank sum of n = 6 pairs, p = 2 * #{sign patterns with rank sum <= W} / 2^6.
skin - keyboard is negative for everyone (W = 0: p = 2/64 = 0.03125); skin - pendant has
one positive difference of rank 1 (W = 1: p = 4/64 = 0.0625); keyboard - pendant is
+1.5, -0.2, -0.9, -0.1, -0.7, -0.3 in time, its positive one of rank 6 (W = 6: the
subsets of 1..6 summing to <= 6 number 14, p = 28/64 = 0.4375), and in commands
+2, -1, -3, -4, -5, -6 (W = 2: p = 6/64 = 0.09375).  Holm multiplies the smallest p by 3,
the next by 2, the largest by 1, keeping them non-decreasing: time 0.09375, 0.125,
0.4375; commands 0.09375, 0.125, 0.125.  Friedman: every participant ranks
(pendant, skin, keyboard) as (3, 1, 2) but P1 (1, 2, 3) in both measures, so the rank
sums are 7, 13, 16 and chi2 = 12 / (6 * 3 * 4) * (49 + 169 + 256) - 3 * 6 * 4 = 7.00,
p = exp(-7 / 2) = 0.030 (2 degrees of freedom), Kendall's W = 7 / (6 * 2) = 0.58.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest

from wovenskin.study.definition import StudyDefinition
from wovenskin.study.document import Heading, Table, Text
from wovenskin.study.reader import TrialResult
from wovenskin.study.report import report_blocks
from wovenskin.study.stats import holm, wilcoxon_pair

INTERFACES = ("skin", "keyboard", "pendant")
PEOPLE = ("P1", "P2", "P3", "P4", "P5", "P6")
EXPERTISE = ("novice",) * 3 + ("expert",) * 3
TIME = {
    "skin": (10.0, 12.0, 14.0, 16.0, 18.0, 20.0),
    "keyboard": (11.0, 14.0, 17.0, 20.0, 23.0, 26.0),
    "pendant": (9.5, 14.2, 17.9, 20.1, 23.7, 26.3),
}
COMMANDS = {
    "skin": (4, 5, 6, 7, 8, 9),
    "keyboard": (5, 7, 9, 11, 13, 15),
    "pendant": (3, 8, 12, 15, 18, 21),
}


def _trials() -> list[TrialResult]:
    trials = []
    for interface in INTERFACES:
        for k, (person, level) in enumerate(zip(PEOPLE, EXPERTISE, strict=True)):
            timed_out = interface == "pendant" and person == "P6"
            trials.append(
                TrialResult(
                    person, "pick_place", interface, 1, Path(person), complete=True,
                    expertise=level, outcome="timeout" if timed_out else "success",
                    duration_s=TIME[interface][k], commands=COMMANDS[interface][k],
                    measures={"objects_seated": 1.0},
                )
            )  # fmt: skip
    # an aborted trial (an experimenter's stop) is not counted anywhere
    trials.append(
        TrialResult("P1", "pick_place", "skin", 2, Path("P1"), complete=True,
                    expertise="novice", outcome="aborted", duration_s=999.0, commands=999)
    )  # fmt: skip
    return trials


@pytest.fixture(scope="module")
def blocks() -> list:
    study = StudyDefinition(name="hand", tasks=("pick_place",), interfaces=INTERFACES)
    return report_blocks(study, _trials(), [], [], {}, False)


def _table_after(blocks: list, test) -> Table:
    """The first table after the first block for which ``test`` holds."""
    start = next(i for i, block in enumerate(blocks) if test(block))
    return next(b for b in blocks[start + 1 :] if isinstance(b, Table))


def _columns(table: Table, *names: str) -> list[tuple[str, ...]]:
    index = [table.header.index(name) for name in names]
    return [tuple(row[i] for i in index) for row in table.rows]


def test_the_task_table_has_the_hand_worked_means_and_stds(blocks) -> None:
    table = _table_after(blocks, lambda b: b == Heading("Task: pick_place", 2))
    names = ("interface", "expertise", "participants", "trials", "time (s)", "commands",
             "success")  # fmt: skip
    assert _columns(table, *names) == [
        # expert 16, 18, 20: mean 18, std sqrt((4 + 0 + 4) / 2) = 2
        ("skin", "expert", "3", "3", "18.0 ± 2.0", "8.0 ± 1.0", "100 %"),
        ("skin", "novice", "3", "3", "12.0 ± 2.0", "5.0 ± 1.0", "100 %"),
        # all: deviations -5, -3, -1, 1, 3, 5 -> sqrt(70 / 5) = 3.74
        ("skin", "all", "6", "6", "15.0 ± 3.7", "6.5 ± 1.9", "100 %"),
        ("keyboard", "expert", "3", "3", "23.0 ± 3.0", "13.0 ± 2.0", "100 %"),
        ("keyboard", "novice", "3", "3", "14.0 ± 3.0", "7.0 ± 2.0", "100 %"),
        # time: deviations +-7.5, +-4.5, +-1.5 -> sqrt(157.5 / 5) = 5.61
        ("keyboard", "all", "6", "6", "18.5 ± 5.6", "10.0 ± 3.7", "100 %"),
        # 20.1, 23.7, 26.3: mean 23.37, std sqrt(19.39 / 2) = 3.11; P6 timed out: 2 of 3
        ("pendant", "expert", "3", "3", "23.4 ± 3.1", "18.0 ± 3.0", "67 %"),
        # 9.5, 14.2, 17.9: mean 13.87, std sqrt(35.45 / 2) = 4.21; 3, 8, 12: 7.67 ± 4.51
        ("pendant", "novice", "3", "3", "13.9 ± 4.2", "7.7 ± 4.5", "100 %"),
        # 111.7 / 6 = 18.62, std sqrt(190.21 / 5) = 6.17; 77 / 6 = 12.83 ± sqrt(218.83 / 5)
        ("pendant", "all", "6", "6", "18.6 ± 6.2", "12.8 ± 6.6", "83 %"),
    ]


def test_the_reductions_are_worked_from_the_means(blocks) -> None:
    table = _table_after(blocks, lambda b: isinstance(b, Text) and "Relative reduction" in b.text)
    assert table.header == ("comparison", "expertise", "time", "commands")
    assert [tuple(row) for row in table.rows] == [
        ("skin vs keyboard", "all", "18.9 %", "35.0 %"),  # (18.5 - 15) / 18.5; (10 - 6.5) / 10
        ("skin vs keyboard", "expert", "21.7 %", "38.5 %"),  # 5 / 23; 5 / 13
        ("skin vs keyboard", "novice", "14.3 %", "28.6 %"),  # 2 / 14; 2 / 7
        ("skin vs pendant", "all", "19.4 %", "49.4 %"),  # 3.617 / 18.617; 6.333 / 12.833
        ("skin vs pendant", "expert", "23.0 %", "55.6 %"),  # 5.367 / 23.367; 10 / 18
        ("skin vs pendant", "novice", "13.5 %", "34.8 %"),  # 1.867 / 13.867; 2.667 / 7.667
    ]


FRIEDMAN = (
    "Friedman test of {} over n = 6 participants, k = 3 interfaces: chi2 = 7.00, "
    "p = 0.030, Kendall's W = 0.58; chi-square approximation, rough for n < 10."
)


@pytest.mark.parametrize(
    ("measure", "expected"),
    [
        (
            "time",
            [  # pair, n, median difference, W, p, p (Holm), rank-biserial
                ("skin vs keyboard", "6", "-3.50", "0.0", "0.031", "0.094", "-1.00"),
                ("skin vs pendant", "6", "-4.00", "1.0", "0.062", "0.125", "-0.90"),
                ("keyboard vs pendant", "6", "-0.25", "6.0", "0.438", "0.438", "-0.43"),
            ],
        ),
        (
            "commands",
            [
                ("skin vs keyboard", "6", "-3.50", "0.0", "0.031", "0.094", "-1.00"),
                ("skin vs pendant", "6", "-7.00", "1.0", "0.062", "0.125", "-0.90"),
                ("keyboard vs pendant", "6", "-3.50", "2.0", "0.094", "0.125", "-0.81"),
            ],
        ),
    ],
)
def test_the_paired_statistics_are_the_hand_worked_ones(blocks, measure, expected) -> None:
    """Rank-biserial (R+ - R-) / 21: (0 - 21), (1 - 20), (6 - 15) / 21 and (2 - 19) / 21."""
    friedman = FRIEDMAN.format(measure)
    assert Text(friedman) in blocks
    table = _table_after(blocks, lambda b: b == Text(friedman))
    names = ("pair", "n", "median difference", "W", "p", "p (Holm)", "rank-biserial")
    assert _columns(table, *names) == expected


def _exact_wilcoxon_p(differences: list[float]) -> float:
    """Two-sided exact p by counting every sign pattern of the ranks (no ties, no zeros)."""
    order = sorted(range(len(differences)), key=lambda i: abs(differences[i]))
    ranks = {i: r + 1 for r, i in enumerate(order)}
    plus = sum(ranks[i] for i, d in enumerate(differences) if d > 0)
    total = len(differences) * (len(differences) + 1) // 2
    w = min(plus, total - plus)
    ranks_list = list(range(1, len(differences) + 1))
    patterns = itertools.product((0, 1), repeat=len(differences))
    count = sum(sum(r for r, s in zip(ranks_list, p, strict=True) if s) <= w for p in patterns)
    return min(1.0, 2 * count / 2 ** len(differences))


def test_the_tests_match_an_independent_count_and_holms_step_down() -> None:
    expected = {"time": (0.03125, 0.0625, 0.4375), "commands": (0.03125, 0.0625, 0.09375)}
    for values, want in ((TIME, expected["time"]), (COMMANDS, expected["commands"])):
        got = []
        for a, b in itertools.combinations(INTERFACES, 2):
            d = [float(x) - float(y) for x, y in zip(values[a], values[b], strict=True)]
            assert _exact_wilcoxon_p(d) == pytest.approx(want[len(got)])
            got.append(wilcoxon_pair(a, b, values[a], values[b]).p)
        assert got == pytest.approx(want)
    # Holm by hand: sorted 0.03125 * 3, 0.0625 * 2, then max(previous, p * 1)
    assert holm([0.03125, 0.0625, 0.4375]) == pytest.approx([0.09375, 0.125, 0.4375])
    assert holm([0.03125, 0.0625, 0.09375]) == pytest.approx([0.09375, 0.125, 0.125])
    assert holm([0.4375, math.nan, 0.03125]) == pytest.approx([0.4375, math.nan, 0.0625],
                                                              nan_ok=True)  # fmt: skip
