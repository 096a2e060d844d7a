"""KBR (van de Ruit et al. 2018, Sec. III, App. B): recovery, low-rank = dense, bad input, determinism.

Data are made here, not with ``sims``: a random-phase sparse multisine (period 10 s, 0.1 ... 19.3 Hz
every 0.8 Hz, flat to 6 Hz then -20 dB/decade, 0.02 rad rms) on a 40 s window at 44 Hz, and the
wrist with contact (eq. 13) driven by the handle angle u:
``I th'' + (b + b_c) th' + (k(t) + k_c) th = b_c u' + k_c u``, torque ``y = b_c (u' - th') + k_c (u - th)``.
"""
import dataclasses

import numpy as np
import pytest

from jointbench import estimators
from jointbench.estimators import _kbr_predict as kpred, _kbr_solve as ks
from jointbench.estimators.kbr import KBR, KBREstimate
from jointbench.core.errors import ConfigError, InputError
from jointbench.core.types import Trial

I, B, BC, KC = 0.003, 0.035, 10.0, 100.0
FS, T, PERIOD = 44.0, 40.0, 10.0
NOISE_FREE = {"sigma": 8.0, "gamma": 25000.0}   # the paper's noise-free hyperparameters (Sec. IV-E)


# ----------------------------------------------------------------------------------------------- data
def multisine(seed: int, period: float = PERIOD, fmax: float = 19.3) -> tuple[np.ndarray, ...]:
    """Lines (Hz), amplitudes (rad) and phases of the paper's perturbation (Sec. IV-D)."""
    f = np.arange(round(0.1 * period), int(fmax * period + 1e-6) + 1, round(0.8 * period)) / period
    a = np.where(f <= 6.0, 1.0, 6.0 / f)
    a *= 0.02 / np.sqrt(np.sum(a ** 2) / 2)
    return f, a, np.random.default_rng(seed).uniform(0, 2 * np.pi, len(f))


def angle(t: np.ndarray, ms, deriv: int = 0) -> np.ndarray:
    f, a, ph = ms
    w = 2 * np.pi * f
    arg = np.outer(t, w) + ph
    return np.cos(arg) @ a if deriv == 0 else -np.sin(arg) @ (a * w)


def wrist_frf(f, k):
    """Frozen impedance (eq. 13) at stiffness ``k``."""
    s = 2j * np.pi * np.asarray(f, float)
    return (BC * s + KC) * (I * s ** 2 + B * s + k) / (I * s ** 2 + (B + BC) * s + k + KC)


def lti_record(ms, k: float = 5.6, fs: float = FS, duration: float = T):
    """Periodic steady state: ``y = IFFT(H U)`` (the multisine fills whole periods)."""
    n = int(round(duration * fs))
    u = angle(np.arange(n) / fs, ms)
    y = np.fft.irfft(np.fft.rfft(u) * wrist_frf(np.fft.rfftfreq(n, 1 / fs), k), n)
    return u, y


