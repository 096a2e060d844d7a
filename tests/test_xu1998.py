"""Xu & Hollerbach (1998) study: config, a smoke run of every part on a tiny subset, the scoring against
benchmarks.metrics, and how a case changes the configured experiment and estimator."""
from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from jointbench import estimators
from jointbench import sims
from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.locate import STUDIES
from jointbench.benchmarks.metrics import rmse, vafm, vafv
from jointbench.benchmarks.studies.xu1998 import protocol as X
from jointbench.benchmarks.study import run_study
from jointbench.core.ensemble import valid_mask
from jointbench.core.errors import ConfigError
from jointbench.core.schema import parse
from jointbench.core.types import Truth
from tests.golden import check_golden
from tests.harness_studies import study_copy

STUDY = STUDIES / "xu1998" / "study.yaml"


def _params(**kw) -> X.TrackParams:
    return parse(X.TrackParams, kw, "test")


@pytest.fixture(scope="module")
def study():
    return load_study("xu1998")


@pytest.fixture(scope="module")
def elbow(study):
    part = study.parts["fig2"]
    return (sims.Experiment.from_mapping(part.experiment, "test"),
            estimators.make("fsewls", part.estimators["fsewls"], "test"))


# ------------------------------------------------------------------------------------------- config
def test_config_parses_with_parts_checks_and_readings(study):
    assert set(study.parts) == {"fig2", "fig3", "fig3_angle_noise", "traces", "calibration", "arithmetic",
                                "readings"}
    ids = {c.id.split("-")[0] for c in study.checks}
    assert ids == {"X1", "X2", "X3", "X4", "X5", "X6", "X7", "X8", "X9"}
    assert all(c.part in study.parts for c in study.checks)
    assert {r.id for r in study.readings} >= {f"R{i}" for i in range(1, 23)}
    for name, part in study.parts.items():
        if name != "arithmetic":              # arithmetic on the paper's numbers: no simulation, one case
            assert len(part.seeds) >= 10, name
    fig2 = study.parts["fig2"]
    assert fig2.sweep["f_v"] == (0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0)
    assert set(fig2.sweep["condition"]) == {"posture", "movement"}
    assert study.parts["fig3"].sweep["nsr"] == (0, 0.05, 0.1, 0.15, 0.2, 0.3)
    variants = study.parts["readings"].params["variants"]
    assert set(study.parts["readings"].sweep["variant"]) == set(variants)
    for v in variants.values():     # every variant is a valid set of protocol parameters
        parse(X.TrackParams, v, "test")


def test_scored_window_is_40_s_and_whole_periods(study, elbow):
    exp, est = elbow
    assert exp.n == 48000 and exp.fs == 1000.0
    keep = X.scored_window(exp.n, exp.fs, _params().discard)
    assert keep.sum() == 40000 and est.transient() < 4.0
    fit = est.fit(sims.simulate(exp, 0))         # the estimate's own valid samples lie inside the window
    assert np.array_equal(X.scored_window(exp.n, exp.fs, _params().discard, valid_mask(fit)), keep)
    for f in study.parts["fig2"].sweep["f_v"] + (0.25, 0.5):
        assert abs(40 * f - round(40 * f)) < 1e-9, f   # a whole number of periods of K


# ------------------------------------------------------------------------------------- case changes
def test_case_experiment_follows_the_parameters(elbow):
    exp, _ = elbow
    e = X.case_experiment(exp, _params(condition="movement", f_v=1.5, zeta=0.1, nsr=0.2))
    assert e.joint.K.frequency == 1.5 and e.joint.K.mean == 40 and e.joint.K.amplitude == 15
    assert e.joint.damping_ratio == 0.1
    assert e.voluntary.movement_amplitude == 0.5 and e.voluntary.movement_frequency == 1.5
    assert e.sensors.torque.noise_variance_ratio == 0.2 and e.sensors.angle.noise_variance_ratio is None
    assert e.sensors.angle.filter == exp.sensors.angle.filter      # anti-aliasing filter kept
    p = X.case_experiment(exp, _params(condition="posture", f_v=0.5, shape="square", nsr=0.1, noise_on="angle"))
    assert type(p.joint.K).__name__ == "Square" and p.joint.K.frequency == 0.5
    assert not p.voluntary.moving
    assert p.sensors.angle.noise_variance_ratio == 0.1 and p.sensors.torque.noise_variance_ratio is None
    assert X.case_experiment(exp, _params(nsr=0)).sensors.torque.noise_variance_ratio is None


