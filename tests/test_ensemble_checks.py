"""Ensembles accepted silently when wrong (issue 20): each refused in one line; the ensemble estimators' bands.

Cases of the issue: an NPZ with realizations x samples (transposed), an ensemble whose time is in ms
(``ensemble_irf`` and ``guarin`` rounded the 40 ms lags at 1 Hz to no lag: a zero-lag IRF), a 12-sample
ensemble (stiffness -697 ... 2289 for a simulated 70 ... 130).
"""
import numpy as np
import pytest

from jointbench import estimators
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.estimators._resample import MIN_REALIZATIONS
from tests.estimate_data import one_blas_thread_per_test, run  # noqa: F401 (autouse fixture)
from tests.test_ensemble_estimators import FS, ensemble_of, true_irf

ENSEMBLE = ("ensemble_irf", "sds", "guarin")
SMALL = {"ensemble_irf": {}, "sds": {"window": 0.5}, "guarin": {"n_basis": 5}}


def as_ms(ens: Ensemble) -> Ensemble:
    """The same ensemble with its time read in milliseconds as seconds (the rate 1000 times too low)."""
    return Ensemble.from_arrays(ens.inputs, ens.outputs, ens.fs / 1000.0, name="ms")


@pytest.mark.parametrize("name", ENSEMBLE)
def test_time_in_ms_is_refused(name):
    ens = as_ms(ensemble_of(true_irf(), 300, 12))
    with pytest.raises(InputError, match=rf"^{name}: ensemble 'ms': lag_before = 0\.04 s is less than half a sample "
                                         r"at 0\.1 Hz.*milliseconds"):
        estimators.make(name, SMALL[name]).fit(ens)


def test_transposed_arrays_are_refused():
    ens = ensemble_of(true_irf(), 300, 12)
    with pytest.raises(InputError, match=r"12 x 300, fewer samples than realizations: transposed"):
        Ensemble.from_arrays(ens.inputs.T, ens.outputs.T, FS)


@pytest.mark.parametrize("name", ENSEMBLE)
def test_a_12_sample_ensemble_is_refused(name):
    """12 samples at 100 Hz with lags +-40 ms (9 lags): at most 4 samples whose lags lie in the record."""
    ens = ensemble_of(true_irf(), 12, 10)
    with pytest.raises(InputError, match=rf"^{name}: .*(samples|window|basis)"):
        estimators.make(name).fit(ens)


def test_ensemble_irf_needs_twice_the_lags():
    with pytest.raises(InputError, match=r"16 samples per realization: the 9 lags and 0 pooled samples leave 8 .*"
                                         r"need 17 samples"):
        estimators.make("ensemble_irf").fit(ensemble_of(true_irf(), 16, 10))
    estimators.make("ensemble_irf").fit(ensemble_of(true_irf(), 17, 10))


def test_command_refuses_the_catalogue_cases(tmp_path):
    ens = ensemble_of(true_irf(), 300, 12)
    cases = {"t.npz": dict(angle=ens.inputs.T, torque=ens.outputs.T, time=ens.time),
             "ms.npz": dict(angle=ens.inputs, torque=ens.outputs, time=ens.time * 1000.0)}
    for file, arrays in cases.items():
        np.savez(tmp_path / file, **arrays)
        for name in ("ensemble_irf", "guarin"):
            code, out, err = run(["-e", name, "-i", tmp_path / file, "-o", tmp_path / "e.csv"])
            assert code != 0 and len(err.strip().splitlines()) == 1, (file, name, err)
            assert not (tmp_path / "e.csv").exists()


# ------------------------------------------------------------------------------------------ the bands
@pytest.mark.parametrize("name", ENSEMBLE)
def test_jackknife_band_is_reproducible(name):
    ens = ensemble_of(true_irf(), 200, 12, noise=0.2)
    a = estimators.make(name, {**SMALL[name], "groups": 6}).fit(ens)
    b = estimators.make(name, {**SMALL[name], "groups": 6}).fit(ens)
    c = estimators.make(name, {**SMALL[name], "groups": 12}).fit(ens)
    lo, hi = a.intervals.bounds["stiffness"]
    assert np.array_equal(lo, b.intervals.bounds["stiffness"][0])
    assert not np.array_equal(lo, c.intervals.bounds["stiffness"][0])
    assert np.all(hi > lo)
    frame = a.to_frame()
    assert {"stiffness_lo", "stiffness_hi"} <= set(frame.columns)
    assert "jackknife over the 12 realizations (6 groups" in a.intervals.method


@pytest.mark.parametrize("name", ENSEMBLE)
def test_no_band_from_too_few_realizations_or_none_asked(name):
    ens = ensemble_of(true_irf(), 200, MIN_REALIZATIONS - 1, noise=0.2)
    few = {"pool": 0.01} if name == "ensemble_irf" else {}          # 7 realizations x 3 samples >= 9 lags
    assert estimators.make(name, {**SMALL[name], **few, "groups": 6}).fit(ens).intervals is None
    ens = ensemble_of(true_irf(), 200, 12, noise=0.2)
    assert estimators.make(name, {**SMALL[name], "groups": 0}).fit(ens).intervals is None