def ltv_record(ms, kfun, fs: float = FS, duration: float = T, pre: float = 5.0, up: int = 20):
    """The ODE with time-varying ``k(t)``, started at rest ``pre`` s before the window.

    Steps of ``1 / (up fs)`` s with ``k`` frozen at each step's midpoint; within a step the solution is
    exact (matrix exponential for the homogeneous part, the sinusoidal forcing's particular solution
    for the rest), so no interpolation of ``u`` is involved. The torque is then sampled at ``fs`` by
    taking every ``up``-th point: the continuous torque has content only at the lines (<= 19.3 Hz) and
    in their narrow skirts, below ``fs / 2`` = 22 Hz, so point sampling does not alias and needs no
    anti-alias filter. Halving the step changes the torque by about 1e-5 relative.
    """
    h = 1.0 / (fs * up)
    steps = int(round((duration + pre) * fs * up))
    tk = -pre + np.arange(steps + 1) * h
    f, a, ph = ms
    w = 2 * np.pi * f
    V = a * np.exp(1j * ph) * (KC + 1j * w * BC)        # forcing b_c u' + k_c u = Re sum V e^{jwt}
    Ks = kfun(tk[:-1] + h / 2) + KC
    tr, det = -(B + BC) / I, Ks / I
    disc = np.sqrt(tr ** 2 / 4 - det)                   # overdamped: real distinct eigenvalues
    l1, l2 = tr / 2 + disc, tr / 2 - disc
    A = np.zeros((steps, 2, 2))
    A[:, 0, 1], A[:, 1, 0], A[:, 1, 1] = 1.0, -det, tr
    eye = np.eye(2)[None]
    Phi = ((np.exp(l1 * h) / (l1 - l2))[:, None, None] * (A - l2[:, None, None] * eye)
           + (np.exp(l2 * h) / (l2 - l1))[:, None, None] * (A - l1[:, None, None] * eye))
    jw = 1j * w[None, :]
    g = 1.0 / (I * (jw * (jw - tr) + det[:, None]))      # (jw - A)^-1 [0, 1/I]: first component

    def particular(tt):
        e = V[None, :] * np.exp(1j * np.outer(tt, w))
        return np.stack([(g * e).sum(1).real, (g * jw * e).sum(1).real], axis=1)

    xa, xb = particular(tk[:-1]).tolist(), particular(tk[1:]).tolist()
    P = Phi.tolist()
    x0 = x1 = 0.0
    th, thd = [0.0] * (steps + 1), [0.0] * (steps + 1)
    for i in range(steps):
        (p00, p01), (p10, p11) = P[i]
        d0, d1 = x0 - xa[i][0], x1 - xa[i][1]
        x0, x1 = p00 * d0 + p01 * d1 + xb[i][0], p10 * d0 + p11 * d1 + xb[i][1]
        th[i + 1], thd[i + 1] = x0, x1
    keep = np.arange(round(pre * fs * up), steps + 1, up)[:int(round(duration * fs))]
    t = tk[keep]
    u, du = angle(t, ms), angle(t, ms, 1)
    y = BC * (du - np.array(thd)[keep]) + KC * (u - np.array(th)[keep])
    return u, y, kfun(t)


def sine_k(t):
    return 5.6 + 0.9 * np.sin(2 * np.pi * t / 20.0)   # between 4.7 and 6.5, period 20 s


def filtered_noise(n: int, std: float, seed: int) -> np.ndarray:
    """White noise through a 2nd-order Butterworth low-pass at 15 Hz (at 20 x 44 Hz), sampled at 44 Hz."""
    from scipy import signal as sps
    b, a = sps.butter(2, 15.0, fs=20 * FS)
    v = sps.lfilter(b, a, np.random.default_rng(seed).standard_normal(20 * n))[::20]
    return v * std / v.std()


@pytest.fixture(scope="module")
def ms():
    return multisine(2018)


@pytest.fixture(scope="module")
def lti(ms):
    u, y = lti_record(ms)
    return Trial.from_arrays(u, y, FS, name="lti")


@pytest.fixture(scope="module")
def sine(ms):
    u, y, k = ltv_record(ms, sine_k)
    return Trial.from_arrays(u, y, FS, name="sine"), k


@pytest.fixture(scope="module")
def lti_fit(lti):
    return estimators.make("kbr", NOISE_FREE).fit(lti)


@pytest.fixture(scope="module")
def noisy(sine):
    """The sine trial with output noise at SNR 10 dB (variance ratio 0.1), and its refined fit."""
    trial, k = sine
    y = trial.torque + filtered_noise(trial.n, trial.torque.std() / np.sqrt(10.0), seed=5)
    noisy = trial.replace(torque=y, name="noisy")
    return noisy, k, estimators.make("kbr", {"refine": True}).fit(noisy)


