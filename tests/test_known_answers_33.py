"""Known-answer tests for the behaviours issue 33 found no test would notice ("Tests that would not notice").

Each test's answer is derived independently of the code under test: from physics (a second-order joint's
overshoot, a low-pass's steady ramp lag), a closed form (Holm's adjustment, Student's t quantile, the MDL's
penalty), a hand calculation, or a simulation whose truth is known. Each was verified against the one-line
bug it is meant to catch: the bug planted in the source, the test run and seen to fail (the message quoted
in the test's docstring), the bug reverted and the test seen to pass.
"""
from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from jointbench import api, estimators, sims
from jointbench.benchmarks.compare import stats as cs
from jointbench.benchmarks.harness.fingerprint import plugin_hash
from jointbench.core import plugins
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.core.estimate import FRFEstimate
from jointbench.sims.apparatus import TorqueDrive
from jointbench.sims.backend_stepping import SteppingBackend
from jointbench.sims.joint_position_dependent import PositionDependentJoint
from jointbench.sims.reflex_stretch import StretchReflex
from tests.test_ensemble_estimators import ensemble_of, true_irf
from tests.test_reflex_estimators import GRID, ankle, lpv_experiment, trial

from jointbench.core.band import MAX_GAP, MIN_RUN, input_band


# ---------------------------------------------------------------- 1. the polynomial reflex pathway's sign
@pytest.mark.parametrize("seed", [0, 1])
def test_polynomial_reflex_rises_with_stretch_velocity(seed):
    """The simulated reflex (sims/reflex_stretch.py, ``stretch: positive``) is a half-wave rectifier of the
    delayed velocity through a unit-gain low-pass and a gain of 5 N.m.s/rad: its torque rises with stretch
    velocity, and its IRF sums to the positive gain. The estimated polynomial pathway (whose scale and sign
    the cascade cannot tell apart: ``N h = (-N)(-h)``) must be reported that way round: N rising over
    positive velocities, flat over negative ones, ``sum(h_R) > 0``.

    Planted: ``if np.sum(h) > 0:`` for ``if np.sum(h) < 0:`` in ``estimators/_reflex.py::_normalized``
    (predictions unchanged). Failed with ``AssertionError: the reflex IRF sums to -4.69 (the simulated
    reflex's gain is +5 N.m.s/rad)``.
    """
    tr = trial(5.0, seed)
    pc = estimators.make("parallel_cascade", {"nonlinearity": "polynomial"}).fit(tr)
    assert pc.reflex_h is not None
    gain = float(np.sum(pc.reflex_h))
    assert gain > 0, f"the reflex IRF sums to {gain:.3g} (the simulated reflex's gain is +5 N.m.s/rad)"
    v = np.linspace(0.0, 0.8 * pc.nonlinearity.scale, 9)
    rise, fall = pc.nonlinearity(v), pc.nonlinearity(-v)
    assert rise[-1] - rise[0] > 0, "the static nonlinearity falls with stretch velocity"
    assert np.all(np.diff(rise) > -0.05 * np.ptp(rise)), "the static nonlinearity is not rising with stretch"
    assert np.ptp(fall) < 0.25 * np.ptp(rise)          # shortening barely excites it (a rectifier's shape)
    # and the simulated truth agrees: the reflex torque grows with the delayed stretch velocity
    s = tr.truth.signals
    assert np.corrcoef(s["reflex_torque"], pc.reflex_torque(tr.angle - tr.angle.mean()))[0, 1] > 0.95


