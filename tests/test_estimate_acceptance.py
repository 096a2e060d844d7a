"""Acceptance of ``jointbench estimate`` on held-out simulated recordings (issue 13).

* With default settings every printed VAF lies in [0, 100] and within 2 points of the VAF computed
  here, independently, from the written outputs (the IRF, the FRF or I, B, K and the input file,
  following docs/estimate.md; the multisine methods from OUT_prediction.csv).
* The 95 % intervals of I, B, K cover the truth in at least 90 % of 50 seeded repetitions and are not
  more than twice as wide as the spread of the estimates (mean half-width <= 2 x 1.96 x their SD).

Records come from ``tests/estimate_data.py`` (sims), never from ../shared.
"""
from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest
from scipy import signal as sps

from jointbench import estimators
from tests.estimate_data import (LTI_TRUTH, gated_wrist, lti_ankle, one_blas_thread_per_test,  # noqa: F401 (autouse)
                                  run, save, tv_elbow)

TOL = 2.0   # points of VAF between the printed and the recomputed value (issue 13)



def printed_vafs(text: str) -> list[float]:
    block = text.split("VAF of the predicted torque", 1)[1].split("wrote:", 1)[0]
    return [float(m) for m in re.findall(r"^\s+\S+\s+(-?[\d.]+|nan) %$", block, re.M)]


def vaf(y, yhat) -> float:
    return float(100 * (1 - np.var(y - yhat) / np.var(y)))


def independent_vaf(name: str, rec, out) -> float:
    """The VAF of docs/estimate.md, recomputed from the written files and the record."""
    u = rec.angle - rec.angle.mean()
    y = rec.torque - rec.torque.mean()
    n, fs = len(u), rec.fs
    if name in ("irf2_ls", "irf2_corr"):
        irf = pd.read_csv(out.with_name(out.stem + "_irf.csv"))
        lags, h = irf["lag"].to_numpy(), irf["h"].to_numpy()
        m1, m2 = -int(lags[0]), int(lags[-1])
        yhat = sps.lfilter(h, [1.0], np.concatenate([u, np.zeros(m1)]))[m1:]     # sum_k h(k) u(t - k)
        return vaf(y[m2:n - m1], yhat[m2:n - m1])
    if name == "spectral":
        frf = pd.read_csv(out.with_name(out.stem + "_frf.csv"))
        f = frf["freq_hz"].to_numpy()
        H = np.where(frf["significant"], frf["re"] + 1j * frf["im"], 0)
        fr = np.fft.rfftfreq(n, 1 / fs)
        Hr = np.interp(fr, f, H.real) + 1j * np.interp(fr, f, H.imag)
        Hr[fr < f[1]] = H[1].real
        yhat = np.fft.irfft(np.fft.rfft(u) * Hr, n)
        half = int(round(fs / f[1])) // 2
        return vaf(y[half:n - half], yhat[half:n - half])
    if name in ("ibk_irf", "ibk_spectral"):
        p = pd.read_csv(out).iloc[0]
        sos = sps.butter(4, 20.0, fs=fs, output="sos")          # the fitted band: 0 ... 20 Hz, zero phase
        uf, yf = sps.sosfiltfilt(sos, u), sps.sosfiltfilt(sos, y)
        du = np.gradient(uf, 1 / fs)
        yhat = p["K"] * uf + p["B"] * du + p["I"] * np.gradient(du, 1 / fs)
        edge = int(np.ceil(2 * fs / 20.0))
        return vaf(yf[edge:n - edge], yhat[edge:n - edge])
    if name == "fsewls":
        frame = pd.read_csv(out)
        steady = frame["steady"].to_numpy(bool)
        return vaf(frame["filtered_torque"][steady], frame["predicted_filtered_torque"][steady])
    pred = pd.read_csv(out.with_name(out.stem + "_prediction.csv"))
    used = pred["in_vaf"].to_numpy(bool)
    return vaf(pred["torque"][used], pred["predicted_torque"][used])


CASES = [("lti", name) for name in ("irf2_ls", "irf2_corr", "spectral", "ibk_spectral", "ibk_irf", "fsewls")]
CASES += [("tv", "fsewls"), ("gated", "skirt"), ("gated", "kbr")]
RECORDS = {"lti": lambda: lti_ankle(101, duration=30.0), "tv": lambda: tv_elbow(102),
           "gated": lambda: gated_wrist(103)}


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    folder = tmp_path_factory.mktemp("records")
    out = {}
    for kind, make in RECORDS.items():
        t = make()
        out[kind] = (t, save(folder / f"{kind}.npz", t))
    return out


@pytest.mark.parametrize("kind, name", CASES)
def test_default_vaf_is_meaningful_and_reproducible(records, tmp_path, kind, name):
    rec, path = records[kind]
    out = tmp_path / "est.csv"
    code, text, err = run(["-e", name, "-i", path, "-o", out])
    assert code == 0, err
    (printed,) = printed_vafs(text)
    assert 0.0 <= printed <= 100.0, (name, printed)
    if kind == "gated":          # the command fitted the whole periods of the multisine it found
        assert "gated multisine" in text
    recomputed = independent_vaf(name, rec, out)
    assert abs(printed - recomputed) <= TOL, (name, printed, recomputed)
    pred = pd.read_csv(out.with_name("est_prediction.csv"))
    used = pred["in_vaf"].to_numpy(bool)
    assert vaf(pred["torque"][used], pred["predicted_torque"][used]) == pytest.approx(printed, abs=0.051)


# ------------------------------------------------------------------------------------------ intervals
def coverage(reps: int, duration: float) -> dict[tuple[str, str], tuple[float, float]]:
    """(coverage, mean half-width / (1.96 SD of the estimates)) per (estimator, parameter)."""
    got = {}
    for seed in range(reps):
        t = lti_ankle(1000 + seed, duration=duration)
        for name in ("ibk_irf", "ibk_spectral"):
            est = estimators.make(name).fit(t)
            for k in "IBK":
                lo, hi = est.intervals.bounds[k]
                got.setdefault((name, k), []).append((getattr(est, k), lo, hi))
    out = {}
    for key, rows in got.items():
        v, lo, hi = np.array(rows).T
        truth = LTI_TRUTH[key[1]]
        out[key] = (float(np.mean((lo <= truth) & (truth <= hi))),
                    float(np.mean(hi - lo) / 2 / (1.96 * np.std(v, ddof=1))))
    return out


def check_coverage(result):
    for key, (cov, ratio) in result.items():
        assert cov >= 0.90, (key, cov, ratio)
        assert ratio <= 2.0, (key, cov, ratio)


def test_intervals_cover_the_truth():
    check_coverage(coverage(reps=50, duration=10.0))


@pytest.mark.slow
def test_intervals_cover_the_truth_long_records():
    check_coverage(coverage(reps=100, duration=30.0))