def rmse_k(est: KBREstimate, trial: Trial, k: np.ndarray) -> float:
    sel = trial.time <= 30.0
    true = np.abs(wrist_frf(est.f1, k))
    return float(np.sqrt(np.mean((est.stiffness(trial.time)[sel] - true[sel]) ** 2)))


# ------------------------------------------------------------------------------------------ recovery
def test_time_invariant_frf_at_the_lines(lti, lti_fit):
    est = lti_fit                     # weak regularisation: gamma = 25 000 against coefficients below 6
    assert isinstance(est, KBREstimate) and est.estimator == "kbr" and est.time is lti.time
    f = est.lines
    assert len(f) == 25 and f[0] == pytest.approx(0.1) and f[-1] == pytest.approx(19.3)
    H = est.frequency_response(f, lti.time)
    assert H.shape == (lti.n, 25)
    err = np.abs(H / wrist_frf(f, 5.6) - 1)
    assert err.max() < 1e-2, err.max()
    assert est.stiffness(12.0) == pytest.approx(abs(wrist_frf(0.1, 5.6)), rel=1e-3)


def test_prediction_of_the_fitted_record(lti, lti_fit):
    est = lti_fit
    y = lti.torque - lti.torque.mean()
    yhat = est.predict(lti.angle)
    assert 1 - np.var(y - yhat) / np.var(y) > 0.9999


def test_slowly_varying_stiffness_without_noise(sine):
    trial, k = sine
    est = estimators.make("kbr", NOISE_FREE).fit(trial)
    assert rmse_k(est, trial, k) < 0.1
    assert np.ptp(est.stiffness(trial.time[trial.time <= 30])) > 1.5   # it follows k, not its mean


def test_noisy_trial_needs_the_gauss_newton_refinement(sine, noisy):
    """SNR 10 dB (variance ratio): the relaxation alone is biased; minimising eq. B.1 is not."""
    trial, _ = sine
    noisy, k, est = noisy
    relax = estimators.make("kbr").fit(noisy)   # the default: relaxation only, as the paper
    assert rmse_k(est, noisy, k) < 0.7
    assert rmse_k(relax, noisy, k) > rmse_k(est, noisy, k)
    clean = trial.torque - trial.torque.mean()
    vaf = 1 - np.var(clean - est.predict(noisy.angle)) / np.var(clean)
    assert vaf > 0.99


# ------------------------------------------------------------------------------ low rank = dense
def dense_solve(pb, weights, fs: float, sigma: float):
    """Eq. B.1 with the explicit kernel matrices, in the dual (representer) form; no K^-1.

    With ``d`` the stacked weighted DFT of ``-mask D_0 y``, ``A_c`` the constants' columns and
    ``B_p = F_band diag(mask x_p)`` (explicit DFT matrix), the minimiser over ``c`` (free) and the
    coefficient variations ``check_p`` (prior ``gamma_p K_0``) is ``c = (A_c^T S^-1 A_c)^-1 A_c^T S^-1 d``,
    ``check_p = gamma_p K_0 B_p^T S^-1 (d - A_c c)``, ``S = sum_p gamma_p B_p K_0 B_p^T + I``.
    """
    n = len(pb.mask)
    m = np.arange(n)
    F = np.exp(-2j * np.pi * np.outer(pb.band, m) / n) * np.sqrt(weights)[:, None]
    stack = lambda x: np.concatenate([x.real, x.imag])  # noqa: E731
    t = m / fs
    K0 = np.exp(-((t[:, None] - t[None, :]) / sigma) ** 2)
    d = stack(-F @ (pb.mask * pb.y0))
    Bs = [stack(F * (pb.mask * x)[None, :]) for x in pb.regressors]
    Ac = np.column_stack([Bp.sum(axis=1) for Bp in Bs])
    S = np.eye(len(d)) + sum(g * Bp @ K0 @ Bp.T for g, Bp in zip(pb.gammas, Bs))
    Si_Ac, Si_d = np.linalg.solve(S, Ac), np.linalg.solve(S, d)
    c = np.linalg.solve(Ac.T @ Si_Ac, Ac.T @ Si_d)
    alpha = np.linalg.solve(S, d - Ac @ c)
    return np.array([cp + g * K0 @ (Bp.T @ alpha) for cp, g, Bp in zip(c, pb.gammas, Bs)])