# ---------------------------------------------------------- 2. tv_parallel_cascade's MDL over R x N rows
@pytest.mark.parametrize("seed", [0, 1])
def test_tv_cascade_keeps_a_weak_reflex_seen_in_every_realization(seed):
    """The MDL ``RSS (1 + k ln n / n)`` counts every row the fit uses: ``n = R N`` over R realizations of N
    samples. A weak true reflex (gain 1 N.m.s/rad, 8 realizations of 12 s at 100 Hz) lowers the residual by
    about 12 % (measured: the intrinsic pathway's VAF alone 96.6 %, both 97.0 %). Its 37 more parameters
    (11 gains, 26 lags) beside the intrinsic 99 (11 x 9) cost, by the closed form, 3.8 % with n = R N = 7 700
    rows, but 15 % with n = N = 966: so the pathway is kept only when the rows are counted right.

    Planted: ``rx.mdl(rss, k_I + k_R, N) < rx.mdl(fit.rss_intrinsic, k_I, N)`` in
    ``estimators/parallel_cascade_tv.py``. Failed with ``AssertionError: the reflex pathway of a simulated
    reflex (gain 1) was dropped: not kept: it does not lower the MDL against the intrinsic pathway alone``.
    """
    R = 8
    ens = Ensemble(tuple(sims.simulate(ankle(1.0, duration=12.0, joint="varying"), seed, realization=r)
                         for r in range(R)))
    fit = estimators.make("tv_parallel_cascade", {"delay": 0.05}).fit(ens)
    N = int(fit.valid.sum())
    k_I, k_R = 11 * 9, 11 + (30 - 5 + 1)

    def penalty(n):                         # the RSS reduction the reflex pathway must bring to be kept
        return (1 + (k_I + k_R) * math.log(n) / n) / (1 + k_I * math.log(n) / n) - 1

    assert penalty(R * N) < 0.05 and penalty(N) > 0.14      # the design: the two counts decide differently
    assert fit.reflex_h is not None, (f"the reflex pathway of a simulated reflex (gain 1) was dropped: "
                                      f"{fit.info['reflex']}")
    assert fit.info["reflex"] == "kept (MDL)" and fit.vaf_reflex > 0


# --------------------------------------------------------------- 3. pv_irf's band: dK/dcoef, axis order
def test_pv_irf_band_is_the_propagated_covariance_of_k():
    """K(sigma) = sum_k h(k, sigma) is linear in the coefficients, so its standard error is exactly
    ``sqrt(J C J')`` with J the derivative of K(sigma) by each coefficient. J is found here by finite
    differences of ``stiffness_at`` (each coefficient moved by 1 in turn: no use of the band's own
    derivative), C the estimate's covariance, and the band's half width must be the t quantile times it.

    Planted: ``g = np.tile(T, L)`` for ``g = np.repeat(T, L, axis=1)`` in ``estimators/pv_irf.py``
    (``stiffness_band``). Failed with ``AssertionError: the band's half width is not t times the propagated
    standard error of K (ratio 7.8 ... 25)``.
    """
    import dataclasses

    from scipy import stats

    pv = estimators.make("pv_irf", {"n_basis": 3}).fit(sims.simulate(lpv_experiment(noise=0.1, duration=60.0), 0))
    sig = GRID[::2]
    base = pv.stiffness_at(sig)
    J = np.empty((len(sig), pv.coef.size))
    for j in range(pv.coef.size):
        c = pv.coef.ravel().copy()
        c[j] += 1.0
        J[:, j] = dataclasses.replace(pv, coef=c.reshape(pv.coef.shape)).stiffness_at(sig) - base
    se = np.sqrt(np.einsum("ij,jk,ik->i", J, pv.cov, J))
    lo, hi = pv.stiffness_band(sig)
    q = stats.t.ppf(0.975, np.interp(pv._x(sig), np.linspace(-1, 1, len(pv.dof_of_x)), pv.dof_of_x))
    ratio = (hi - lo) / 2 / (q * se)
    assert np.allclose(ratio, 1.0, rtol=1e-6), (f"the band's half width is not t times the propagated standard "
                                                f"error of K (ratio {ratio.min():.2g} ... {ratio.max():.2g})")
    assert np.allclose((lo + hi) / 2, base)


# ------------------------------------------------------------------------ 4. the input band's gap rule
def _band_of(excited: np.ndarray) -> tuple[float, float] | None:
    """The input band of a Welch estimate whose squared coherence is 0.9 at ``excited`` frequencies and 0.01
    elsewhere (every frequency powered; 20 averages: significant above 1 - 0.05^(1/19) = 0.146)."""
    f = np.arange(len(excited)) * 0.5
    coh = np.where(excited, 0.9, 0.01)
    frf = FRFEstimate(freq=f, H=np.ones(len(f), complex), coherence=coh, fs=100.0, time=np.arange(400) / 100.0,
                      estimator="spectral", n_averages=20)
    band = input_band(frf)
    return None if band is None else (band.lo, band.hi)


