"""The input's band (jointbench.core.band): one definition of an excited frequency, the band of the most power.

The symptom (issue 33): fsewls on a real ankle recording (~106 s at 1 kHz, perturbation below 3.7 Hz) reported
the input's band as "235.5 ... 500 Hz". The record here is of that kind: a low-pass random angle below
3.7 Hz at 1 kHz, plus the servo's broadband jitter (white, microradians to a milliradian); the torque of a
second-order joint (I 0.015, B 0.8, K 150) to that angle, plus white noise and a 60 Hz hum. ``I w^2`` makes
the jitter coherent with the torque at hundreds of frequencies up to 500 Hz: more than the perturbation's
band has, so a band chosen by its count of excited frequencies is the jitter's.
"""
from pathlib import Path

import numpy as np
import pytest
from scipy import signal as sps

from jointbench import api, estimators
from jointbench.core import band
from jointbench.core.estimate import FRFEstimate
from jointbench.core.types import Trial
from jointbench.estimators._band import band_of_trials, welch_of_trials
from tests.estimate_data import one_blas_thread_per_test, run, save  # noqa: F401 (autouse fixture)

ANKLE = Path(__file__).resolve().parents[2] / "shared" / "data" / "reklab-ankle" / "ankle_stationary.npz"


def low_band(seed: int, jitter: float = 2e-5, duration: float = 106.0, fs: float = 1000.0) -> Trial:
    """Angle low-passed below 3.7 Hz (0.03 rad RMS) plus ``jitter`` rad RMS white; torque of the joint plus
    5 % white noise and a 60 Hz hum of 5 % of its RMS."""
    rng = np.random.default_rng(seed)
    n = int(round(duration * fs))
    b, a = sps.butter(8, 3.7 / (fs / 2))
    angle = sps.filtfilt(b, a, rng.standard_normal(n + 2000))[1000:-1000]
    angle = 0.03 * angle / angle.std() + jitter * rng.standard_normal(n)
    d1 = np.gradient(angle, 1 / fs)
    torque = 0.015 * np.gradient(d1, 1 / fs) + 0.8 * d1 + 150.0 * angle
    t = np.arange(n) / fs
    torque += 0.05 * torque.std() * (rng.standard_normal(n) + np.sin(2 * np.pi * 60.0 * t))
    return Trial.from_arrays(angle, torque, fs, name=f"low{seed}")


def strongest(frf: FRFEstimate) -> float:
    return float(frf.freq[np.argmax(frf.input_power)])


@pytest.mark.parametrize("jitter", [2e-5, 1e-3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_band_of_a_low_band_record_is_low(seed, jitter):
    frf = welch_of_trials("x", [low_band(seed, jitter)])
    found = band.input_band(frf)
    assert found.lo <= 0.5 and 3.5 <= found.hi <= 15.0, found.text()
    assert found.lo <= strongest(frf) <= found.hi


def test_the_record_holds_the_trap():
    """With a milliradian of jitter, the input has power and coherence at hundreds of frequencies above 50 Hz
    (the count rule's band): only the power tells the perturbation's band."""
    frf = welch_of_trials("x", [low_band(0, 1e-3)])
    ex = band.excited(frf.input_power, frf.coherence, frf.n_averages)
    assert np.count_nonzero(ex & (frf.freq > 50)) > 10 * np.count_nonzero(ex & (frf.freq < 15))
    # the input's power unknown: every frequency with coherence counts, groups ranked by their count (the rule
    # fsewls printed "235.5 ... 500 Hz" with): the jitter's band
    count_rule = band.input_band(FRFEstimate(freq=frf.freq, H=frf.H, coherence=frf.coherence, fs=frf.fs,
                                             time=frf.time, n_averages=frf.n_averages))
    assert count_rule.lo > 15, count_rule.text()


def test_fsewls_reports_the_low_band_through_the_api_and_the_cli(tmp_path):
    tr = low_band(3, 1e-3, duration=60.0)
    fit = api.fit("fsewls", tr)
    text = fit.estimate.fit_info["band"]
    assert "the high-passed input's band 0 ..." in text, text
    hi = float(text.split("the high-passed input's band 0 ... ")[1].split(" Hz")[0])
    assert hi <= 15.0, text
    code, out, err = run(["-e", "fsewls", "-i", save(tmp_path / "low.npz", tr), "-o", tmp_path / "fit.csv"])
    assert code == 0, err
    assert f"the high-passed input's band 0 ... {hi:g} Hz" in out


def test_the_threshold_and_its_edges():
    assert band.coherence_threshold(2) == pytest.approx(0.95)
    assert band.coherence_threshold(11) == pytest.approx(1 - 0.05 ** 0.1)
    coh = np.array([0.0, 0.2, 0.5, 1.0])
    assert band.significant(coh, None).tolist() == [False, True, True, True]   # unknown averages: coh > 0
    assert band.significant(coh, 1).tolist() == [False, True, True, True]      # one: no test (as before)
    assert band.significant(coh, 11).tolist() == [False, False, True, True]
    assert band.has_power(np.array([1.0, 1e-7, 2e-6])).tolist() == [True, False, True]


@pytest.mark.skipif(not ANKLE.exists(), reason="../shared/data/reklab-ankle is not beside this checkout")
@pytest.mark.parametrize("key", ["z_pf", "z_df"])
def test_a_real_ankle_records_band_holds_its_strongest_frequency(key):
    d = np.load(ANKLE)
    x = d[key]
    tr = Trial.from_arrays(x[:, 0], x[:, 1], float(d["fs"]), name=key)
    frf = welch_of_trials("x", [tr])
    found = band_of_trials("x", [tr])
    assert found is not None and found.lo <= strongest(frf) <= found.hi
    est = estimators.make("spectral").fit(tr)
    assert band.input_band(est) == found           # the spectral estimate and the band check agree

