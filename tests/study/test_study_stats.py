"""Paired statistics against scipy and hand-worked values; small n said, not tested."""

from __future__ import annotations

import math

import pytest
from scipy import stats

from wovenskin.study.stats import compare_interfaces, friedman, holm, wilcoxon_pair

# Seven participants, skin against keyboard (seconds); differences -1, 1, -2, -3, -3, -3,
# -3.5: |d| ranks 1.5, 1.5, 3, 5.5, 5.5, 5.5, 5.5... (ties averaged), R+ = 1.5.
SKIN = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.5]
KEYS = [2.0, 1.0, 5.0, 7.0, 8.0, 9.0, 11.0]


def test_holm_adjusts_by_rank_and_keeps_order_monotone():
    assert holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    assert holm([0.5, math.nan, 0.01]) == pytest.approx([0.5, math.nan, 0.02], nan_ok=True)
    assert holm([0.6, 0.7]) == [1.0, 1.0]


def test_wilcoxon_matches_scipy_and_the_effect_sizes_the_hand_ranks_give():
    test = wilcoxon_pair("skin", "keyboard", SKIN, KEYS)
    expected = stats.wilcoxon(SKIN, KEYS)
    assert test.statistic == expected.statistic == 1.5
    assert test.p == pytest.approx(expected.pvalue)
    z = stats.wilcoxon(SKIN, KEYS, method="approx").zstatistic
    assert test.z == pytest.approx(-abs(z))  # skin lower: negative
    assert test.r == pytest.approx(-abs(z) / math.sqrt(7))
    assert test.rank_biserial == pytest.approx((1.5 - 26.5) / 28)
    assert test.n == test.n_nonzero == 7 and test.median_difference == -3.0


def test_too_few_pairs_is_said_with_n():
    test = wilcoxon_pair("a", "b", [1, 2, 3, 4, 5], [2, 3, 4, 5, 7])
    assert math.isnan(test.p) and "n = 5" in test.note and "too few" in test.note
    zeros = wilcoxon_pair("a", "b", [1] * 8, [1] * 6 + [2, 3])
    assert zeros.n == 8 and zeros.n_nonzero == 2 and "n = 2" in zeros.note


def test_friedman_matches_scipy_and_refuses_too_few():
    columns = [[1, 2, 3, 4], [2, 3, 5, 5], [3, 5, 4, 6]]
    result = friedman(columns)
    expected = stats.friedmanchisquare(*columns)
    assert result.statistic == pytest.approx(expected.statistic)
    assert result.p == pytest.approx(expected.pvalue)
    assert result.kendall_w == pytest.approx(expected.statistic / (4 * 2))
    assert "rough" in result.note
    assert "n = 2" in friedman([[1, 2], [2, 3], [3, 4]]).note
    assert "k = 2" in friedman([[1, 2, 3], [2, 3, 4]]).note


def test_compare_interfaces_pairs_participants_and_applies_holm():
    values = {
        f"P{i}": {"skin": s, "keyboard": k, "pendant": k + 5 + i}
        for i, (s, k) in enumerate(zip(SKIN, KEYS, strict=True))
    }
    values["P9"] = {"skin": 1.0}  # no pairs: left out of every test
    overall, tests = compare_interfaces(values, ["skin", "keyboard", "pendant"])
    assert overall.n == 7
    assert [(t.a, t.b) for t in tests] == [
        ("skin", "keyboard"),
        ("skin", "pendant"),
        ("keyboard", "pendant"),
    ]
    assert tests[0].p == pytest.approx(stats.wilcoxon(SKIN, KEYS).pvalue)
    assert [t.p_holm for t in tests] == pytest.approx(holm([t.p for t in tests]))