@pytest.fixture(scope="module")
def small():
    """10 s at 20 Hz, lines 0.2 ... 6.6 Hz, a little noise: a problem the dense solve can afford."""
    ms = multisine(7, period=10.0, fmax=6.6)
    u, y = lti_record(ms, k=5.0, fs=20.0, duration=10.0)
    y = y + 0.01 * y.std() * np.random.default_rng(1).standard_normal(len(y))
    settings = {"sigma": 3.0, "kernel_points": 200, "eig_threshold": 1e-13, "max_rank": 200,
                "relax_iterations": 1, "refine": False}
    return Trial.from_arrays(u, y, 20.0, name="small"), settings


def test_low_rank_equals_dense_reference(small):
    trial, settings = small
    kbr = estimators.make("kbr", settings)
    pb = kbr.problem(trial)
    assert pb.points == trial.n and pb.Phi.shape[1] < trial.n   # exact eigenpairs, truncated at 1e-13
    est = kbr.fit(trial)                                         # one solve with sigma_E^2 = 1
    got = np.vstack([est.a, est.b])
    want = dense_solve(pb, np.ones(len(pb.band)), 20.0, 3.0)
    for g, w in zip(got, want):
        assert np.abs(g - w).max() < 1e-8 * np.abs(w).max()


def test_weighted_solve_equals_dense_reference(small):
    """Uneven weights sigma_E^-2. They are kept moderate because the dense GLS step loses accuracy as
    the weights grow (``S^-1`` nearly annihilates the constants' columns, which the low-rank solve
    eliminates exactly): about 1e-13 here, 1e-9 with weights 1000 times larger."""
    trial, settings = small
    pb = estimators.make("kbr", settings).problem(trial)
    weights = np.random.default_rng(3).uniform(0.1, 10.0, len(pb.band))
    system = ks.equation_system(pb.regressors, pb.y0, pb.mask, pb.Phi, np.sqrt(pb.gammas), pb.band)
    c, z, _ = ks.solve_weighted(system, weights)
    got = system.trajectories(c, z)
    want = dense_solve(pb, weights, 20.0, 3.0)
    for g, w in zip(got, want):
        assert np.abs(g - w).max() < 1e-8 * np.abs(w).max()


def test_nystrom_features_match_the_kernel():
    t = np.arange(1760) / FS
    Phi = ks.kernel_features(t, 8.0, 1e-12, 100, 41)
    i = np.arange(0, 1760, 7)
    K0 = np.exp(-((t[i, None] - t[None, i]) / 8.0) ** 2)
    assert np.abs(Phi[i] @ Phi[i].T - K0).max() < 1e-8


# ------------------------------------------------------------------------------------ the estimate
def test_estimate_interface(lti, lti_fit):
    est = lti_fit
    frame = est.to_frame()
    assert list(frame.columns) == ["time", "a1", "a2", "b0", "b1", "b2", "b3", "stiffness", "stiffness_lo",
                                   "stiffness_hi"]
    assert len(frame) == lti.n and frame.notna().all().all()
    assert est.parameters() == {}                       # no I, B, K in this model
    f = np.array([0.1, 1.0, 5.0])
    assert est.frequency_response(f, 3.0).shape == (3,)
    assert est.frequency_response(f, np.array([1.0, 2.0])).shape == (2, 3)
    with pytest.raises(ValueError, match="time"):
        est.frequency_response(f)
    assert np.ndim(est.stiffness(1.0)) == 0 and est.stiffness(lti.time).shape == (lti.n,)
    resp = est.response_frame()
    assert set(resp.columns) >= {"time", "freq_hz", "mag"} and len(resp) == 25 * lti.n
    with pytest.raises(ValueError, match="time base"):
        est.predict(lti.angle[:100])
    assert est.summary()["rank"] >= 10


