"""Issue 37: the velocity taken before decimation (the ``differentiate`` setting), the Chebyshev anti-alias filter of
MATLAB's ``decimate``, the parallel cascade's normal equations built once for a fixed delay, and parity with REKLAB's
``PC_stiffnessID`` on the five shared ankle trials (docs/reklab_parity.md; skipped where ../shared is absent)."""
from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.signal as sps

from jointbench import api, estimators
from jointbench.cli import estimate as cli_estimate
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import ConfigError, JointBenchError
from jointbench.core.signal import VELOCITY, decimate, resample_trial, velocity
from jointbench.core.types import Trial
from jointbench.estimators import _reflex as rx

REPO = Path(__file__).resolve().parents[1]
REKLAB = REPO.parent / "shared" / "data" / "reklab-ankle" / "ankle_stationary.npz"
shared = pytest.mark.skipif(not REKLAB.is_file(), reason="../shared/data/reklab-ankle absent (developers only)")


def load_script():
    spec = importlib.util.spec_from_file_location("reklab_parity", REPO / "docs" / "reklab_parity.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def parity_script():
    return load_script()


def simulated(perturbation: dict, seed: int = 0, duration: str = "40 s") -> Trial:
    """The simulated ankle of docs/reklab_parity.py (K 140, reflex gain 10), recorded at 1 kHz."""
    mod = load_script()
    return api.simulate({**mod.experiment(perturbation), "duration": duration}, seed=seed)


# ------------------------------------------------------------------------------------------- decimation
def test_chebyshev_decimation_is_matlabs_decimate():
    """filter='chebyshev' is the filter of MATLAB's and Octave's decimate (cheby1(8, 0.05, 0.8/q), forward and
    backward, every q-th sample from the first), as scipy.signal.decimate's IIR designs it: the same samples away
    from the ends (the edge padding differs), and not the FIR's."""
    rng = np.random.default_rng(3)
    x = sps.lfilter(*sps.butter(2, 0.1), rng.standard_normal(20000))
    ours = decimate(x, 10, filter="chebyshev")
    ref = sps.decimate(x, 10, ftype="iir", zero_phase=True)
    inner = slice(50, -50)
    assert ours.shape == ref.shape
    np.testing.assert_allclose(ours[inner], ref[inner], rtol=0, atol=1e-6 * np.abs(ref).max())
    assert np.abs(decimate(x, 10)[inner] - ref[inner]).max() > 1e-3 * np.abs(ref).max()
    with pytest.raises(JointBenchError, match="decimation filter"):
        decimate(x, 10, filter="butter")


def test_decimated_trial_keeps_the_velocity_of_the_recorded_rate():
    """resample_trial adds the angle's velocity taken before decimation: at 30 Hz, 1 kHz central differences are 1.8 %
    low, 100 Hz ones 50 % low; a second decimation keeps the first rate's velocity."""
    fs, f = 1000.0, 30.0
    t = np.arange(20000) / fs
    tr = Trial.from_arrays(0.01 * np.sin(2 * np.pi * f * t), np.zeros(t.size), fs)
    true_amp = 0.01 * 2 * np.pi * f
    for dec in (resample_trial(tr, 100.0), resample_trial(resample_trial(tr, 500.0), 100.0)):
        mid = slice(100, -100)
        amp = lambda v: np.sqrt(2) * np.std(v[mid])        # noqa: E731
        before, after = velocity(dec, "before_decimation"), velocity(dec, "after_decimation")
        assert VELOCITY in dec.channels and np.array_equal(before, dec.channels[VELOCITY])
        assert abs(amp(before) / true_amp - 1) < 0.03      # the FIR's pass band at 30 Hz and the 1 kHz difference
        assert abs(amp(after) / true_amp - (np.sin(2 * np.pi * f / 100) / (2 * np.pi * f / 100))) < 0.02
    assert np.array_equal(velocity(tr, "before_decimation"), velocity(tr, "after_decimation"))    # not decimated


def test_decimate_filter_argument_is_checked(tmp_path, capsys):
    """api.fit and jointbench estimate refuse an unknown filter in one line naming the argument as each knows it."""
    tr = Trial.from_arrays(np.sin(np.arange(4000) / 7.0), np.cos(np.arange(4000) / 7.0), 1000.0)
    with pytest.raises(ConfigError, match=r"^decimate_filter: expected one of 'fir', 'chebyshev'"):
        api.fit("irf2_ls", tr, decimate=10, decimate_filter="cheby")
    np.savez(tmp_path / "r.npz", time=tr.time, angle=tr.angle, torque=tr.torque)
    parser = argparse.ArgumentParser(prog="jointbench")
    cli_estimate.add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["estimate", "-e", "irf2_ls", "-i", str(tmp_path / "r.npz"), "-o",
                              str(tmp_path / "o.csv"), "--decimate", "10", "--decimate-filter", "cheby"])
    with pytest.raises(ConfigError, match=r"^--decimate-filter: expected one of"):
        args.func(args)


