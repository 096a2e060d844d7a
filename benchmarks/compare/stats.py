"""Statistics of a method comparison, as pure functions on arrays: intervals over realizations, ranks and
winners among finite values, the Wilcoxon signed-rank test of paired differences with Holm's correction,
and win counts over scenarios. No frame, file or figure here (:mod:`jointbench.benchmarks.compare.figures` uses them).

Every random draw comes from an explicit seed (:data:`SEED` unless given), so the same values give the
same intervals.

References
----------
Efron & Tibshirani, *An Introduction to the Bootstrap* (1993), ch. 13 (the percentile interval).
Wilcoxon, "Individual comparisons by ranking methods", Biometrics Bulletin 1 (1945) 80-83 (signed ranks).
Holm, "A simple sequentially rejective multiple test procedure", Scand. J. Statist. 6 (1979) 65-70.
Agarwal, Schwarzer, Castro, Courville & Bellemare, "Deep reinforcement learning at the edge of the
statistical precipice", NeurIPS 2021 (intervals over runs rather than point scores; rliable).
"""
from __future__ import annotations

import functools
from typing import Literal

import numpy as np

#: seed of the bootstrap draws over realizations
SEED = 20_180_101
#: bootstrap draws for the interval of a median over realizations
DRAWS = 2000
Better = Literal["max", "min"]


def bootstrap_interval(values, level: float = 0.90, draws: int = DRAWS, seed: int = SEED,
                        stat=np.median) -> tuple[float, float]:
    """Percentile bootstrap interval of ``stat`` (default the median) over the realizations ``values``:
    the ``(1 - level)/2`` and ``(1 + level)/2`` quantiles (nearest ranks outward) of ``stat`` over ``draws``
    resamplings with replacement. One value, or all equal: ``(v, v)``. NaN values are dropped; none left:
    ``(nan, nan)``.

    References
    ----------
    Efron & Tibshirani (1993), eq. 13.5 (the percentile interval).
    """
    x = np.asarray(values, float)
    x = x[~np.isnan(x)]
    if x.size == 0:
        return float("nan"), float("nan")
    if x.size == 1 or np.all(x == x[0]):
        return float(x[0]), float(x[0])
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, x.size, size=(draws, x.size))
    boot = stat(x[idx], axis=1)
    a = (1 - level) / 2
    return (float(np.percentile(boot, 100 * a, method="lower")),
            float(np.percentile(boot, 100 * (1 - a), method="higher")))


def contains(lo: float, value: float, hi: float) -> bool:
    """Whether the interval ``[lo, hi]`` holds ``value`` (an infinite value: when both ends equal it)."""
    if not np.isfinite(value):
        return bool(lo == value and hi == value)
    return bool(lo <= value <= hi)


def ranks(values, better: Better) -> np.ndarray:
    """Competition ranks (1 = best; ties share the better rank) of the finite ``values``; a non-finite
    value (NaN, an infinite rise time) gets no rank (NaN)."""
    x = np.asarray(values, float)
    out = np.full(x.shape, np.nan)
    ok = np.isfinite(x)
    if not ok.any():
        return out
    key = -x[ok] if better == "max" else x[ok]
    out[ok] = [1 + int(np.sum(key < k)) for k in key]
    return out


def winner(values, better: Better) -> int | None:
    """Index of the best finite value (the first on a tie), or ``None`` when none is finite."""
    r = ranks(values, better)
    if not np.isfinite(r).any():
        return None
    return int(np.flatnonzero(r == 1)[0])


