"""FSEWLS (Xu & Hollerbach 1998): recovery on a simulated elbow, RK4 recursion, readings, errors.

The elbow ``I theta'' + B(t) theta' + K(t) theta = tau`` is simulated here (not with ``sims``) by
classical RK4 at 10 kHz and sampled at 1 kHz. The torque is a random binary sequence of +-4 N m with
a 10 ms clock whose switches fall half-way between two 1 kHz samples (as with a DAC clock not locked
to the ADC): a switch exactly at a sample, taken right-continuous, would make the sampled torque lead
the angle by half a sample at low frequencies (1.5 % residual of the regression at 1 kHz).
"""
import dataclasses
import math

import numpy as np
import pytest
import scipy.signal as sps

from jointbench import estimators
from jointbench.benchmarks.metrics import vafv
from jointbench.estimators._fsewls_kernels import (UPPER3, ewls, ewls_riccati_rk4, forcing, highpass,
                                                  highpass_time_constant, rk4_coefficients, solve_spd3, svf, svf_pole,
                                                  unpack)
from jointbench.estimators.fsewls import FSEWLS, FSEWLSEstimate
from jointbench.core.errors import ConfigError, InputError
from jointbench.core.types import Trial

FS, I0, ZETA = 1000.0, 0.06, 0.3