@pytest.mark.parametrize("gap", [1, MAX_GAP, MAX_GAP + 1])
def test_input_band_joins_runs_across_at_most_max_gap_frequencies(gap):
    """Two runs of excited frequencies (5 and 4 long) separated by ``gap`` unexcited ones: joined into one
    band (0.5 ... the second run's end) when the gap is at most MAX_GAP (module docstring: "joined across
    gaps of at most MAX_GAP frequencies"), else the longer run alone.

    Planted: ``if a - groups[-1][1] - 1 < MAX_GAP:`` for ``<= MAX_GAP`` in ``estimators/_band.py``.
    Failed (gap = MAX_GAP) with ``AssertionError: a gap of 2 frequencies: band (0.5, 2.5), expected (0.5,
    5.5)``; the other way, ``<= MAX_GAP + 1``, failed at gap = MAX_GAP + 1 with ``AssertionError: a gap of 3
    frequencies: band (0.5, 6.0), expected (0.5, 2.5)``.
    """
    first, second = 5, 4
    excited = np.zeros(40, bool)
    excited[1:1 + first] = True
    start = 1 + first + gap
    excited[start:start + second] = True
    expected = (0.5, (start + second - 1) * 0.5) if gap <= MAX_GAP else (0.5, first * 0.5)
    got = _band_of(excited)
    assert got == expected, f"a gap of {gap} frequencies: band {got}, expected {expected}"


def test_input_band_needs_runs_of_min_run():
    """A run one shorter than MIN_RUN is no band; a run of MIN_RUN is.

    Planted: ``if i - start > MIN_RUN:`` for ``>= MIN_RUN`` in ``estimators/_band.py``. Failed with
    ``assert None == (1.0, 2.0)``.
    """
    for n, expected in ((MIN_RUN - 1, None), (MIN_RUN, (1.0, (MIN_RUN + 1) * 0.5))):
        excited = np.zeros(30, bool)
        excited[2:2 + n] = True
        assert _band_of(excited) == expected


# --------------------------------------------- 5. the reflex simulator's fractional-delay interpolation
@pytest.mark.parametrize("extra", [0.25, 0.5, 0.8])
def test_fractional_reflex_delay_gives_the_analytic_ramp_response(extra):
    """A linear pathway (``nonlinearity: none``, gain 1) driven by a velocity ramp v(t) = t: its input is the
    delayed ramp t - delta, exactly (linear interpolation is exact on a line), and the unit-gain second-order
    activation's steady response to a ramp lags it by 2 zeta / omega. After the transient (e^(-zeta omega t):
    1e-12 by 2 s) the torque must be t - delta - 2 zeta / omega, for a delay of 40 + ``extra`` samples.

    Planted: ``v0 = self.frac * v0 + (1.0 - self.frac) * v1`` (weights swapped) in
    ``sims/reflex_stretch.py::ReflexStepper.advance``. Failed (extra 0.25) with ``AssertionError: delay of
    40.25 samples: the torque is off the analytic ramp response by 0.0005`` (half a sample: read at 40.75);
    at 40.8 by 0.0006. A delay of k + 0.5 samples cannot tell the weights apart (it passes either way).
    """
    fs, zeta, freq = 1000.0, 0.7, 3.2
    delay = (40 + extra) / fs
    reflex = StretchReflex(gain=1.0, delay=delay, nonlinearity="none", frequency=freq, damping_ratio=zeta)
    t = np.arange(3000) / fs
    torque = reflex.torque(t.copy(), fs)
    late = t >= 2.0
    analytic = t[late] - delay - 2 * zeta / (2 * np.pi * freq)
    err = float(np.max(np.abs(torque[late] - analytic)))
    assert err < 1e-8, (f"delay of {40 + extra:g} samples: the torque is off the analytic ramp response by "
                        f"{err:.2g}")


