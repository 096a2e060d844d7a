"""Smoke run of the whole Westwick & Perreault (2012) study, and estimator recovery through the simulator."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from jointbench import estimators
from jointbench import sims
from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.study import run_study
from tests.golden import check_golden
from tests.test_harness import write_study


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("w2012")

    def fewer_seeds(d):
        for part in d["parts"].values():
            if "seeds" in part:
                part["seeds"] = 2
    return run_study(write_study(tmp, fewer_seeds), out_root=tmp / "results", workers=2, progress=False)


def test_study_writes_every_output(smoke):
    folder = smoke.folder
    for name in ("checks.csv", "cases.csv", "curves.csv.gz", "report.md", "fig2.png", "fig3.png",
                 "fig4.png", "fig5.png", "fig6_ibk_spectral.png", "fig7.png", "fig8.png"):
        assert (folder / name).is_file(), name
    comp = pd.read_csv(folder / "checks.csv")
    assert list(comp.columns[:9]) == ["check", "description", "published", "reproduced", "low", "high", "status",
                                      "evidence", "reading"]
    assert list(comp["check"]) == [c.id for c in load_study("westwick2012").checks]
    cases = pd.read_csv(folder / "cases.csv")
    for col in ("study", "part", "seed", "estimator", "metric", "value", "wall_time_s", "git_commit"):
        assert col in cases.columns
    assert not smoke.failed


def test_smoke_outcome_is_pinned(smoke):
    """Every check's status in this smoke run is pinned: a check that flips fails here."""
    check_golden("westwick2012", smoke.checks)


def test_analytic_checks_pass(smoke):
    comp = smoke.checks.set_index("check")
    for check in comp.index:
        if check[:2] in ("W1", "W2", "W3"):
            assert comp.loc[check, "status"] == "pass", check


def test_report_lists_misses_with_reasons_and_every_reading(smoke):
    text = (smoke.folder / "report.md").read_text()
    for r in load_study("westwick2012").readings:
        assert f"**{r.id}. {r.topic}.**" in text
    for row in smoke.checks.itertuples():
        if row.status == "miss":
            assert f"**{row.check}**" in text and row.note, row.check


def _noisy_elbow(seed: int):
    """The Fig. 6 elbow on the servo, with encoder quantisation, torque noise and no torque filter."""
    exp = load_study("westwick2012").parts["fig6"].experiment
    exp = {**exp, "voluntary": {"mean": 3.5, "rms": 0.02, "cutoff": "1 Hz"},
           "sensors": {"angle": {"quantization": "6.28e-5 rad"}, "torque": {"noise_rms": 0.05}}}
    return sims.simulate(sims.Experiment.from_mapping(exp, "test"), seed)


@pytest.mark.parametrize("name, settings, tol", [
    ("ibk_spectral", {"fmax": "20 Hz"}, 0.02),
    ("ibk_irf", {"bandlimit": "20 Hz"}, 0.02),
    # The correlation (Toeplitz) IRF treats the angle as zero outside the record (biased
    # correlations): an end effect of order M/N times the large inertial torque, a few percent on K.
    ("ibk_irf", {"bandlimit": "20 Hz", "irf_method": "corr"}, 0.08),
])
def test_parametric_estimators_recover_simulated_elbow(name, settings, tol):
    trial = _noisy_elbow(seed=11)
    est = estimators.make(name, settings).fit(trial)
    for p, true in (("I", 0.171), ("B", 1.22), ("K", 53.5)):
        assert abs(getattr(est, p) / true - 1) < tol, (p, getattr(est, p))


def test_same_seed_same_trial_and_estimate():
    a, b = _noisy_elbow(3), _noisy_elbow(3)
    assert np.array_equal(a.angle, b.angle) and np.array_equal(a.torque, b.torque)
    ea = estimators.make("ibk_spectral").fit(a)
    eb = estimators.make("ibk_spectral").fit(b)
    assert (ea.I, ea.B, ea.K) == (eb.I, eb.B, eb.K)