def test_case_estimator_overrides(elbow):
    _, est = elbow
    assert X.case_estimator(est, _params(condition="posture")).settings.highpass_cutoff is None     # R5
    assert X.case_estimator(est, _params(condition="posture", posture_highpass=True)).settings.highpass_cutoff == 1.0
    m = X.case_estimator(est, _params(condition="movement", svf_causal=True, svf_cutoff_means="a",
                                      estimator_settings={"forgetting": "23 1/s"}))
    assert m.settings.highpass_cutoff == 1.0 and m.settings.svf_causal and m.settings.svf_cutoff_means == "a"
    assert m.settings.forgetting == 23.0 and est.settings.forgetting == 20.0   # the configured one untouched
    with pytest.raises(ConfigError, match="unknown key 'forgeting'"):
        X.case_estimator(est, _params(estimator_settings={"forgeting": 23}))
    v = X.resolve_variant(_params(variants={"c": {"svf_causal": True}}, variant="c"))
    assert v.svf_causal is True and v.variant == "c"
    with pytest.raises(ConfigError, match="variant"):
        _params(variants={}, variant="nope")


# ------------------------------------------------------------------------------------------- scoring
def test_scores_use_the_metrics_of_eq_8():
    n, dt = 2000, 1e-3
    t = np.arange(n) * dt
    truth = Truth(I=0.06, B=0.9 + 0.1 * np.sin(2 * np.pi * t), K=40 + 15 * np.sin(2 * np.pi * t))
    rng = np.random.default_rng(1)

    @dataclasses.dataclass
    class Fit:
        I: np.ndarray
        B: np.ndarray
        K: np.ndarray

        def damping_ratio(self):
            return self.B / (2 * np.sqrt(self.K * self.I))

    fit = Fit(I=0.06 + 0.01 * rng.standard_normal(n), B=truth.B * 0.9, K=truth.K - 1 + rng.standard_normal(n))
    keep = np.zeros(n, bool)
    keep[200:1800] = True
    s = X._scores(fit, truth, keep, dt)
    K, Kh = truth.K[keep], fit.K[keep]
    assert s["vafm_K"] == pytest.approx(vafm(K, Kh)) and s["vafv_K"] == pytest.approx(vafv(K, Kh, dt))
    assert s["rmse_K"] == pytest.approx(rmse(K, Kh))
    assert s["mean_err_K"] == pytest.approx(Kh.mean() - K.mean()) and s["mean_K"] == pytest.approx(Kh.mean())
    # the constant inertia: floor of 1 on the integral (eq. 8 rule), i.e. 100 (1 - int I~_hat^2 dt)
    Ih = fit.I[keep]
    assert s["vafv_I"] == pytest.approx(100 * (1 - np.sum((Ih - Ih.mean()) ** 2) * dt))
    assert s["abs_err_pct_I"] == pytest.approx(abs(100 * (Ih.mean() - 0.06) / 0.06))


def test_frozen_model_interpolates_as_numpy_interp():
    """At the grid's own instants the values themselves (copies), elsewhere np.interp: the same numbers."""
    rng = np.random.default_rng(4)
    t = np.arange(500) * (1 / 1000.0)
    model = X._Frozen(t, *(rng.standard_normal(500) for _ in range(3)))
    for at in (t, t[:-1] + 0.0005, np.arange(500) / 1000.0, np.array([-1.0, 0.2501, 9.0])):
        got = model.coefficients_at(at)
        for g, v in zip(got, (model.I, model.B, model.K)):
            assert np.array_equal(g, np.interp(at, t, v))
    assert not np.shares_memory(model.coefficients_at(t)[2], model.K)