# --------------------------------------------- 6. the position-dependent joint's damping from its ratio
@pytest.mark.parametrize("zeta", [0.2, 0.4])
def test_position_dependent_damping_ratio_gives_the_second_order_overshoot(zeta):
    """A torque step on a joint of constant K = 100 N.m/rad, I = 0.01 kg.m2 and ``damping_ratio`` zeta:
    B = 2 zeta sqrt(K I), so the angle overshoots its final value T/K by exp(-pi zeta / sqrt(1 - zeta^2))
    (the second-order step response), 52.7 % at zeta 0.2, 25.4 % at 0.4.

    Planted: ``return self.damping_ratio * np.sqrt(self.K.at(theta) * self.I)`` (the factor 2 gone) in
    ``sims/joint_position_dependent.py::damping_at``. Failed (zeta 0.2) with ``AssertionError: zeta 0.2:
    overshoot 72.9 %, the second-order step response's 52.7 %``.
    """
    fs, K, I, T = 20000.0, 100.0, 0.01, 0.5
    n = int(0.2 * fs)
    j = PositionDependentJoint(I=I, K=K, damping_ratio=zeta)
    out = SteppingBackend().run(j, TorqueDrive(), np.full(n, T), np.zeros(n), fs)
    overshoot = 100.0 * (np.max(out.angle) / (T / K) - 1.0)
    expected = 100.0 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta ** 2))
    assert abs(overshoot - expected) < 0.5, (f"zeta {zeta:g}: overshoot {overshoot:.1f} %, the second-order step "
                                             f"response's {expected:.1f} %")


# -------------------------------------------------- 7. a paired comparison's verdict from Holm's p
def _family(n_ab: int) -> dict[str, dict[int, float]]:
    """Three methods over ``n_ab`` realizations: a above b at every one (distinct margins: the signed-rank
    p is 2 / 2^n), c far above and below both by turns (its comparisons far from significant)."""
    r = np.arange(n_ab)
    a = 10.0 + r
    b = a - 0.1 * (r + 1)
    c = 10.0 + np.where(r % 2 == 0, 50.0, -50.0) + r
    return {m: dict(enumerate(v.tolist())) for m, v in (("a", a), ("b", b), ("c", c))}


def test_paired_verdict_follows_holms_adjusted_p():
    """Six realizations, a above b at each: raw p = 2 / 64 = 0.031 < 0.05, but Holm over the family of three
    pairs multiplies the smallest p by 3: 0.094 > 0.05, so no difference is shown. Ten realizations: raw p =
    2 / 1024, Holm's 0.0059 < 0.05: a is favoured.

    Planted: ``rec["verdict"] = rec["favours"] if rec["p"] < alpha else ""`` in
    ``benchmarks/compare/stats.py::paired_comparisons``. Failed with ``AssertionError: raw p 0.03125, Holm's
    0.09375: verdict 'a', expected none``.
    """
    pairs = {(p["a"], p["b"]): p for p in cs.paired_comparisons(_family(6), "max", alpha=0.05)}
    ab = pairs["a", "b"]
    assert ab["p"] == pytest.approx(2 / 64) and ab["favours"] == "a"
    assert ab["p_holm"] == pytest.approx(3 * 2 / 64)
    assert ab["verdict"] == "", (f"raw p {ab['p']:.4g}, Holm's {ab['p_holm']:.4g}: verdict {ab['verdict']!r}, "
                                 f"expected none")
    ten = {(p["a"], p["b"]): p for p in cs.paired_comparisons(_family(10), "max", alpha=0.05)}["a", "b"]
    assert ten["p_holm"] == pytest.approx(3 * 2 / 1024) and ten["verdict"] == "a"


def _tuning_rows(n: int) -> tuple:
    """Per-realization rows of one feasible cell: three methods, paper and tuned columns; tuning raises m1's
    VAF of k at every one of ``n`` realizations (distinct margins), moves m2's and m3's up and down by turns."""
    import pandas as pd

    recs = []
    for r in range(n):
        paper = {"m1": 50.0 + r, "m2": 60.0 + r, "m3": 70.0 + r}
        step = 1.0 + 0.1 * r
        tuned = {"m1": paper["m1"] + step, "m2": paper["m2"] + (step if r % 2 else -step),
                 "m3": paper["m3"] + (-step if r % 2 else step)}
        for tuning, vals in (("paper", paper), ("tuned", tuned)):
            recs += [{"cell": "c", "method": m, "tuning": tuning, "realization": r, "value": v, "status": "ok",
                      "backend": "analytic", "metric": "vaf_stiffness", "case_id": f"{m}-{tuning}"}
                     for m, v in vals.items()]
    table = pd.DataFrame([{"cell": "c", "backend": "analytic", "metric": "vaf_stiffness", "value": 60.0}])
    return pd.DataFrame(recs), table


