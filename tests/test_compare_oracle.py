"""The oracle bound of a comparison scenario (issue 36): on noise-free data it recovers the scored
stiffness exactly; with white noise it attains the Cramér-Rao bound sigma^2 (X^T X)^-1 of its linear model
(Monte Carlo over noise replicates with a seed); efficiency divides by the right bound."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from jointbench import api, sims
from jointbench.benchmarks.compare import oracle
from jointbench.benchmarks.compare.identifiability import torque_channel, without_torque_noise
from jointbench.benchmarks.scoring import frozen_stiffness
from jointbench.sims.experiment import limb_response

ELBOW = {"joint": {"model": "time_varying", "I": 0.06, "K": {"shape": "sine", "mean": 40, "amplitude": 15,
                                                            "frequency": 0.5}, "damping_ratio": 0.3},
         "apparatus": {"kind": "torque_drive"},
         "perturbation": {"kind": "prbs", "amplitude": 4, "clock": 0.01, "sequence": "mls"},
         "fs_sim": 1000, "duration": 8, "acquisition": {"detrend": False, "fs": 100, "trim": 0.5}}
WRIST = {"joint": "wrist_vanderuit2018", "apparatus": {"kind": "handle"},
         "perturbation": {"kind": "multisine", "period": 10, "f_min": 0.1, "f_max": 19.3, "spacing": 0.8,
                          "corner": 6, "slope": -20, "rms": 0.02},
         "sensors": {"torque": {"noise_filter": {"kind": "butter", "order": 2, "cutoff": 15}}},
         "fs_sim": 2500, "duration": 20, "acquisition": {"detrend": False, "fs": 50, "decimation": "fft", "trim": 0}}


def _noise_free(exp, seed=3, realization=1):
    """The oracle fitted to the noise-free impedance torque of one realization, and the truth."""
    trial = sims.simulate(exp, seed, realization=realization)
    resp, _ = limb_response(exp, seed, realization)
    X, layout = oracle.regressors(exp, resp)
    beta = oracle.fit_levels(X, np.asarray(trial.truth.signals["torque"], float))
    return oracle.scored_stiffness(exp, trial, oracle.coefficients(beta, layout, len(trial.time))), trial


@pytest.mark.parametrize("config,shape", [(ELBOW, "sine"), (WRIST, "square")])
def test_oracle_is_exact_without_noise(config, shape):
    """Torque drive (K and B = 2 zeta sqrt(K I) vary: two regressors each) and a wrist through a hand
    contact (the scored stiffness is k in series with the contact): the regressors span the acquired
    impedance torque, so least squares on noise-free data returns the scored truth."""
    cfg = dict(config)
    if shape == "square":
        cfg["joint"] = {**api.joint("wrist_vanderuit2018"), "k": {"shape": "square", "mean": 5.6, "amplitude": 0.9,
                                                                  "period": 10}}
    exp = api.experiment(cfg)
    khat, trial = _noise_free(exp)
    k = frozen_stiffness(trial)
    assert np.ptp(k) > 1                                     # a time-varying truth
    assert np.max(np.abs(khat - k)) < 1e-8 * np.max(k)


def test_oracle_attains_the_cramer_rao_bound_with_white_noise():
    """Constant K = 40 (second-order joint), white torque noise of rms sigma = 0.05 N·m on a torque drive
    sampled at 200 Hz:
    the model y = X beta + e with X = [theta'', theta', theta] fixed (one response; replicates redraw only the
    noise) has the Cramér-Rao bound sigma^2 (X^T X)^-1 (Kay 1993, Theorem 4.1). Over M = 400 noise replicates
    (seed 11) the oracle's K-hat is unbiased (within 4 standard errors) and its variance is within 25 % of
    the bound's (the sample variance's relative standard error is sqrt(2 / (M - 1)) = 7 %)."""
    sigma, M, seed = 0.05, 400, 11
    cfg = {**ELBOW, "joint": {"model": "second_order", "I": 0.06, "B": 0.9, "K": 40.0},
           "sensors": {"torque": {"noise_rms": sigma}},
           # no decimation: white noise at the simulation rate stays white (an anti-alias filter colours it
           # near the Nyquist rate, and least squares is then unbiased but above the bound)
           "fs_sim": 200, "acquisition": {"detrend": False, "fs": 200, "trim": 0.5}}
    exp = api.experiment(cfg)
    resp, _ = limb_response(exp, seed, 0)
    X, layout = oracle.regressors(exp, resp)
    assert [c.name for c in layout] == ["I", "B", "K"]        # constant coefficients: one regressor each
    clean = sims.simulate(without_torque_noise(exp), seed)
    y0 = np.asarray(clean.truth.signals["torque"], float)
    k_hats, noise_var = [], []
    for j in range(1, M + 1):
        trial = sims.simulate(exp, seed, replicate=j)       # same response, new noise
        e = torque_channel(trial) - torque_channel(clean)
        noise_var.append(np.mean(e ** 2))
        k_hats.append(oracle.fit_levels(X, y0 + e)[2])
    assert np.mean(noise_var) == pytest.approx(sigma ** 2, rel=0.02)   # the noise is what the bound assumes
    crb = oracle.crb_covariance(X, sigma ** 2)[2, 2]
    k_hats = np.asarray(k_hats)
    assert abs(k_hats.mean() - 40.0) < 4 * np.sqrt(crb / M)
    assert k_hats.var(ddof=1) == pytest.approx(crb, rel=0.25)


def test_oracle_errors_rows_and_ensembles():
    """The oracle's metrics over realizations. Fitted to ensembles of M = 4 realizations its variance is
    about 1/M of a single trial's (an unbiased fit: total error ~ 1/2); over R = 8 realizations (seed 0;
    each total error within about 20 %) the ensemble bound is below 0.8 times the single-trial one. The
    stacked fit of one realization twice is the fit of it once."""
    cfg = {**ELBOW, "sensors": {"torque": {"noise_variance_ratio": 0.1}}}
    exp = api.experiment(cfg)
    out = oracle.oracle_errors(exp, 0, realizations=8, discard=1.0, ensemble_size=4)
    assert set(out) == set(oracle.ORACLE_METRICS)
    assert all(np.isfinite(v) and v > 0 for v in out.values())
    assert out["oracle_total_error_ensemble"] < 0.8 * out["oracle_total_error"]
    d = oracle.realization_data(exp, 0, 1)
    assert np.allclose(oracle.oracle_estimate(exp, [d, d]), oracle.oracle_estimate(exp, [d]), rtol=1e-10)


def test_oracle_refuses_a_nonlinear_plant():
    exp = api.experiment({**ELBOW, "joint": "ankle_position_dependent"})
    assert "linear in its coefficients" in oracle.not_applicable(exp)
    assert oracle.not_applicable(api.experiment(ELBOW)) == ""


def test_efficiency_divides_by_the_matching_bound():
    rows = pd.DataFrame([
        {"estimator": "(scenario)", "cell": "c", "backend": "analytic", "metric": "oracle_total_error", "value": 0.5},
        {"estimator": "(scenario)", "cell": "c", "backend": "analytic", "metric": "oracle_total_error_ensemble",
         "value": 0.25}])
    table = pd.DataFrame([
        {"cell": "c", "backend": "analytic", "method": "sds", "tuning": "paper", "metric": "total_error", "value": 2.0},
        {"cell": "c", "backend": "analytic", "method": "sds (ensemble)", "tuning": "paper", "metric": "total_error",
         "value": 1.0},
        {"cell": "c", "backend": "analytic", "method": "kbr", "tuning": "paper", "metric": "total_error",
         "value": np.inf},
        {"cell": "d", "backend": "analytic", "method": "sds", "tuning": "paper", "metric": "total_error",
         "value": 1.0}])
    eff = oracle.efficiency(table, rows).set_index(["cell", "method"])["efficiency"]
    assert eff[("c", "sds")] == pytest.approx(4.0)
    assert eff[("c", "sds (ensemble)")] == pytest.approx(4.0)    # against the oracle fitted to ensembles
    assert np.isnan(eff[("c", "kbr")]) and np.isnan(eff[("d", "sds")])   # not finite; no oracle on d
    text = oracle.bound_text(oracle.efficiency(table, rows), "analytic")
    assert "span 4 to 4" in text and "Cramér–Rao" in text
