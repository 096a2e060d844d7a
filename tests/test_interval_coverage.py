"""Every estimator's 95 % interval covers in a simulation of its own kind (issue 20), over seeds.

The rule of the threshold: when an interval is right, its misses over ``S`` independent seeds follow
Binomial(S, 0.05); a check fails when the misses exceed the count that a right interval exceeds with
probability below 0.001 (:func:`allowed_misses`; over the ~15 checks here a false alarm below 2 %). With
20 seeds that is 5 misses (coverage 75 %): it catches intervals that are badly wrong (the issue's
+-0 and +-1e13, or a bias of several widths), not a few points of under-coverage; the ``slow`` version
(100 seeds: 13 misses allowed, coverage 87 %) is the finer measure. Intervals that cover by being vast
are caught by the width: the median half-width over 1.96 robust standard deviations of the errors
(MAD x 1.4826) must lie within 0.5 ... 2.5 (:data:`WIDTH`): a MAD of 20-50 checks is uncertain by about
25 %, and the ensemble estimators' jackknife is conservative by design (its variance is biased upwards,
Efron & Stein 1981; measured 1.2-1.4 for ensemble_irf over 56 checks).

The kinds: a time-invariant impedance (exact second-order torque of a random-phase multisine angle to
12 Hz, 10 s at 250 Hz, white torque noise of 30 % of its variance) for the time-invariant estimators;
ensembles of white inputs through a time-varying IRF with output noise for the ensemble estimators, each
in the time variation its model represents (ensemble_irf: any, pointwise; sds: constant over its
window; guarin: within its basis). Estimators with intervals tested elsewhere, or not yet, are listed
with where or why: a new estimator with intervals and no entry fails
:func:`test_every_estimator_with_intervals_has_a_coverage_check`.
"""
import numpy as np
import pytest
from scipy import stats

from jointbench import estimators
from tests.estimate_data import one_blas_thread  # noqa: F401 (autouse fixture)
from tests.test_band_checks import TRUTH, narrow_band
from tests.test_ensemble_estimators import LAGS, ensemble_of, true_irf

LAG = {"lag_before": 0.04, "lag_after": 0.04}
#: time-invariant estimators: settings and the quantities whose intervals are checked
LTI = {"ibk_spectral": ({}, ("I", "B", "K")),
       "ibk_irf": (LAG, ("I", "B", "K")),
       "irf2_ls": (LAG, ("stiffness",)),
       "irf2_corr": (LAG, ("stiffness",)),
       "spectral": ({}, ("stiffness",))}
#: time-invariant estimators checked in the slow version only (1.3 s a fit)
LTI_SLOW = {"parallel_cascade": ({}, ("stiffness",))}
#: ensemble estimators: settings and the time variation of the true IRF (a factor on true_irf())
ENSEMBLE = {"ensemble_irf": ({}, "sine"),
            "sds": ({"window": 0.3}, "constant"),
            "guarin": ({"basis": "legendre", "n_basis": 2}, "ramp")}
#: estimators whose intervals are checked for coverage in another test
ELSEWHERE = {"pv_irf": "tests/test_reflex_estimators.py::test_pv_irf_band_covers_k_at_the_stated_rate",
             "parallel_cascade": "test_slow_lti_coverage here (LTI_SLOW); without a reflex its band is irf2_ls's "
                                 "(tests/test_reflex_estimators.py)"}
#: estimators with intervals and no coverage test yet (issue 20, not done: say so, never narrow silently)
NOT_YET = {"kbr": "needs a time-varying multisine simulation of its own kind (minutes)",
           "skirt": "needs a sparse-multisine simulation of its own kind",
           "fsewls": "needs a time-varying elbow simulation of its own kind"}
#: estimators that give no intervals
NO_INTERVALS = {"tv_parallel_cascade", "ensemble_spectral"}


#: bounds of the median half-width over 1.96 robust standard deviations of the errors (module docstring)
WIDTH = (0.5, 2.5)


def allowed_misses(checks: int, level: float = 0.95, alarm: float = 0.001) -> int:
    """Largest miss count a right ``level`` interval reaches with probability >= ``alarm`` over ``checks``."""
    return int(stats.binom.isf(alarm, checks, 1 - level))


