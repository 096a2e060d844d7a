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
from jointbench.core.types import Trial
from tests.estimate_data import one_blas_thread_per_test  # noqa: F401 (autouse fixture)
from tests.test_band_checks import TRUTH, narrow_band
from tests.test_ensemble_estimators import LAGS, ensemble_of, true_irf
from tests.test_fsewls import FS as FS_ELBOW, simulate as elbow
from tests.test_kbr import FS as FS_WRIST, lti_record, ltv_record, multisine, sine_k, wrist_frf
from tests.test_skirt import impedance, k_sine, lti_trial, ltv_trial

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
                                 "(tests/test_reflex_estimators.py)",
             "pv_parallel_cascade": "tests/test_pv_parallel_cascade.py (its K(theta) band on a simulated trial with a "
                                    "reflex, pointwise over the schedule, 8 seeds)"}
#: estimators with intervals and no coverage test yet (issue 20, not done: say so, never narrow silently)
NOT_YET: dict[str, str] = {}
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
    listed = set(LTI) | set(ENSEMBLE) | set(ELSEWHERE) | set(NOT_YET) | set(MULTISINE) | {"fsewls"} | NO_INTERVALS
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


# ------------------------------------------------------------------ multisine estimators: kbr, skirt
# Their kind: the wrist with contact (van de Ruit et al. 2018, eq. 13) driven by a random-phase sparse
# multisine (0.1 ... 19.3 Hz every 0.8 Hz, 40 s at 44 Hz; tests/test_kbr.py, tests/test_skirt.py), white torque
# noise of 0.3 times the torque's SD (SNR 10 dB); the stiffness is |H| at the lowest line (0.1 Hz). Quick: the
# time-invariant wrist (k = 5.6, a periodic steady state), one check per record (a time-invariant record's
# band errors are one number); slow: k(t) = 5.6 + 0.9 sin(2 pi t / 20 s) from the ODE, three times per record.
NOISE = 0.3


def _noisy(u, y, seed):
    return y + np.random.default_rng(1000 + seed).standard_normal(len(y)) * NOISE * y.std()


def wrist_lti(name: str, seed: int):
    if name == "kbr":
        u, y = lti_record(multisine(seed))
        trial, k = Trial.from_arrays(u, _noisy(u, y, seed), FS_WRIST, name=f"wrist{seed}"), 5.6
        return trial, np.full(trial.n, abs(wrist_frf(0.1, k)))
    t = lti_trial(seed)
    return t.replace(torque=_noisy(t.angle, t.torque, seed)), np.full(t.n, abs(impedance(0.1)))


def wrist_ltv(name: str, seed: int):
    if name == "kbr":
        u, y, k = ltv_record(multisine(seed), sine_k)
        return Trial.from_arrays(u, _noisy(u, y, seed), FS_WRIST, name=f"wrist{seed}"), np.abs(wrist_frf(0.1, k))
    t = ltv_trial(k_sine, seed=seed)
    return t.replace(torque=_noisy(t.angle, t.torque, seed)), np.abs(impedance(0.1, k_sine(t.time)))


#: settings of each multisine estimator's coverage check. kbr with refine here; its default (the paper's relaxation
#: of App. B, stopped at a fixed point of the weights, not the minimiser of eq. B.1) is biased by noise
#: (tests/test_kbr.py::test_noisy_trial_needs_the_gauss_newton_refinement) and has its own check:
#: test_kbr_relaxation_band_covers
MULTISINE = {"kbr": {"refine": True}, "skirt": {}}


def multisine_coverage(name: str, seeds: int, make, times: int, settings: dict | None = None):
    rows = []
    for seed in range(seeds):
        trial, truth = make(name, seed)
        est = estimators.make(name, MULTISINE[name] if settings is None else settings).fit(trial)
        lo, hi = est.intervals.bounds["stiffness"]
        k = est.stiffness(trial.time)
        at = np.linspace(0.2 * trial.n, 0.7 * trial.n, times).astype(int)   # away from the record's ends
        rows += [(k[i], lo[i], hi[i], truth[i]) for i in at]
    return check(name, rows)


@pytest.mark.parametrize("name", list(MULTISINE))
def test_multisine_bands_cover(name):
    multisine_coverage(name, 20, wrist_lti, 1)