@functools.lru_cache(maxsize=None)
def _signed_rank_null(n: int) -> np.ndarray:
    """P(W+ = w), w = 0 .. n(n+1)/2, for n pairs without ties: every sign pattern equally likely."""
    counts = np.zeros(n * (n + 1) // 2 + 1)
    counts[0] = 1.0
    for k in range(1, n + 1):             # rank k with a + sign adds k to W+
        counts[k:] = counts[k:] + counts[:-k].copy()
    return counts / 2.0 ** n


def signed_rank_p(diffs) -> float:
    """Two-sided p-value of the Wilcoxon signed-rank test that paired differences are centred on 0.

    Zero differences are dropped (Wilcoxon's own treatment); none left: 1. Exact null distribution of the
    sum of the positive ranks ``W+`` for up to 50 pairs without ties in the absolute differences
    (p = 2 min(P(W+ <= w), P(W+ >= w)), at most 1), scipy's normal approximation otherwise.

    References
    ----------
    Wilcoxon (1945).
    """
    d = np.asarray(diffs, float)
    d = d[np.isfinite(d) & (d != 0)]
    if d.size == 0:
        return 1.0
    a = np.abs(d)
    if d.size <= 50 and np.unique(a).size == d.size:
        w = int(np.sum((np.argsort(np.argsort(a)) + 1)[d > 0]))
        pmf = _signed_rank_null(d.size)
        return float(min(1.0, 2 * min(pmf[:w + 1].sum(), pmf[w:].sum())))
    from scipy import stats

    return float(stats.wilcoxon(d, zero_method="wilcox", method="approx").pvalue)


def holm(pvalues) -> np.ndarray:
    """Holm's step-down adjusted p-values: the i-th smallest of m p-values times (m - i + 1), made
    non-decreasing in that order and capped at 1. Rejecting where the adjusted value is below alpha
    keeps the family-wise error rate at alpha.

    References
    ----------
    Holm (1979).
    """
    p = np.asarray(pvalues, float)
    m = p.size
    if m == 0:
        return p
    order = np.argsort(p, kind="stable")
    adj = np.minimum(1.0, np.maximum.accumulate(p[order] * (m - np.arange(m))))
    out = np.empty(m)
    out[order] = adj
    return out


def min_signed_rank_p(n: int) -> float:
    """The smallest two-sided exact p-value the signed-rank test can give with ``n`` pairs: 2 / 2^n
    (every difference of one sign)."""
    return 2.0 / 2.0 ** n if n > 0 else 1.0


def discordant_signed_rank_p(n: int, discordant: int = 0) -> float:
    """The exact two-sided signed-rank p-value of ``n`` pairs without ties whose ``discordant`` smallest
    absolute differences point the other way: ``2 P(W <= d(d+1)/2)`` under the null (``d = discordant``),
    the smallest p-value ``n`` pairs can give with ``d`` of them against the rest. ``d = 0``:
    :func:`min_signed_rank_p`.

    References
    ----------
    Wilcoxon (1945) (the null distribution of the signed-rank sum).
    """
    if n <= 0:
        return 1.0
    if not 0 <= discordant <= n:
        raise ValueError(f"discordant must be between 0 and n = {n}, got {discordant}")
    w = discordant * (discordant + 1) // 2
    return float(min(1.0, 2 * _signed_rank_null(n)[:w + 1].sum()))


def holm_first_threshold(m: int, alpha: float) -> float:
    """The level the smallest of ``m`` p-values must be below for Holm's procedure to reject anything:
    ``alpha / m`` (Holm 1979; with no p-value below it, no hypothesis of the family is rejected)."""
    return alpha / m if m > 0 else alpha


def rejection_attainable(n: int, m: int, alpha: float, discordant: int = 0) -> bool:
    """Whether a family of ``m`` paired signed-rank tests over ``n`` shared realizations can reject at
    family-wise level ``alpha`` after Holm's correction, with the ``discordant`` smallest differences of
    the best pair pointing the other way (0: every difference of one sign, the most any data can give)."""
    return discordant_signed_rank_p(n, discordant) < holm_first_threshold(m, alpha)


def realizations_needed(m: int, alpha: float, discordant: int = 0, most: int = 200) -> int:
    """The fewest realizations ``n`` with which a family of ``m`` pairs can reject at ``alpha`` after Holm
    (:func:`rejection_attainable`) when the ``discordant`` smallest differences point the other way.

    Raises
    ------
    ValueError
        None up to ``most``.
    """
    for n in range(max(1, discordant + 1), most + 1):
        if rejection_attainable(n, m, alpha, discordant):
            return n
    raise ValueError(f"no n up to {most} lets {m} pairs reject at {alpha:g} with {discordant} discordant")


def paired_comparisons(values: dict[str, dict], better: Better, alpha: float = 0.05) -> list[dict]:
    """Every pair of methods compared over the realizations they share.

    ``values`` maps a method to {realization: value}. For each pair (a, b) with at least one shared
    realization where both values are finite: ``n`` shared realizations, ``median_diff`` (median over
    them of a - b) with ``diff_lo``/``diff_hi`` (the paired percentile bootstrap 90 % interval of that
    median: the realizations resampled as pairs), ``p`` (:func:`signed_rank_p`), ``p_holm`` (Holm over
    all pairs of this call: one family), ``favours``: 'a' or 'b' (the one the median difference favours;
    '' on 0) and ``verdict``: ``favours`` when ``p_holm < alpha``, else '' (no difference shown).
    """
    names = list(values)
    recs = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            shared = [r for r in values[a] if r in values[b]
                      and np.isfinite(values[a][r]) and np.isfinite(values[b][r])]
            if not shared:
                continue
            d = np.array([values[a][r] - values[b][r] for r in shared], float)
            lo, hi = bootstrap_interval(d)
            recs.append({"a": a, "b": b, "n": len(shared), "median_diff": float(np.median(d)), "diff_lo": lo,
                         "diff_hi": hi, "p": signed_rank_p(d)})
    for rec, ph in zip(recs, holm([r["p"] for r in recs])):
        rec["p_holm"] = float(ph)
        good = rec["median_diff"] > 0 if better == "max" else rec["median_diff"] < 0
        bad = rec["median_diff"] < 0 if better == "max" else rec["median_diff"] > 0
        rec["favours"] = "a" if good else "b" if bad else ""
        rec["verdict"] = rec["favours"] if ph < alpha else ""
    return recs


def win_counts(pairs_by_scenario: dict[str, list[dict]]) -> dict[tuple[str, str], dict]:
    """Over scenarios, for every ordered pair (a, b): ``wins`` (scenarios where a is significantly better
    than b), ``ahead`` (scenarios where the median paired difference favours a, significant or not) and
    ``of`` (scenarios where the two were compared). ``pairs_by_scenario``: scenario -> the output of
    :func:`paired_comparisons`."""
    out: dict[tuple[str, str], dict] = {}
    for pairs in pairs_by_scenario.values():
        for r in pairs:
            for x, y, side in ((r["a"], r["b"], "a"), (r["b"], r["a"], "b")):
                c = out.setdefault((x, y), {"wins": 0, "ahead": 0, "of": 0})
                c["of"] += 1
                c["wins"] += r["verdict"] == side
                c["ahead"] += r.get("favours", "") == side
    return out