def lti_truth(name: str, est, k: str) -> float:
    if name == "spectral":              # |H| at the lowest positive Welch frequency
        w = 2 * np.pi * est.freq[1]
        return abs(TRUTH["K"] + 1j * w * TRUTH["B"] - TRUTH["I"] * w ** 2)
    return TRUTH["K"] if k == "stiffness" else TRUTH[k]


def check(name: str, rows: list[tuple[float, float, float, float]]):
    """``rows`` of (estimate, lo, hi, truth), one per independent check."""
    v, lo, hi, truth = np.array(rows).T
    misses = int(np.sum((truth < lo) | (truth > hi)))
    assert misses <= allowed_misses(len(rows)), (name, f"{misses} misses of {len(rows)}")
    spread = 1.4826 * np.median(np.abs((v - truth) - np.median(v - truth)))
    ratio = float(np.median((hi - lo) / 2) / (1.96 * spread))
    assert WIDTH[0] <= ratio <= WIDTH[1], (name, f"half-width / 1.96 SD = {ratio:.2f}")
    return misses, ratio


def lti_coverage(name: str, seeds: int):
    settings, keys = {**LTI, **LTI_SLOW}[name]
    rows = {k: [] for k in keys}
    for seed in range(seeds):
        est = estimators.make(name, settings).fit(narrow_band(seed, fs=250.0, duration=10.0, noise=0.3))
        for k in keys:
            lo, hi = (float(np.mean(b)) for b in est.intervals.bounds[k])
            v = float(np.mean(est.stiffness(est.time))) if k == "stiffness" else float(getattr(est, k))
            rows[k].append((v, lo, hi, lti_truth(name, est, k)))
    return {k: check(f"{name} {k}", r) for k, r in rows.items()}


def true_tv(kind: str, n: int) -> np.ndarray:
    x = np.linspace(-1.0, 1.0, n)
    factor = {"sine": 1 + 0.3 * np.sin(np.pi * x), "constant": np.ones(n), "ramp": 1 + 0.3 * x}[kind]
    return true_irf()[:, None] * factor[None, :]


def ensemble_coverage(name: str, seeds: int, n: int = 150, R: int = 20, times: int = 6):
    """``times`` checks per seed at samples spread over the valid span (far apart relative to the lags:
    their noise is nearly independent)."""
    settings, kind = ENSEMBLE[name]
    H = true_tv(kind, n)
    rows = []
    for seed in range(seeds):
        est = estimators.make(name, settings).fit(ensemble_of(H, n, R, seed=100 + seed, noise=0.3))
        lo, hi = est.intervals.bounds["stiffness"]
        idx = np.flatnonzero(est.valid)
        at = idx[np.linspace(len(LAGS), len(idx) - 1 - len(LAGS), times).astype(int)]
        k = est.stiffness(est.time)
        rows += [(k[i], lo[i], hi[i], H[:, i].sum()) for i in at]
    return check(name, rows)


def test_allowed_misses():
    assert allowed_misses(20) == 5 and allowed_misses(100) == 13


def test_every_estimator_with_intervals_has_a_coverage_check():
    listed = set(LTI) | set(ENSEMBLE) | set(ELSEWHERE) | set(NOT_YET) | NO_INTERVALS
    names = set(estimators.REGISTRY.names())
    assert names <= listed, sorted(names - listed)


@pytest.mark.parametrize("name", list(LTI))
def test_lti_intervals_cover(name):
    lti_coverage(name, seeds=20)


@pytest.mark.parametrize("name", list(ENSEMBLE))
def test_ensemble_bands_cover(name):
    ensemble_coverage(name, seeds=8)


@pytest.mark.slow
@pytest.mark.parametrize("name", [*LTI, *LTI_SLOW])
def test_slow_lti_coverage(name):
    """irf2_corr missed 22 of 100 here before its intervals held its end effect (the zero-padded correlations
    pull the coordinates of the lag directions above the input's band towards zero:
    :func:`estimators._twosided.correlation_end_effect`); 10 of 100 after (irf2_ls: 7)."""
    lti_coverage(name, seeds=100)


@pytest.mark.slow
@pytest.mark.parametrize("name", list(ENSEMBLE))
def test_slow_ensemble_coverage(name):
    ensemble_coverage(name, seeds=25)