def test_explicit_lines_and_band(lti, lti_fit):
    auto = lti_fit
    given = estimators.make("kbr", {**NOISE_FREE, "lines_hz": list(auto.lines)}).fit(lti)
    assert np.array_equal(auto.lines, given.lines)
    part = estimators.make("kbr", {**NOISE_FREE, "band": "0.5, 10"}).fit(lti)
    assert part.info["band_hz"] == "0.5 ... 10"
    assert abs(part.frequency_response([4.9], 20.0)[0] / wrist_frf(4.9, 5.6) - 1) < 1e-3


# ------------------------------------------------------------------------------------------- errors
@pytest.mark.parametrize("sigma", [0.0, -8.0])
def test_sigma_must_be_positive(sigma):
    with pytest.raises(ConfigError, match="'sigma'"):
        estimators.make("kbr", {"sigma": sigma})


@pytest.mark.parametrize("settings,key", [({"band": [10.0, 5.0]}, "band"), ({"band": [1.0]}, "band"),
                                          ({"gamma": 0}, "gamma"), ({"lines_hz": [1.0, 1.0]}, "lines_hz"),
                                          ({"max_leakage": 1.5}, "max_leakage")])
def test_bad_settings(settings, key):
    with pytest.raises(ConfigError, match=key):
        estimators.make("kbr", settings)


def test_band_without_excited_line(lti):
    with pytest.raises(InputError, match="'band'.*no excited line"):
        estimators.make("kbr", {"band": [0.2, 0.8]}).fit(lti)   # between the lines at 0.1 and 0.9 Hz


def test_record_shorter_than_one_period(ms):
    n = int(6.0 * FS)                                           # 6 s of a 10 s period
    tr = Trial.from_arrays(angle(np.arange(n) / FS, ms), np.zeros(n), FS, name="short")
    with pytest.raises(InputError, match="shorter than one period"):
        estimators.make("kbr").fit(tr)
    # given lines: checked by the shared rule of the multisine estimators (estimators/_multisine_lines.py),
    # which names the period the lines imply
    with pytest.raises(InputError, match="shorter than one period .10 s"):
        estimators.make("kbr", {"lines_hz": [0.1, 0.9, 1.7]}).fit(tr)


def test_broadband_input_is_refused():
    from scipy import signal as sps
    rng = np.random.default_rng(0)
    white = rng.standard_normal(1760)
    low = sps.filtfilt(*sps.butter(8, 5.0, fs=FS), white)             # most bins far below the pass band
    for u in (white, low):
        tr = Trial.from_arrays(u, rng.standard_normal(1760), FS, name="noise")
        with pytest.raises(InputError, match="not a sparse multisine"):
            estimators.make("kbr").fit(tr)
    with pytest.raises(InputError, match="constant"):
        estimators.make("kbr").fit(Trial.from_arrays(np.full(1760, 0.3), white, FS))


def test_one_record_at_a_time(lti):
    with pytest.raises(InputError, match="one record"):
        estimators.make("kbr").fit([lti, lti])


# ------------------------------------------------------------------------------------- determinism
def test_deterministic(noisy):
    noisy, _, a = noisy
    b = estimators.make("kbr", {"refine": True}).fit(noisy)
    assert a.to_frame().equals(b.to_frame())
    assert np.array_equal(a.predict(noisy.angle), b.predict(noisy.angle))
    assert dataclasses.asdict(KBR.Settings()) == dataclasses.asdict(estimators.make("kbr").settings)


# ----------------------------------------------------------------------------- numerical pieces
def ridge_reference(Ac, Az, b):
    """The ridge problem as one least-squares problem ``[[Ac, Az], [0, I]] x ~ [b, 0]`` (lstsq, SVD)."""
    p, q = Ac.shape[1], Az.shape[1]
    A = np.vstack([np.column_stack([Ac, Az]), np.column_stack([np.zeros((q, p)), np.eye(q)])])
    return np.linalg.lstsq(A, np.concatenate([b, np.zeros(q)]), rcond=None)[0]