# ------------------------------------------------------------------------------------- the setting
MULTISINE = {"kind": "multisine", "period": "10 s", "f_min": "0.1 Hz", "f_max": "19.3 Hz", "spacing": "0.8 Hz",
             "corner": "6 Hz", "slope": -20, "rms": "0.02 rad", "quiet": "5 s"}


@pytest.fixture(scope="module")
def ankle():
    return simulated(MULTISINE)


@pytest.fixture(scope="module")
def ensemble(ankle):
    """Two realizations of the simulated ankle (the ensemble estimators' data), truth hidden."""
    other = api.simulate({**load_script().experiment(MULTISINE), "duration": "40 s"}, seed=0, realization=1)
    return Ensemble((ankle.replace(truth=None), other.replace(truth=None)), name="ankle")


def test_differentiate_before_decimation_is_the_default_and_the_more_accurate(ankle):
    """On the simulated ankle with a reflex (K 140 N.m/rad, gain 10 N.m.s/rad, a multisine to 19 Hz), recorded at
    1 kHz and fitted at 100 Hz: the velocity taken before decimation gives intrinsic K and the reflex gain nearer
    the truth than the one taken after (docs/reklab_parity.md: 5 seeds, three perturbations)."""
    for name in ("parallel_cascade", "tv_parallel_cascade", "guarin"):
        assert estimators.make(name).settings.differentiate == "before_decimation"
    err = {}
    for where in ("before_decimation", "after_decimation"):
        est = api.fit("parallel_cascade", ankle, settings={"differentiate": where}, decimate=10).estimate
        err[where] = (abs(float(est.stiffness(0.0)) / 140 - 1),
                      abs(float(np.sum(est.reflex_h) * est.nonlinearity.coef[0]) / 10 - 1))
    assert err["before_decimation"][0] < err["after_decimation"][0]
    assert err["before_decimation"][1] < 0.03 < err["after_decimation"][1]


@pytest.mark.parametrize("name, settings", [("parallel_cascade", {}),
                                            ("tv_parallel_cascade", {"n_basis": 3}),
                                            ("guarin", {"reflex": True, "n_basis": 3, "groups": 0})])
def test_prediction_uses_the_velocity_the_fit_used(ankle, ensemble, name, settings):
    """Without decimation both settings give the same estimate; with it they differ, and the pipeline's prediction
    of each record it was fitted on (its VAF) uses the velocity that fit used."""
    data = ankle.replace(truth=None) if name == "parallel_cascade" else ensemble
    where = ("before_decimation", "after_decimation")
    plain = [Trial.from_arrays(decimate(t.angle, 10), decimate(t.torque, 10), 100.0, name=t.name)
             for t in ([data] if isinstance(data, Trial) else data)]     # decimated elsewhere: one velocity
    plain = plain[0] if isinstance(data, Trial) else Ensemble(tuple(plain), name="plain")
    a, b = (api.fit(name, plain, settings={**settings, "differentiate": w}).estimate for w in where)
    np.testing.assert_array_equal(a.stiffness(a.time), b.stiffness(b.time))
    fits = {w: api.fit(name, data, settings={**settings, "differentiate": w}, decimate=10) for w in where}
    a, b = (f.estimate for f in fits.values())
    assert not np.allclose(a.stiffness(a.time), b.stiffness(b.time), rtol=1e-6)
    for w, f in fits.items():
        assert f.estimate.differentiate == w
        for t, p in zip(f.trials, f.predictions):
            yhat = f.estimate.predict(t.angle - t.angle.mean(), velocity(t, w))
            np.testing.assert_allclose(p.yhat, yhat, rtol=0, atol=1e-12 * np.abs(p.y).max())
        if name == "parallel_cascade":
            assert abs(f.predictions[0].vaf() - f.estimate.vaf_total) < 1e-9