def test_kbr_relaxation_band_covers():
    """kbr's default (the relaxation alone) is biased by noise (-0.48 N m/rad here, 2.2 robust SDs of its errors):
    its posterior spread alone missed the truth in 16 of 20 seeds. Its interval is the refined minimiser's,
    widened to hold the relaxation's estimate: it covers, and is not vast (WIDTH against the relaxation's spread)."""
    multisine_coverage("kbr", 20, wrist_lti, 1, settings={})


def test_kbr_relaxation_band_is_the_refined_band_holding_the_estimate():
    """What the default band is: the band of ``refine: true`` (same data) widened just enough to hold the
    relaxation's own estimate, at every sample; never narrower than the refined band."""
    trial, _ = wrist_lti("kbr", 3)
    relax, refined = (estimators.make("kbr", st).fit(trial) for st in ({}, {"refine": True}))
    lo, hi = relax.intervals.bounds["stiffness"]
    rlo, rhi = refined.intervals.bounds["stiffness"]
    k = relax.stiffness(trial.time)
    assert np.all(lo <= k) and np.all(k <= hi)
    assert np.allclose(lo, np.minimum(rlo, k), rtol=1e-6) and np.allclose(hi, np.maximum(rhi, k), rtol=1e-6)
    assert np.any(k < rlo) or np.any(k > rhi)       # the widening does something on this noisy record
    assert "widened to hold the relaxation's estimate" in relax.intervals.method


#: settings of the varying-stiffness check (k(t) = 5.6 + 0.9 sin(2 pi t / 20 s)): kbr with a kernel whose prior
#: holds that variation. Its band is a Bayesian posterior at a fixed kernel: it holds the smoothing's error only as
#: far as the prior allows the variation. With the default sigma = 20 s the squared-exponential prior weighs a 20 s
#: period by exp(-(pi sigma / 20 s)^2) = 5e-5: refined, 37 misses of 120 (coverage 69 %), the errors at the three
#: times biased by -0.28, +0.38, +0.22 N m/rad with SD 0.2 and half-width 0.38 (the band's spread right, the
#: smoothing's bias outside it); sigma = auto chose 16 s (20 misses of 60). sigma = 5 s (prior weight 0.54 at that
#: period; the only other width tried): 3 misses of 60 refined, 2 of 60 with the relaxation's widened band.
LTV_SETTINGS = {"kbr": {"refine": True, "sigma": 5.0}, "kbr_relaxation": {"sigma": 5.0}, "skirt": {}}


@pytest.mark.slow
@pytest.mark.parametrize("case", list(LTV_SETTINGS))
def test_slow_multisine_bands_cover_a_varying_stiffness(case):
    multisine_coverage(case.split("_")[0], 40, wrist_ltv, 3, settings=LTV_SETTINGS[case])


# ---------------------------------------------------------------------------------------- fsewls
# Its kind: Xu & Hollerbach's elbow (I 0.06, K 40, zeta 0.3) driven by a +-4 N m random binary torque of a
# 10 ms clock (tests/test_fsewls.py), 12 s at 1 kHz, white noise of 0.5 N m SD on the measured torque (an eighth of
# the drive), time-invariant; checks at three times of the steady span per record (1/forgetting = 50 ms apart
# by far: nearly independent).
def fsewls_coverage(seeds: int):
    rows = {k: [] for k in "IBK"}
    for seed in range(seeds):
        _, theta, tau, K, B = elbow(12.0, seed=seed)
        tau = tau + np.random.default_rng(1000 + seed).standard_normal(len(tau)) * 0.5
        trial = Trial.from_arrays(theta, tau, FS_ELBOW, imposed="torque", name=f"elbow{seed}")
        est = estimators.make("fsewls").fit(trial)
        idx = np.flatnonzero(est.steady())
        at = idx[np.linspace(0, len(idx) - 1, 3).astype(int)]
        for k, truth in zip("IBK", (0.06, B[0], K[0])):
            v = np.broadcast_to(getattr(est, k), trial.time.shape)
            lo, hi = est.intervals.bounds[k]
            rows[k] += [(v[i], lo[i], hi[i], truth) for i in at]
    return {k: check(f"fsewls {k}", r) for k, r in rows.items()}


def test_fsewls_bands_cover():
    fsewls_coverage(7)


@pytest.mark.slow
def test_slow_fsewls_bands_cover():
    fsewls_coverage(40)
