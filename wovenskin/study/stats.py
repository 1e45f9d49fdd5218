"""Paired statistics across interfaces: Friedman, then Wilcoxon signed-rank with Holm.

Every participant uses every interface, so the tests are paired over participants: one
value per participant and interface (their mean over the trials of a task).  Friedman
(scipy's chi-square approximation) asks whether the interfaces differ at all; each pair
then gets a two-sided Wilcoxon signed-rank test (zeros dropped, exact p where scipy can),
Holm-corrected over the pairs, with two effect sizes: r = Z / sqrt(N) (Rosenthal 1991; Z
from the normal approximation, N the non-zero pairs, signed like the median difference)
and the matched-pairs rank-biserial correlation (Kerby 2014: (R+ - R-) / (R+ + R-)).
Below :data:`MIN_PAIRS` pairs no two-sided exact p can fall under 0.05, so the test is
not run and the result says so with its n.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy import stats

from wovenskin.wording import quantity

MIN_PAIRS = 6  # with 5 non-zero pairs the smallest two-sided exact p is 2 / 2**5 = 0.0625
MIN_FRIEDMAN = 3  # participants with every interface


def holm(pvalues: Sequence[float]) -> list[float]:
    """Holm-Bonferroni adjusted p-values, in the given order (NaN stays NaN)."""
    indexed = [(p, i) for i, p in enumerate(pvalues) if not math.isnan(p)]
    indexed.sort()
    m = len(indexed)
    adjusted = [math.nan] * len(pvalues)
    running = 0.0
    for rank, (p, i) in enumerate(indexed):
        running = max(running, min(1.0, (m - rank) * p))
        adjusted[i] = running
    return adjusted


@dataclass(frozen=True)
class PairedTest:
    """The Wilcoxon signed-rank test of ``a`` against ``b`` over ``n`` paired
    participants (``n_nonzero`` with a difference); p-values are NaN when not run."""

    a: str
    b: str
    n: int
    n_nonzero: int
    median_difference: float
    statistic: float = math.nan
    p: float = math.nan
    p_holm: float = math.nan
    z: float = math.nan
    r: float = math.nan
    rank_biserial: float = math.nan
    note: str = ""


def wilcoxon_pair(a: str, b: str, x: Sequence[float], y: Sequence[float]) -> PairedTest:
    """Paired test of ``x`` (condition ``a``) against ``y`` (``b``), same participants."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    d = x - y
    nonzero = d[d != 0]
    n, k = len(d), len(nonzero)
    median = float(np.median(d)) if n else math.nan
    if k < MIN_PAIRS:
        note = f"n = {k} non-zero pairs: too few for a test (needs >= {MIN_PAIRS})"
        return PairedTest(a, b, n, k, median, note=note)
    ranks = stats.rankdata(np.abs(nonzero))
    r_plus, r_minus = ranks[nonzero > 0].sum(), ranks[nonzero < 0].sum()
    rank_biserial = float((r_plus - r_minus) / (r_plus + r_minus))
    exact = stats.wilcoxon(x, y)
    approx = stats.wilcoxon(x, y, method="approx")
    z = abs(float(approx.zstatistic)) * (1 if rank_biserial >= 0 else -1)
    return PairedTest(
        a,
        b,
        n,
        k,
        median,
        statistic=float(exact.statistic),
        p=float(exact.pvalue),
        z=z,
        r=z / math.sqrt(k),
        rank_biserial=rank_biserial,
    )


@dataclass(frozen=True)
class FriedmanResult:
    """The Friedman test over ``n`` participants with all ``k`` interfaces."""

    n: int
    k: int
    statistic: float = math.nan
    p: float = math.nan
    kendall_w: float = math.nan
    note: str = ""


def friedman(columns: Sequence[Sequence[float]]) -> FriedmanResult:
    """Friedman's test of ``k`` conditions (one column each, rows = participants), with
    Kendall's W = chi2 / (n (k - 1)) as its effect size."""
    k = len(columns)
    n = len(columns[0]) if k else 0
    if k < 3:
        return FriedmanResult(n, k, note=f"k = {k} interfaces: Friedman needs >= 3")
    if n < MIN_FRIEDMAN:
        people = quantity(n, "participant")
        note = f"n = {people} with every interface: too few (needs >= {MIN_FRIEDMAN})"
        return FriedmanResult(n, k, note=note)
    data = np.asarray(columns, dtype=float)
    if np.all(data == data[0]):
        return FriedmanResult(n, k, note="every interface gave the same values: no test")
    result = stats.friedmanchisquare(*data)
    chi2 = float(result.statistic)
    note = "chi-square approximation, rough for n < 10" if n < 10 else ""
    return FriedmanResult(n, k, chi2, float(result.pvalue), chi2 / (n * (k - 1)), note)


def compare_interfaces(
    values: Mapping[str, Mapping[str, float]], interfaces: Sequence[str]
) -> tuple[FriedmanResult, list[PairedTest]]:
    """``values[participant][interface]`` compared: Friedman over the participants with
    every interface, then every pair over the participants with both, Holm-corrected."""
    complete = [p for p in values if all(i in values[p] for i in interfaces)]
    columns = [[values[p][i] for p in complete] for i in interfaces]
    overall = friedman(columns)
    tests = []
    for a, b in itertools.combinations(interfaces, 2):
        both = [p for p in values if a in values[p] and b in values[p]]
        tests.append(
            wilcoxon_pair(a, b, [values[p][a] for p in both], [values[p][b] for p in both])
        )
    adjusted = holm([t.p for t in tests])
    tests = [replace(t, p_holm=p) for t, p in zip(tests, adjusted, strict=True)]
    return overall, tests