def test_tuning_effect_counts_only_holm_significant_changes():
    """The tuned column against the paper column, Holm over the three methods of the cell: m1 better at all
    6 realizations has raw p = 2 / 64 = 0.031, Holm's 3 x 0.031 = 0.094: not significantly better; at 10
    realizations, Holm's 3 x 2 / 1024 = 0.0059: significantly better (in 1 of 1 scenarios).

    Planted: ``rec["helped"] = bool(rec["p"] < ALPHA and good)`` in
    ``benchmarks/compare/pairs.py::tuning_effect``. Failed with ``AssertionError: m1 counted as tuned
    significantly better on raw p 0.031 (Holm's 0.094)``.
    """
    from jointbench.benchmarks.compare.pairs import tuning_effect

    out = tuning_effect(*_tuning_rows(6)).set_index("method")
    assert out.loc["m1", "tuned significantly better"] == 0, ("m1 counted as tuned significantly better on raw p "
                                                            "0.031 (Holm's 0.094)")
    assert out["tuned significantly worse"].sum() == 0
    assert tuning_effect(*_tuning_rows(10)).set_index("method").loc["m1", "tuned significantly better"] == 1


# ------------------------------------------------------- 8. a plugin's source hash and its subpackages
_PLUGIN_INIT = "from .methods.core import Method  # noqa: F401\n"
_PLUGIN_CORE = '''from jointbench.estimators import Estimator, register


@register(__name__.split(".")[0])
class Method(Estimator):
    """A plugin whose estimator lives in a subpackage."""

    accepts = frozenset({"trial"})

    def _fit(self, trials):
        raise NotImplementedError
'''


def _plugin(root, name: str, edit: str = "") -> None:
    pkg = root / name
    (pkg / "methods").mkdir(parents=True)
    (pkg / "__init__.py").write_text(_PLUGIN_INIT)
    (pkg / "methods" / "__init__.py").write_text("")
    (pkg / "methods" / "core.py").write_text(_PLUGIN_CORE + edit)


def test_a_plugins_source_hash_covers_its_subpackages(tmp_path, monkeypatch):
    """Three plugin packages with the same files (an estimator registered in a subpackage, under its
    package's name); the second's subpackage module carries one more line of code (an edit), the third is
    the first byte for byte. The source hash (of the files' relative names and parsed code: a comment would
    not count, tests/test_tuning_declared.py) must tell the edited one apart, and not the copy.

    Planted: ``base.glob("*.py")`` for ``base.rglob("*.py")`` in ``jointbench/core/plugins.py::source_files``
    (subpackages ignored). Failed with ``AssertionError: an edit in the plugin's subpackage left its source
    hash unchanged``.
    """
    names = ("kat33_plugin_a", "kat33_plugin_b", "kat33_plugin_c")
    _plugin(tmp_path, names[0])
    _plugin(tmp_path, names[1], edit="EDITED = True\n")
    _plugin(tmp_path, names[2])
    monkeypatch.setattr(sys, "path", list(sys.path))            # plugins.load puts the folder on it
    monkeypatch.setattr(plugins, "_LOADED", {})                 # and records the plugins: not beyond this test
    try:
        for n in names:
            plugins.load(str(tmp_path / n))
        text = plugin_hash(list(names))
        digest = {n: text[n].split()[-1] for n in names}
        assert digest[names[0]] != digest[names[1]], "an edit in the plugin's subpackage left its source hash unchanged"
        assert digest[names[0]] == digest[names[2]]
    finally:
        for n in names:
            estimators.REGISTRY._items.pop(n, None)
            estimators.REGISTRY._tags.pop(n, None)
            for mod in [m for m in sys.modules if m == n or m.startswith(n + ".")]:
                del sys.modules[mod]


# ----------------------------------------------------------------- 9. the sampling rate from a time column
SHORT_LAGS = {"lag_before": "5 ms", "lag_after": "5 ms"}