def simulate(duration: float, k_amp: float = 0.0, f_v: float = 0.0, seed: int = 0, sub: int = 10):
    """``(time, angle, torque, K, B)`` at 1 kHz; ``K = 40 + k_amp sin(2 pi f_v t)``, ``B = 2 zeta sqrt(K I)``."""
    n = int(round(duration * FS))
    per = int(round(0.01 * FS * sub))                       # fine steps per 10 ms clock
    off = per - sub // 2                                    # switch half a sample after a 1 kHz sample
    levels = (4.0 * np.random.default_rng(seed).choice([-1.0, 1.0], (n * sub + off) // per + 1)).tolist()
    h, w = 1.0 / (FS * sub), 2 * math.pi * f_v

    def accel(t, x, v, u):
        k = 40.0 + k_amp * math.sin(w * t)
        return (u - 2 * ZETA * math.sqrt(k * I0) * v - k * x) / I0

    theta, tau = np.empty(n), np.empty(n)
    x = v = 0.0
    for i in range(n):
        theta[i], tau[i] = x, levels[(i * sub + off) // per]
        for j in range(i * sub, (i + 1) * sub):
            t, u = j * h, levels[(j + off) // per]
            a1 = accel(t, x, v, u)
            a2 = accel(t + h / 2, x + h / 2 * v, v + h / 2 * a1, u)
            a3 = accel(t + h / 2, x + h / 2 * (v + h / 2 * a1), v + h / 2 * a2, u)
            a4 = accel(t + h, x + h * (v + h / 2 * a2), v + h * a3, u)
            x, v = (x + h * v + h * h / 6 * (a1 + a2 + a3),
                    v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4))
    time = np.arange(n) / FS
    K = 40.0 + k_amp * np.sin(w * time)
    return time, theta, tau, K, 2 * ZETA * np.sqrt(K * I0)


@pytest.fixture(scope="module")
def steady_elbow():
    """12 s, time-invariant (K = 40, B = 0.294), noise-free, torque-driven."""
    _, theta, tau, K, B = simulate(12.0, seed=1)
    return Trial.from_arrays(theta, tau, FS, imposed="torque", name="elbow"), (I0, B[0], K[0])


@pytest.fixture(scope="module")
def slow_elbow():
    """20 s, K = 40 + 15 sin(2 pi 0.05 t)."""
    _, theta, tau, K, B = simulate(20.0, k_amp=15.0, f_v=0.05, seed=2)
    return Trial.from_arrays(theta, tau, FS, imposed="torque", name="slow"), K


# -------------------------------------------------------------------------------------- recovery
READINGS = {"default": {}, "a": {"svf_cutoff_means": "a"}, "causal": {"svf_causal": True},
            "causal-a": {"svf_causal": True, "svf_cutoff_means": "a"}, "no-highpass": {"highpass_cutoff": None}}


def est_settings(settings):
    return estimators.make("fsewls", settings).settings


@pytest.mark.parametrize("reading", READINGS)
def test_time_invariant_elbow_recovered_within_1_percent(steady_elbow, reading):
    trial, truth = steady_elbow
    est = estimators.make("fsewls", READINGS[reading]).fit(trial)
    keep = est.steady()  # default: 3.50 s discarded at each end (transient), 3.5 ... 8.5 s scored
    assert est.transient == pytest.approx(FSEWLS(est_settings(READINGS[reading])).transient())
    assert keep.sum() >= 4000
    for got, want in zip((est.I, est.B, est.K), truth):
        assert np.abs(got[keep] / want - 1).max() < 0.01, reading
    assert est.output_vaf() > 99.9


def test_default_pole_and_transient():
    est = estimators.make("fsewls")
    assert highpass_time_constant(1.0, 4, 0.5) == pytest.approx(0.966, abs=0.01)
    a = 2 * np.pi * 3.2 / np.sqrt(2 ** (1 / 3) - 1)
    assert est.pole() == pytest.approx(a) and a == pytest.approx(39.44, abs=0.01)
    assert est.transient() == pytest.approx(3 * highpass_time_constant(1.0, 4, 0.5) + 10 / a + 7 / 20)
    assert estimators.make("fsewls", {"svf_cutoff_means": "a"}).pole() == pytest.approx(2 * np.pi * 3.2)


def test_slowly_varying_stiffness_tracked(slow_elbow):
    trial, K = slow_elbow
    est = estimators.make("fsewls").fit(trial)
    keep = est.steady()
    assert vafv(K[keep], est.K[keep], 1 / FS) >= 95.0
    assert np.abs(est.K[keep] - K[keep]).max() < 2.0   # N m/rad, on a 15 N m/rad swing


def test_highpass_removes_offset_and_trend_up_to_the_ends():
    t = np.arange(12000) / FS
    x = np.stack([np.full_like(t, 0.3), 0.3 + 0.05 * t])
    assert np.abs(highpass(x, FS, 1.0, 4, 0.5)).max() < 1e-6


def test_offset_and_slow_voluntary_movement_do_not_disturb_the_fit(steady_elbow):
    """Posture offset plus theta_n = 0.5 sin(2 pi 0.2 t + 1) with its voluntary torque I theta_n'' + B theta_n'
    + K theta_n (not at rest at either end): the high-pass removes it; the same 1 % as without it."""
    trial, (I, B, K) = steady_elbow
    w, t = 2 * np.pi * 0.2, trial.time
    th_n = 0.3 + 0.5 * np.sin(w * t + 1)
    tau_n = -I * w * w * (th_n - 0.3) + B * 0.5 * w * np.cos(w * t + 1) + K * th_n
    moved = Trial.from_arrays(trial.angle + th_n, trial.torque + tau_n, FS, imposed="torque")
    est = estimators.make("fsewls").fit(moved)
    keep = est.steady()
    for got, want in zip((est.I, est.B, est.K), (I, B, K)):
        assert np.abs(got[keep] / want - 1).max() < 0.01


def test_estimate_interface(steady_elbow):
    trial, (I, B, K) = steady_elbow
    est = estimators.make("fsewls").fit(trial)
    assert isinstance(est, FSEWLSEstimate) and est.time is trial.time and est.estimator == "fsewls"
    keep = est.steady()
    assert np.abs(est.damping_ratio()[keep] / ZETA - 1).max() < 0.01
    frame = est.to_frame()
    assert list(frame.columns) == ["time", "I", "I_lo", "I_hi", "B", "B_lo", "B_hi", "K", "K_lo", "K_hi",
                                   "stiffness", "stiffness_lo", "stiffness_hi", "band_lo_hz", "band_hi_hz",
                                   "steady", "filtered_torque", "predicted_filtered_torque"]
    assert frame["steady"].sum() == keep.sum() and frame.notna().all().all()
    assert est.filtered_torque.shape == est.predicted_filtered_torque.shape == (1, trial.n)
    H = est.frequency_response(np.array([0.0, 2.0]), np.array([5.0, 6.0]))
    assert H.shape == (2, 2) and H[1, 0] == pytest.approx(K, rel=0.01)
    assert H[0, 1] == pytest.approx(K + 1j * 4 * np.pi * B - I * (4 * np.pi) ** 2, rel=0.01)
    assert est.frequency_response([2.0], 5.0).shape == (1,)
    with pytest.raises(ValueError, match="time"):
        est.frequency_response([2.0])
    torque = est.predict(trial.angle)       # impedance: torque from angle with the estimated I, B, K
    r = trial.torque[keep] - torque[keep]
    assert 1 - np.var(r) / np.var(trial.torque[keep]) > 0.9
    summary = est.summary()
    assert summary["transient_s"] == pytest.approx(est.transient) and summary["output_vaf"] > 99.9


def test_imposed_angle_gives_the_same_fit(steady_elbow):
    trial, _ = steady_elbow
    a = estimators.make("fsewls").fit(trial)
    b = estimators.make("fsewls").fit(trial.replace(imposed="angle"))
    assert np.array_equal(a.K, b.K) and np.array_equal(a.I, b.I)


def test_pooled_identical_records_equal_one(steady_elbow):
    trial, _ = steady_elbow
    est = estimators.make("fsewls")
    one, two = est.fit(trial), est.fit([trial, trial.replace(name="copy")])
    for k in "IBK":
        assert np.allclose(getattr(two, k), getattr(one, k), rtol=1e-9, atol=0)
    assert two.filtered_torque.shape == (2, trial.n)
    assert {"filtered_torque_1", "predicted_filtered_torque_1"} <= set(two.to_frame().columns)


def test_deterministic(slow_elbow):
    trial, _ = slow_elbow
    a = estimators.make("fsewls").fit(trial).to_frame()
    b = estimators.make("fsewls").fit(trial).to_frame()
    assert a.equals(b)


# ------------------------------------------------------------------------- RK4 and information form
def generic_rk4(rate, x0: float, t: np.ndarray) -> np.ndarray:
    out = [x0]
    for t0, t1 in zip(t[:-1], t[1:]):
        h, x = t1 - t0, out[-1]
        k1 = rate(t0, x)
        k2 = rate(t0 + h / 2, x + h / 2 * k1)
        k3 = rate(t0 + h / 2, x + h / 2 * k2)
        k4 = rate(t1, x + h * k3)
        out.append(x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4))
    return np.array(out)


@pytest.mark.parametrize("z", [0.02, 0.3, 1.5])
def test_rk4_recursion_equals_generic_rk4(z):
    """x' = -lam x + u(t)^2 with u linearly interpolated: the recursion is RK4 step for step."""
    h, n = 1e-3, 200
    lam = z / h
    t = np.arange(n) * h
    u = np.random.default_rng(3).standard_normal(n)
    ref = generic_rk4(lambda s, x: -lam * x + np.interp(s, t, u) ** 2, 0.7, t)
    c, w0, wm, w1 = rk4_coefficients(lam, h)
    x = [0.7]
    for k in range(n - 1):
        x.append(c * x[-1] + w0 * u[k] ** 2 + wm * (0.5 * (u[k] + u[k + 1])) ** 2 + w1 * u[k + 1] ** 2)
    assert np.allclose(x, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    assert abs(c - np.exp(-z)) < z ** 5 / 100  # RK4's stability polynomial, error z^5/120


def _regression(trial):
    s = est_settings({})
    x = highpass(np.stack([trial.angle, trial.torque])[:, None], FS, s.highpass_cutoff, s.highpass_order,
                 s.highpass_ripple)
    return svf(x[0], x[1], FS, svf_pole(s.svf_cutoff, s.svf_order, s.svf_cutoff_means), s.svf_order, False)


def test_information_form_equals_riccati_rk4(slow_elbow):
    """The fast linear recursion and plain RK4 on eq. 6 agree to RK4's truncation error."""
    trial, _ = slow_elbow
    Phi, y = _regression(trial)
    Phi, y = Phi[:, 4000:7000], y[:, 4000:7000]          # 3 s in the steady part of a varying elbow
    R0, r0 = unpack(forcing(Phi[:, :500], y[:, :500]).sum(axis=0) / FS)
    fast = ewls(Phi, y, 1 / FS, 20.0, R0, r0)
    ref = ewls_riccati_rk4(Phi[0], y[0], 1 / FS, 20.0, np.linalg.inv(R0), np.linalg.solve(R0, r0))
    assert np.allclose(fast[0], np.linalg.lstsq(Phi[0, :500], y[0, :500], rcond=None)[0], rtol=1e-9)
    assert (np.abs(fast - ref) / np.abs(ref)).max() < 1e-6


def _solve_spd3_numpy(x):
    """The 3 x 3 solve of ewls as numpy passes (its formulation before it was compiled, issue 22): the
    reference for the compiled loop's order of operations."""
    s = 1.0 / np.sqrt(x[[0, 3, 5]].mean(axis=1))
    a = np.array([x[k] * (s[i] * s[j]) for k, (i, j) in enumerate(zip(*UPPER3))] + [x[6 + i] * s[i] for i in range(3)])
    a00, a01, a02, a11, a12, a22, b0, b1, b2 = a
    l10, l20 = a01 / a00, a02 / a00
    d1, e12 = a11 - l10 * a01, a12 - l20 * a01
    l21 = e12 / d1
    d2 = a22 - l20 * a02 - l21 * e12
    z1 = b1 - l10 * b0
    x2 = (b2 - l20 * b0 - l21 * z1) / d2
    x1 = (z1 - e12 * x2) / d1
    x0 = (b0 - a01 * x1 - a02 * x2) / a00
    return np.column_stack([x0 * s[0], x1 * s[1], x2 * s[2]])


@pytest.mark.parametrize("records", [1, 3])
def test_ewls_recursion_is_lfilter_on_the_rk4_drive(records):
    """The compiled recursion of ewls gives exactly what its numpy formulation gave (issue 22): the products
    at the samples and mid-points by numpy.einsum, the RK4 drive w0 f0 + wm fm + w1 f1, scipy.signal.lfilter."""
    from jointbench.estimators import _ewls_loops
    from jointbench.estimators._fsewls_kernels import products, rk4_coefficients
    rng = np.random.default_rng(records)
    P, y, start = rng.standard_normal((3, records, 5000)), rng.standard_normal((records, 5000)), rng.standard_normal(9)
    c, w0, wm, w1 = rk4_coefficients(20.0, 1e-3)
    f = products(P, y)
    fm = products((P[..., 1:] + P[..., :-1]) * 0.5, (y[:, 1:] + y[:, :-1]) * 0.5)
    drive = np.empty_like(f)
    drive[:, 0] = start
    drive[:, 1:] = f[:, :-1] * w0 + fm * wm + f[:, 1:] * w1
    got = np.empty_like(f)
    _ewls_loops.recursion(P, y, w0, wm, w1, c, start, got)
    assert np.array_equal(got, sps.lfilter([1.0], [1.0, -c], drive, axis=-1))


def test_spd_solve_equals_lapack_and_refuses_indefinite():
    """The written-out 3 x 3 LDL^T solve of ewls against numpy.linalg.solve (LU with pivoting)."""
    rng = np.random.default_rng(5)
    A = rng.standard_normal((2000, 3, 3))
    R = A @ np.swapaxes(A, 1, 2) + 0.1 * np.eye(3)        # positive definite, condition up to ~1e3
    r = rng.standard_normal((2000, 3))
    x = np.concatenate([R[:, UPPER3[0], UPPER3[1]], r], axis=1).T
    want = np.linalg.solve(R, r[..., None])[..., 0]
    assert np.abs(solve_spd3(x) - want).max() <= 1e-11 * np.abs(want).max()
    assert np.array_equal(solve_spd3(x), _solve_spd3_numpy(x))   # the compiled loop: the same bits
    R[7] = np.diag([1.0, -1.0, 1.0])                       # indefinite at one sample
    x = np.concatenate([R[:, UPPER3[0], UPPER3[1]], r], axis=1).T
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
        solve_spd3(x)


def test_information_form_and_riccati_converge_at_fourth_order():
    """On smooth regressors the two discretisations differ by O(h^4): halving h divides by ~16."""
    def gap(fs):
        t = np.arange(int(fs)) / fs
        Phi = np.stack([np.sin(7 * t) + 2, np.cos(5 * t), np.sin(3 * t + 1)], axis=1)[None]
        y = Phi[0] @ np.array([1.0, -2.0, 0.5]) + np.sin(11 * t)
        R0, r0 = np.eye(3) * 0.2, np.zeros(3)
        fast = ewls(Phi, y[None], 1 / fs, 20.0, R0, r0)
        ref = ewls_riccati_rk4(Phi[0], y, 1 / fs, 20.0, np.linalg.inv(R0), r0)
        return np.abs(fast - ref).max()
    ratio = gap(100.0) / gap(200.0)
    assert 10 < ratio < 25


# -------------------------------------------------------------------------------------- bad input
def test_record_too_short_names_the_settings(steady_elbow):
    trial, _ = steady_elbow
    short = Trial.from_arrays(trial.angle[:7000], trial.torque[:7000], FS, name="short")
    with pytest.raises(InputError, match="too short") as info:
        estimators.make("fsewls").fit(short)
    for part in ("'short'", "7 s", "highpass_cutoff", "svf_cutoff", "forgetting", "init_window", "7.5 s"):
        assert part in str(info.value)
    estimators.make("fsewls", {"init_window": 0.4}).fit(short.replace(
        angle=trial.angle[:7400], torque=trial.torque[:7400], time=trial.time[:7400]))  # 7.4 s is enough


@pytest.mark.parametrize("fs,settings,match", [
    (50.0, {}, "svf_cutoff"),                                   # a = 6.3 Hz > fs/10
    (100.0, {"highpass_cutoff": 60.0}, "highpass_cutoff"),      # above Nyquist
    (100.0, {"forgetting": 60.0}, "forgetting"),                # lam dt = 0.6 > 0.5
])
def test_sampling_rate_too_low(fs, settings, match):
    rng = np.random.default_rng(0)
    tr = Trial.from_arrays(rng.standard_normal(int(20 * fs)), rng.standard_normal(int(20 * fs)), fs)
    with pytest.raises(InputError, match=match):
        estimators.make("fsewls", settings).fit(tr)


@pytest.mark.parametrize("key,value", [("forgetting", 0), ("forgetting", -20.0), ("forgetting", "0 1/s"),
                                       ("init_window", 0.0), ("svf_cutoff", 0.0), ("highpass_cutoff", 0.0),
                                       ("svf_order", 1), ("highpass_order", 0), ("highpass_ripple", 0.0),
                                       ("svf_cutoff_means", "half-power"), ("svf_causal", "maybe")])
def test_bad_settings_name_the_key(key, value):
    with pytest.raises(ConfigError, match=f"'{key}'"):
        estimators.make("fsewls", {key: value})


def test_units_in_settings():
    s = estimators.make("fsewls", {"forgetting": "20 1/s", "init_window": "250 ms", "svf_cutoff": "3.2 Hz",
                                   "highpass_ripple": "1 dB"}).settings
    assert (s.forgetting, s.init_window, s.svf_cutoff, s.highpass_ripple) == (20.0, 0.25, 3.2, 1.0)


def test_nan_rejected(steady_elbow):
    trial, _ = steady_elbow
    angle = trial.angle.copy()
    angle[100] = np.nan
    with pytest.raises(InputError, match="non-finite"):
        Trial.from_arrays(angle, trial.torque, FS)              # the Trial refuses it
    bad = Trial.from_arrays(trial.angle, trial.torque, FS, name="bad")
    object.__setattr__(bad, "torque", np.where(np.arange(trial.n) == 5, np.inf, trial.torque))
    with pytest.raises(InputError, match="'bad' has non-finite"):
        estimators.make("fsewls").fit(bad)                      # and so does FSEWLS if one slips through


def test_constant_angle_cannot_separate_parameters():
    tr = Trial.from_arrays(np.full(20000, 0.3), np.random.default_rng(0).standard_normal(20000), FS)
    with pytest.raises(InputError, match="cannot separate"):
        estimators.make("fsewls").fit(tr)


def test_pooled_records_must_have_equal_length(steady_elbow):
    trial, _ = steady_elbow
    other = Trial.from_arrays(trial.angle[:-10], trial.torque[:-10], FS)
    with pytest.raises(InputError, match="equal length"):
        estimators.make("fsewls").fit([trial, other])


def test_settings_are_frozen_and_documented():
    fields = {f.name: f for f in dataclasses.fields(FSEWLS.Settings)}
    assert set(fields) == {"highpass_cutoff", "highpass_order", "highpass_ripple", "svf_order", "svf_cutoff",
                           "svf_cutoff_means", "svf_causal", "svf_form", "forgetting", "init_window"}
    assert all(f.metadata.get("doc") for f in fields.values())


def test_svf_lowpass_form_drops_the_differentiator():
    """svf_form='lowpass': L = a^n/(s+a)^n, so L theta of a constant is the constant (the printed form
    s^(n-2) a^n/(s+a)^n has a zero at s = 0 and removes it)."""
    fs, n = 1000.0, 20000
    theta = np.full(n, 0.3)
    mid = slice(n // 4, 3 * n // 4)
    Phi_low, _ = svf(theta, theta, fs, a=39.4, order=3, causal=False, form="lowpass")
    Phi_pr, _ = svf(theta, theta, fs, a=39.4, order=3, causal=False, form="printed")
    assert np.allclose(Phi_low[mid, 2], 0.3, atol=1e-6) and np.allclose(Phi_pr[mid, 2], 0.0, atol=1e-6)


def _svf_as_first_written(theta, tau, fs, a, order, causal, form):
    """svf as it was before issue 22 (filters designed per call, np.pad, np.stack of the products)."""
    import scipy.fft
    from jointbench.estimators._fsewls_kernels import odd_fast_len
    n = theta.shape[-1]
    pad = int(np.ceil(40.0 / a * fs))
    nfft = odd_fast_len(n + 2 * pad)
    f = scipy.fft.rfftfreq(nfft, 1.0 / fs)
    jw = 2j * np.pi * f
    low = (a / (jw + a)) ** order if causal else (a * a / (a * a + (2 * np.pi * f) ** 2)) ** (order / 2.0)
    widths = [(0, 0)] * (theta.ndim - 1) + [(pad, nfft - n - pad)]
    spec = scipy.fft.rfft(np.stack([np.pad(theta, widths), np.pad(tau, widths)]), axis=-1)
    base = low * jw ** (order - 2) if form == "printed" else low
    ops = np.stack([spec[0] * (base * jw * jw), spec[0] * (base * jw), spec[0] * base, spec[1] * base])
    out = scipy.fft.irfft(ops, nfft, axis=-1)[..., pad:pad + n]
    return np.moveaxis(out[:3], 0, -1), out[3]


@pytest.mark.parametrize("causal", [False, True])
@pytest.mark.parametrize("shape", [(30000,), (2, 30000), (5000,)])
def test_svf_with_cached_multipliers_is_bit_identical(shape, causal):
    """The multipliers designed once per record length (issue 22) give the bits of the former svf, on 1-D and
    pooled records, twice in a row (the second call from the cache), in both forms."""
    rng = np.random.default_rng(22)
    theta, tau = rng.standard_normal(shape), rng.standard_normal(shape)
    for form in ("printed", "lowpass"):
        want = _svf_as_first_written(theta, tau, FS, 39.4, 3, causal, form)
        for _ in range(2):
            got = svf(theta, tau, FS, 39.4, 3, causal, form)
            assert all(g.shape == w.shape and np.array_equal(g.view(np.int64), w.view(np.int64))
                       for g, w in zip(got, want))


def test_its_prediction_of_another_record_is_refused_not_its_own_vaf():
    """FSEWLS's prediction is the regression's own output (the filtered torque of the records it was fitted on):
    scoring another record with it gave the fitted record's VAF as if held out (issue 37's real-data track found
    99.2 % "held out"); now refused in one line, the fitted records scored as before."""
    from jointbench import api
    from jointbench.core.errors import InputError

    fit = api.fit("fsewls", api.simulate("matrix:xu1998_elbow", seed=1))
    assert list(api.score(fit, fit.trials)["vaf"]) == fit.vaf
    with pytest.raises(InputError, match=r"fitted on .* this record is not record 1"):
        api.score(fit, api.simulate("matrix:xu1998_elbow", seed=2))