# --------------------------------------------------------------------- normal equations: once for a fixed delay
def test_fixed_delay_builds_the_normal_equations_once(ankle, monkeypatch):
    """The second set of normal equations (the delay scan's, with the rectifier) is built only when the delay is
    searched and the pathway's nonlinearity is not the scan's; at the delay the search found, a fixed delay gives
    the same numbers."""
    tr = resample_trial(ankle.replace(truth=None), 100.0)
    calls = []
    build = rx.NormalEquations.build.__func__

    def counted(cls, *args, **kwargs):
        calls.append(args[-2].nonlinearity)
        return build(cls, *args, **kwargs)

    monkeypatch.setattr(rx.NormalEquations, "build", classmethod(counted))
    for nonlinearity, searched in (("polynomial", ["polynomial", "rectifier"]), ("rectifier", ["rectifier"])):
        calls.clear()
        found = estimators.make("parallel_cascade", {"nonlinearity": nonlinearity}).fit(tr)
        assert calls == searched
        calls.clear()
        fixed = estimators.make("parallel_cascade", {"nonlinearity": nonlinearity,
                                                     "delay": found.reflex_delay / tr.fs}).fit(tr)
        assert calls == [nonlinearity]
        assert fixed.reflex_delay == found.reflex_delay
        np.testing.assert_allclose(fixed.h, found.h, rtol=1e-9, atol=1e-12 * np.abs(found.h).max())
        np.testing.assert_allclose(fixed.reflex_h, found.reflex_h, rtol=1e-9,
                                   atol=1e-12 * np.abs(found.reflex_h).max())
        assert abs(fixed.vaf_total - found.vaf_total) < 1e-9


# -------------------------------------------------------------------------- parity with REKLAB (shared trials)
@pytest.fixture(scope="module")
def parity(parity_script):
    return parity_script.parity(REKLAB)


@shared
@pytest.mark.parametrize("record", ["z_pf", "z_pf2", "z_df", "z_df2", "z_df3"])
def test_parallel_cascade_matches_reklab(parity, record):
    """With REKLAB's settings, the velocity taken before decimation and MATLAB's decimation filter, intrinsic K
    within 3 % and the reflex gain within 10 % of PC_stiffnessID's (tools/reklab/pc_stiffnessID_rect.csv, run in
    GNU Octave), the total VAF within 1 point, the IRFs' shapes alike."""
    row = parity[(parity["config"] == "matched") & (parity["record"] == record)].iloc[0]
    assert abs(row["K_diff_pct"]) <= 3.0
    assert abs(row["gain_diff_pct"]) <= 10.0
    assert abs(row["vaf_diff"]) <= 1.0
    assert row["irf_corr_intrinsic"] > 0.98 and row["irf_corr_reflex"] > 0.85


@shared
def test_parity_page_is_the_scripts_output(parity_script, parity):
    """docs/reklab_parity.md shows what docs/reklab_parity.py computes now: its parity table and the table of
    configurations (regenerate with make parity-reklab)."""
    from jointbench.benchmarks.harness.pages import markdown_table

    text = (REPO / "docs" / "reklab_parity.md").read_text()
    assert markdown_table(parity_script.parity_table(parity)) in text
    assert markdown_table(parity_script.configs_table(parity)) in text


def test_reference_numbers_carry_their_provenance():
    """The reference CSV names the toolbox commit and the Octave it was run with, for the five trials."""
    ref = pd.read_csv(REPO / "tools" / "reklab" / "pc_stiffnessID_rect.csv")
    assert list(ref["trial"]) == ["z_pf", "z_pf2", "z_df", "z_df2", "z_df3"]
    assert ref["toolbox_commit"].str.fullmatch(r"[0-9a-f]{40}").all() and ref["octave"].notna().all()
    assert (ref["intrinsic_K"] < 0).all()             # the recorded torque's sign (docs/reklab_parity.py negates)


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