def _csv(path, time: np.ndarray, seed: int = 0) -> str:
    rng = np.random.default_rng(seed)
    angle = 0.01 * rng.standard_normal(len(time))
    torque = 120.0 * angle + 0.01 * rng.standard_normal(len(time))
    np.savetxt(path, np.column_stack([time, angle, torque]), delimiter=",", header="time,angle,torque",
               comments="", fmt=["%.6f", "%.9g", "%.9g"])
    return str(path)


def test_fit_reads_the_sampling_rate_of_rounded_time_stamps(tmp_path):
    """2048 Hz stamps written to the microsecond: the steps are 488 or 489 us (488.28 on average), so the
    median step gives 2049.2 Hz (2050 once rounded to the stamps); the rate the stamps fit is 2048 Hz,
    exactly. ``api.fit`` has no ``time=`` (gone with issue 34: a time base comes with a file or a Trial).

    Planted: ``step = float(np.median(dt))`` for the mean step in ``jointbench/fitting/read.py::time_base``
    (the old ``api.fit(time=)``'s rule). Failed with ``AssertionError: fs 2050 Hz from 2048 Hz stamps``.
    """
    n, fs = 4096, 2048.0
    path = _csv(tmp_path / "rounded.csv", np.round(np.arange(n) / fs + 0.25, 6))
    fit = api.fit("irf2_ls", path, settings=SHORT_LAGS)
    got = fit.trials[0].fs
    assert got == fs, f"fs {got:g} Hz from {fs:g} Hz stamps"
    with pytest.raises(TypeError):
        api.fit("irf2_ls", path, time=np.arange(n) / fs)


def test_fit_refuses_jittered_or_gapped_time(tmp_path):
    """Time stamps with a missing sample, or jitter of 3 % of a step, are not a uniform time base: refused in
    one line naming it (no rate is guessed from them)."""
    n, fs = 2000, 500.0
    t = np.arange(n) / fs
    gapped = np.delete(np.arange(n + 1) / fs, 700)
    jitter = t + 0.03 / fs * np.random.default_rng(1).uniform(-1, 1, n)
    for name, time in (("gapped", gapped), ("jitter", jitter)):
        with pytest.raises(InputError, match="time is not uniform") as info:
            api.fit("irf2_ls", _csv(tmp_path / f"{name}.csv", time), settings=SHORT_LAGS)
        assert "\n" not in str(info.value)


# ---------------------------------------------- 10. the realization jackknife band's two-sided quantile
def test_realization_jackknife_band_uses_the_two_sided_t_quantile():
    """The delete-a-group jackknife (Efron & Tibshirani 1993, ch. 11): with G = 8 groups the variance is
    (G - 1)/G sum_g (k_g - mean k)^2, from the estimator refitted without each group (done here by hand
    with the public estimator on ``Ensemble.subset``), and a 95 % two-sided band is k -+ t_7(0.975) se with
    t_7(0.975) = 2.3646 (tables); a one-sided t_7(0.95) = 1.8946 is a 90 % band.

    Planted: ``q = float(stats.t.ppf(LEVEL, G - 1))`` in ``estimators/_resample.py::realization_jackknife``.
    Failed with ``AssertionError: half width / jackknife se = 1.895, the two-sided 95 % quantile t_7 is
    2.3646``.
    """
    ens = ensemble_of(true_irf(), 300, 16, seed=3, noise=0.3)
    fitter = estimators.make("ensemble_irf", {"groups": 8})
    est = fitter.fit(ens)
    assert est.intervals is not None and est.intervals.level == 0.95
    lo, hi = est.intervals.bounds["stiffness"]
    t = est.time
    G = 8
    ks = np.array([fitter.fit(ens.subset([r for r in range(ens.size) if r % G != g])).stiffness(t)
                   for g in range(G)])
    se = np.sqrt((G - 1) / G * np.sum((ks - ks.mean(axis=0)) ** 2, axis=0))
    ok = est.valid & (se > 0)
    q = ((hi - lo) / 2)[ok] / se[ok]
    assert np.allclose(q, q[0], rtol=1e-9)
    assert q[0] == pytest.approx(2.3646, abs=1e-4), (f"half width / jackknife se = {q[0]:.4g}, the two-sided "
                                                     f"95 % quantile t_7 is 2.3646")