def test_output_vafs_of_a_subset_are_those_of_all(elbow):
    exp, est = elbow
    exp = X.case_experiment(dataclasses.replace(exp, duration=14.0), _params(f_v=0.5))
    trial = sims.simulate(exp, 0)
    fit = est.fit(trial)
    keep = X.scored_window(trial.n, trial.fs, 4.0, valid_mask(fit))
    full = X.output_vafs(fit, trial, keep)
    assert set(full) == set(X.OUTPUTS)
    for name in X.OUTPUTS:
        assert X.output_vafs(fit, trial, keep, signals=(name,)) == {name: full[name]}


# ----------------------------------------------------------------------------------------- smoke run
@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    """Every part on a tiny subset: 1 seed, 14 s records (5 s scored), reduced sweeps."""
    tmp = tmp_path_factory.mktemp("xu1998")

    def edit(d):
        for part in d["parts"].values():
            part["seeds"] = 1
            if "experiment" in part:           # part arithmetic simulates nothing
                part["experiment"] = {**part["experiment"], "duration": "14 s"}
        d["parts"]["fig2"]["sweep"] = {"condition": ["posture", "movement"], "f_v": [0.5, 1.5]}
        d["parts"]["fig3"]["sweep"] = {"nsr": [0, 0.2]}
        d["parts"]["fig3_angle_noise"]["sweep"] = {"nsr": [0.2]}
        d["parts"]["traces"]["sweep"] = {"shape": ["sine", "square"], "condition": ["posture"]}
        d["parts"]["readings"]["sweep"] = {"variant": ["chosen", "causal_L"], "condition": ["movement"],
                                           "f_v": [0.5]}
    path = study_copy(tmp, "xu1998", edit, name="study.yaml")
    return run_study(path, out_root=tmp / "results", serial=True, progress=False)


def test_smoke_run_writes_every_output(smoke):
    assert not smoke.failed, [r.error for r in smoke.failed]
    folder = smoke.folder
    for name in ("checks.csv", "cases.csv", "curves.csv.gz", "report.md", "fig2.png", "fig2_traces.png",
                 "fig3.png", "fig3_traces.png", "fig3_angle_noise.png", "traces_sine.png", "traces_square.png",
                 "calibration.png", "readings.png"):
        assert (folder / name).is_file(), name
    comp = pd.read_csv(folder / "checks.csv")
    assert list(comp["check"]) == [c.id for c in load_study("xu1998").checks]
    check_golden("xu1998", smoke.checks)
    text = (folder / "report.md").read_text()
    for r in load_study("xu1998").readings:
        assert f"**{r.id}. {r.topic}.**" in text
    assert "What each reading gives" in text and "Output VAF by candidate signal" in text


def test_smoke_run_metrics(smoke):
    rows = smoke.rows
    fig2 = rows[rows["part"] == "fig2"]
    for m in ("vafm_K", "vafv_K", "vafm_B", "vafv_B", "vafm_I", "vafv_I", "rmse_K", "rmse_B", "rmse_I",
              "mean_K", "true_mean_K", "mean_err_K", "vaf_output", "vaf_output_filtered_torque",
              "vaf_output_torque", "vaf_output_angle", "mean_zeta"):
        assert (fig2["metric"] == m).sum() == 4, m
    assert set(fig2["estimator"]) == {"fsewls"} and set(fig2["condition"]) == {"posture", "movement"}
    v = fig2[(fig2["metric"] == "vafv_K") & (fig2["condition"] == "posture")].set_index("f_v")["value"]
    assert 80 < v[0.5] <= 100 and v[1.5] < v[0.5]        # tracking falls with f_v
    out = fig2[fig2["metric"] == "vaf_output"]["value"]
    assert (out == fig2[fig2["metric"] == "vaf_output_filtered_torque"]["value"].to_numpy()).all()   # R4
    fig3 = rows[rows["part"] == "fig3"]
    drop = fig3[fig3["metric"] == "drop_vafv_K"].set_index("nsr")["value"]
    assert drop[0] == 0 and drop[0.2] > 0
    cal = rows[(rows["part"] == "calibration") & (rows["metric"] == "true_mean_I")]["value"]
    assert cal.iloc[0] == pytest.approx(0.0687)
    assert set(rows[rows["part"] == "readings"]["variant"]) == {"chosen", "causal_L"}