@pytest.mark.parametrize("spread", [1.0, 1e3, 1e9])
def test_ridge_solve_normal_equations_and_qr_agree(spread):
    """Uneven column scales and two constants' columns that coincide to ``1 / spread``: the scaled normal
    matrix has a condition number of about 7, 4e6 (the plain Cholesky solve is then 8e-9 off, the refined
    one 2e-12) and 1e16 (the QR path takes over)."""
    rng = np.random.default_rng(5)
    Ac = rng.standard_normal((300, 4)) * np.array([1e-3, 1.0, 1e2, 1e4])
    Ac[:, 3] = Ac[:, 2] * 1e2 + Ac[:, 3] / spread
    Az = rng.standard_normal((300, 20)) * 30.0
    b = rng.standard_normal(300)
    c_qr, z_qr = ks.ridge_solve_qr(Ac, Az, b)
    c, z = ks.ridge_solve(Ac, Az, b)
    x, x_qr = np.concatenate([c, z]), np.concatenate([c_qr, z_qr])
    assert np.abs(x - x_qr).max() < 1e-11 * np.abs(x_qr).max()
    if spread == 1.0:
        assert np.abs(x - ridge_reference(Ac, Az, b)).max() < 1e-11 * np.abs(x).max()


def test_ridge_solve_takes_the_qr_when_ill_conditioned(monkeypatch):
    calls = []
    monkeypatch.setattr(ks, "ridge_solve_qr", lambda *a: calls.append(1) or (np.zeros(a[0].shape[1]),
                                                                             np.zeros(a[1].shape[1])))
    rng = np.random.default_rng(2)
    Ac = rng.standard_normal((50, 2))
    ks.ridge_solve(Ac, rng.standard_normal((50, 3)), rng.standard_normal(50))
    assert not calls
    ks.ridge_solve(np.column_stack([Ac[:, 0], Ac[:, 0] * (1 + 1e-12)]), rng.standard_normal((50, 3)),
                   rng.standard_normal(50))
    assert calls == [1]


def test_gmres_solves_a_nonsymmetric_system():
    rng = np.random.default_rng(4)
    A = np.eye(120) * 3 + rng.standard_normal((120, 120)) / 11
    b = rng.standard_normal(120)
    x, ok = kpred.gmres(lambda v: A @ v, b, restart=15, restarts=40, rtol=1e-12)
    assert ok and np.linalg.norm(A @ x - b) <= 1e-12 * np.linalg.norm(b)
    x, ok = kpred.gmres(lambda v: A @ v, b, restart=3, restarts=2, rtol=1e-12)
    assert not ok


def test_periodic_response_matches_the_dense_solve(monkeypatch):
    """The periodic solution by GMRES and by the dense fallback (forced) against the explicit operator."""
    n, fs = 440, 44.0
    t = np.arange(n) / fs
    a = np.vstack([0.01 + 0.008 * np.sin(2 * np.pi * t / 10), 3e-6 * (1 + 0.5 * np.cos(2 * np.pi * t / 7))])
    r = np.random.default_rng(8).standard_normal(n)
    Dp = kpred.periodic_derivative_response(n, fs, 2)
    L = np.column_stack([e + np.sum(a * ks.derivatives(e, Dp[1:3]), axis=0) for e in np.eye(n)])   # column j: e_j
    want = np.linalg.solve(L, r)
    got = kpred.periodic_response(a, r, Dp)
    assert np.abs(got - want).max() < 1e-10 * np.abs(want).max()
    monkeypatch.setattr(kpred, "gmres", lambda *args, **kw: (np.zeros(n), False))
    dense = kpred.periodic_response(a, r, Dp)
    assert np.abs(dense - want).max() < 1e-10 * np.abs(want).max()
