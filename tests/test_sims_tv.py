"""Time-varying simulation: profiles, joints, the ``ltv`` backend against independent solutions,
PRBS and multisine perturbations, coloured noise, delay correction, replicates, fft decimation."""
import numpy as np
import pytest
from scipy import signal as sps
from scipy.integrate import solve_ivp

from jointbench.core.errors import ConfigError
from jointbench.core.signal import decimate_fft
from jointbench.sims import JOINTS, PERTURBATIONS, PROFILES, Experiment, simulate
from jointbench.sims.apparatus import Handle, PositionServo, TorqueDrive
from jointbench.sims.backend_lti import LTIBackend
from jointbench.sims.backend_ltv import LTVBackend, affine_recursion, derivative, step_matrices
from jointbench.sims.joint_second_order import SecondOrderJoint
from jointbench.sims.joint_time_varying import TimeVaryingJoint
from jointbench.sims.joint_wrist_contact import WristContactJoint
from jointbench.sims.perturbation_multisine import Multisine
from jointbench.sims.perturbation_prbs import PRBS
from jointbench.sims.profile import parse_profile
from jointbench.sims.sensors import SensorFilter

XU = {
    "joint": {"model": "time_varying", "I": 0.06, "damping_ratio": 0.3,
              "K": {"shape": "sine", "mean": 40, "amplitude": 15, "frequency": "0.5 Hz"}},
    "apparatus": {"kind": "torque_drive"},
    "perturbation": {"kind": "prbs", "amplitude": 4, "clock": "10 ms"},
    "fs_sim": "5 kHz", "duration": "6 s",
    "acquisition": {"detrend": False, "fs": "1 kHz", "trim": "0.5 s"},
}
WRIST = {
    "joint": {"model": "wrist_contact", "I": "3 g.m2", "b": 0.035, "b_c": 10, "k_c": 100,
              "k": {"shape": "square", "mean": 5.6, "amplitude": 0.9, "period": "10 s"}},
    "apparatus": {"kind": "handle"},
    "perturbation": {"kind": "multisine", "quiet": "1 s"},
    "fs_sim": "2500 Hz", "duration": "12 s",
    "sensors": {"torque": {"noise_snr_db": 10, "noise_filter": {"kind": "butter", "order": 2, "cutoff": 15}}},
    "acquisition": {"detrend": False, "fs": "44 Hz", "decimation": "fft", "trim": "1 s"},
}


def exp(base, **changes):
    d = {k: (dict(v) if isinstance(v, dict) else v) for k, v in base.items()}
    for k, v in changes.items():
        d[k] = v
    return Experiment.from_mapping(d, "test")


# --------------------------------------------------------------------------------------------- profiles
def test_profiles_values():
    t = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    assert np.allclose(parse_profile(3, "x").at(t), 3.0)
    s = parse_profile({"shape": "sine", "mean": 40, "amplitude": 15, "period": "1 s"}, "x")
    assert np.allclose(s.at(t), [40, 55, 40, 25, 40])
    q = parse_profile({"shape": "square", "mean": 5, "amplitude": 1, "frequency": 1}, "x")
    assert list(q.at(t)) == [6, 6, 4, 4, 6]
    p = parse_profile({"shape": "piecewise", "times": [0, 0.5], "values": [1.13, 10.1]}, "x")
    assert list(p.at(t)) == [1.13, 1.13, 10.1, 10.1, 10.1]
    lin = parse_profile({"shape": "piecewise", "times": [0, 1], "values": [0, 2], "interpolate": "linear"}, "x")
    assert np.allclose(lin.at(t), 2 * t)
    assert set(PROFILES.names()) >= {"constant", "sine", "square", "piecewise"}


@pytest.mark.parametrize("data, words", [
    ({"shape": "saw"}, "unknown profile"),
    ({"shape": "sine", "mean": 1, "amplitude": 1}, "exactly one of 'frequency'"),
    ({"shape": "sine", "mean": 1, "amplitude": 1, "period": 1, "freq": 2}, "unknown key 'freq'"),
    ({"shape": "piecewise", "times": [0, 0], "values": [1, 2]}, "increase strictly"),
    ({"shape": "piecewise", "times": [0, 1], "values": [1]}, "same number"),
    ([1, 2], "expected a number or a mapping"),
])
def test_bad_profiles(data, words):
    with pytest.raises(ConfigError, match=words):
        parse_profile(data, "test")


def test_joint_rejects_negative_stiffness_and_double_damping():
    with pytest.raises(ConfigError, match="'K'.*> 0"):
        TimeVaryingJoint(I=0.06, K={"shape": "sine", "mean": 10, "amplitude": 15, "period": 1}, B=1.0)
    with pytest.raises(ConfigError, match="exactly one of 'B'"):
        TimeVaryingJoint(I=0.06, K=40, B=1.0, damping_ratio=0.3)
    with pytest.raises(ConfigError, match="needs apparatus kind 'handle'"):
        exp(WRIST, apparatus={"kind": "position_servo"})
    with pytest.raises(ConfigError, match="needs a joint model with a contact"):
        exp(XU, apparatus={"kind": "handle"})


def test_damping_ratio_gives_b_from_k():
    j = TimeVaryingJoint(I=0.06, K={"shape": "sine", "mean": 40, "amplitude": 15, "period": 2}, damping_ratio=0.3)
    t = np.linspace(0, 2, 9)
    I, B, K = j.coefficients_at(t)
    assert np.allclose(B, 0.6 * np.sqrt(K * 0.06)) and not j.time_invariant


# ------------------------------------------------------------------------------------------ ltv backend
def test_step_matrices_equal_expm():
    """The two-coefficient form against scipy's expm of the augmented matrix: under-damped (elbow), the
    wrist's stiff contact, critically damped (double eigenvalue), a singular A (p = 0), A = 0 and a
    positive-feedback case (real eigenvalues of both signs)."""
    import scipy.linalg
    p = np.array([-900.0, -35000.0, -100.0, 0.0, 0.0, 400.0])
    q = np.array([-3.0, -3345.0, -20.0, -5.0, 0.0, 10.0])
    h = 1 / 2500
    E, J1, J2 = step_matrices(p, q, h)
    for i in range(len(p)):
        M = np.zeros((6, 6))
        M[:2, :2] = np.array([[0, 1], [p[i], q[i]]]) * h
        M[:2, 2:4] = np.eye(2) * h
        M[2:4, 4:] = np.eye(2)
        X = scipy.linalg.expm(M)
        for got, ref in ((E, X[:2, :2]), (J1, X[:2, 2:4]), (J2, X[:2, 4:] * h)):
            assert np.allclose(np.reshape([c[i] for c in got], (2, 2)), ref, rtol=1e-12, atol=1e-14 * abs(ref).max())


def test_step_coefficients_shortcuts_are_bit_identical():
    """Long stacks and shared runs (square waves) give exactly the numbers of one plain pass."""
    from jointbench.sims.backend_ltv import step_coefficients
    n = 3 * 8192 + 123
    t = np.arange(n) / 2500
    for k in (5.6 + 0.9 * np.sin(2 * np.pi * t / 20), np.where(np.mod(t / 10, 1) < 0.5, 6.5, 4.7)):
        p, q, h = -(k + 100) / 0.003, np.full(n, -10.035 / 0.003), 1 / 2500
        m = int(np.ceil(np.log2(np.max(np.abs(p) + np.abs(q) + 1.0) * h / 0.25)))
        for got, want in zip(step_coefficients(p, q, h), _series_plain(p, q, h, m)):
            assert all(np.array_equal(g, w) for g, w in zip(got, want))


def _series_plain(p, q, h, m):
    """_series as plain expressions (no buffers): the reference for its in-place arithmetic."""
    import math
    from jointbench.sims.backend_ltv import _TAYLOR_TERMS
    tau = h / 2.0 ** m
    tp, tq = p * tau, q * tau
    a, b = np.full_like(tp, 1.0 / math.factorial(_TAYLOR_TERMS + 2)), np.zeros_like(tp)
    for k in range(_TAYLOR_TERMS - 1, -1, -1):
        a, b = tp * b + 1.0 / math.factorial(k + 2), tau * a + tq * b
    s1a, s1b = tp * b + 1.0, tau * a + tq * b
    E, J1, J2 = (tp * s1b + 1.0, tau * s1a + tq * s1b), (s1a * tau, s1b * tau), (a * (tau * tau), b * (tau * tau))
    for _ in range(m):
        (ea, eb), (j1a, j1b), (j2a, j2b) = E, J1, J2
        pe, qe = p * eb, q * eb
        J2 = (j2a + tau * j1a + ea * j2a + pe * j2b, j2b + tau * j1b + ea * j2b + eb * j2a + qe * j2b)
        J1 = (j1a + ea * j1a + pe * j1b, j1b + ea * j1b + eb * j1a + qe * j1b)
        E = (ea * ea + pe * eb, 2.0 * ea * eb + qe * eb)
        tau *= 2.0
    return E, J1, J2


@pytest.mark.parametrize("m", [0, 1, 2, 5])
@pytest.mark.parametrize("n", [1, 255, 256, 1000])
def test_compiled_series_is_the_plain_arithmetic(m, n):
    """The compiled Taylor series and doublings (sims/_ltv_kernels.py, in groups of 256 steps) give exactly
    the numbers of the plain numpy expressions, for stacks shorter than, equal to and longer than a group."""
    from jointbench.sims.backend_ltv import _series
    rng = np.random.default_rng(m)
    p, q = -rng.uniform(0, 1e4, n), rng.uniform(-50, 50, n)
    for got, want in zip(_series(p, q, 1e-3, m), _series_plain(p, q, 1e-3, m)):
        assert all(np.array_equal(g, w) for g, w in zip(got, want))


def _affine_numpy(E, v0, v1, x0, block=32):
    """affine_recursion as numpy passes over blocks (its formulation before it was compiled, issue 22):
    the reference for the compiled loop's order of operations."""
    n1 = len(v0)
    if n1 <= block:
        e00, e01, e10, e11 = (c.tolist() for c in E)
        w0, w1 = v0.tolist(), v1.tolist()
        x, y = float(x0[0]), float(x0[1])
        xs, ys = [x], [y]
        for k in range(n1):
            x, y = e00[k] * x + e01[k] * y + w0[k], e10[k] * x + e11[k] * y + w1[k]
            xs.append(x)
            ys.append(y)
        return np.array(xs), np.array(ys)
    nb = -(-n1 // block)

    def blocks(c, fill):
        return np.concatenate([c, np.full(nb * block - n1, fill)]).reshape(nb, block).T

    e00, e01, e10, e11 = (blocks(c, f) for c, f in zip(E, (1.0, 0.0, 0.0, 1.0)))
    w0, w1 = blocks(v0, 0.0), blocks(v1, 0.0)
    x, y = w0[0].copy(), w1[0].copy()
    P00, P01, P10, P11 = e00[0].copy(), e01[0].copy(), e10[0].copy(), e11[0].copy()
    for j in range(1, block):
        a00, a01, a10, a11 = e00[j], e01[j], e10[j], e11[j]
        x, y = a00 * x + a01 * y + w0[j], a10 * x + a11 * y + w1[j]
        P00, P01, P10, P11 = (a00 * P00 + a01 * P10, a00 * P01 + a01 * P11,
                              a10 * P00 + a11 * P10, a10 * P01 + a11 * P11)
    sx, sy = _affine_numpy((P00, P01, P10, P11), x, y, x0, block)
    X, Y = np.empty((block, nb)), np.empty((block, nb))
    x, y = sx[:-1], sy[:-1]
    for j in range(block):
        x, y = e00[j] * x + e01[j] * y + w0[j], e10[j] * x + e11[j] * y + w1[j]
        X[j], Y[j] = x, y
    return np.concatenate([[x0[0]], X.T.ravel()[:n1]]), np.concatenate([[x0[1]], Y.T.ravel()[:n1]])


@pytest.mark.parametrize("n", [2, 20, 33, 35, 777, 32 * 32 + 3, 32 * 32 * 32 + 100])
def test_compiled_affine_recursion_is_the_blockwise_numpy_arithmetic(n):
    """The compiled recursion gives exactly the numbers of the blockwise numpy passes, read-only inputs
    (the memo of step_weights) or not, and an overflow spreads as it did there."""
    rng = np.random.default_rng(n)
    E = tuple(rng.uniform(-0.5, 0.5, n - 1) for _ in range(4))
    v0, v1 = rng.standard_normal(n - 1), rng.standard_normal(n - 1)
    want = _affine_numpy(E, v0, v1, (0.3, -0.2))
    for c in E[:2]:
        c.flags.writeable = False
    for got, ref in zip(affine_recursion(E, v0, v1, (0.3, -0.2)), want):
        assert np.array_equal(got, ref)
    v0[(n - 1) // 2] = np.inf
    with np.errstate(invalid="ignore"):      # inf - inf in the reference, as in the simulation it was
        want = _affine_numpy(E, v0, v1, (0.3, -0.2))
    for got, ref in zip(affine_recursion(E, v0, v1, (0.3, -0.2)), want):
        assert np.array_equal(got, ref, equal_nan=True)


@pytest.mark.parametrize("n", [2, 20, 33, 35, 777, 32 * 32 + 3, 32 * 32 * 32 + 100])
def test_affine_recursion_equals_loop(n):
    """Blocks of 32 steps: within one block, exactly one, one and a bit, two and three levels of blocks."""
    rng = np.random.default_rng(n)
    E = tuple(rng.uniform(-0.5, 0.5, n - 1) for _ in range(4))
    v0, v1 = rng.standard_normal(n - 1), rng.standard_normal(n - 1)
    x, y = affine_recursion(E, v0, v1, (0.3, -0.2))
    assert x.shape == y.shape == (n,)
    xs, ys = [0.3], [-0.2]
    e00, e01, e10, e11, w0, w1 = (c.tolist() for c in (*E, v0, v1))
    for k in range(n - 1):
        a, b = xs[-1], ys[-1]
        xs.append(e00[k] * a + e01[k] * b + w0[k])
        ys.append(e10[k] * a + e11[k] * b + w1[k])
    assert np.allclose(x, xs, atol=1e-12) and np.allclose(y, ys, atol=1e-12)


@pytest.mark.parametrize("apparatus", [PositionServo(30000.0), TorqueDrive()])
def test_ltv_equals_lti_for_a_constant_joint(apparatus):
    fs, n = 5000.0, 10000
    rng = np.random.default_rng(1)
    d = sps.sosfilt(sps.butter(2, 10, fs=fs, output="sos"), rng.standard_normal(n))
    tv = sps.sosfilt(sps.butter(2, 1, fs=fs, output="sos"), rng.standard_normal(n))
    d[0] = tv[0] = 0.0
    joint = SecondOrderJoint(I=0.171, B=1.22, K=53.5)
    a = LTIBackend().run(joint, apparatus, d, tv, fs)
    b = LTVBackend().run(joint, apparatus, d, tv, fs)
    for x, y in ((a.angle, b.angle), (a.velocity, b.velocity), (a.torque_measured, b.torque_measured)):
        assert np.max(np.abs(x - y)) <= 1e-9 * np.max(np.abs(x))


def _drive(t):
    return 2.0 * np.sin(2 * np.pi * 1.3 * t) + np.sin(2 * np.pi * 7.1 * t + 1) + 0.5 * np.cos(2 * np.pi * 17 * t)


def test_ltv_time_varying_elbow_matches_solve_ivp():
    """Independent solution: adaptive Runge-Kutta (DOP853) with the same linearly interpolated input."""
    fs, n = 5000.0, 10000
    t = np.arange(n) / fs
    joint = TimeVaryingJoint(I=0.06, K={"shape": "sine", "mean": 40, "amplitude": 15, "frequency": 2.0},
                             damping_ratio=0.3)
    d = _drive(t)
    r = LTVBackend().run(joint, TorqueDrive(), d, np.zeros(n), fs)

    def f(tt, x):
        I, B, K = joint.coefficients_at(np.array(tt))
        return [x[1], (np.interp(tt, t, d) - B * x[1] - K * x[0]) / I]

    ref = solve_ivp(f, (0, t[-1]), [0.0, 0.0], t_eval=t, method="DOP853", rtol=1e-11, atol=1e-13, max_step=1 / fs)
    assert np.max(np.abs(r.angle - ref.y[0])) <= 1e-5 * np.max(np.abs(ref.y[0]))


def test_ltv_wrist_with_contact_matches_fine_rk4():
    """Independent solution: classical RK4 at 40 substeps per sample (the contact pole is at -3.3e3 1/s)."""
    fs, n, sub = 2500.0, 2500, 40
    t = np.arange(n) / fs
    joint = WristContactJoint(I=0.003, b=0.035, k={"shape": "sine", "mean": 5.6, "amplitude": 0.9, "period": 0.5},
                              b_c=10, k_c=100)
    u = 0.01 * _drive(t)
    r = LTVBackend().run(joint, Handle(), u, np.zeros(n), fs)

    du = derivative(u, 1 / fs)

    def f(tt, x, i):
        k = 5.6 + 0.9 * np.sin(2 * np.pi * tt / 0.5)
        a = (tt - t[i]) * fs                          # u and u' are both held linearly between samples
        ui, ud = (1 - a) * u[i] + a * u[i + 1], (1 - a) * du[i] + a * du[i + 1]
        y = 10 * (ud - x[1]) + 100 * (ui - x[0])
        return np.array([x[1], (y - 0.035 * x[1] - k * x[0]) / 0.003])

    x, h, ref = np.zeros(2), 1 / fs / sub, [0.0]
    for i in range(n - 1):
        for j in range(sub):
            tt = t[i] + j * h
            k1 = f(tt, x, i)
            k2 = f(tt + h / 2, x + h / 2 * k1, i)
            k3 = f(tt + h / 2, x + h / 2 * k2, i)
            k4 = f(tt + h, x + h * k3, i)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        ref.append(x[0])
    assert np.max(np.abs(r.angle - ref)) <= 1e-5 * np.max(np.abs(ref))
    # the handle torque is the contact torque, and equals the limb's impedance torque (no voluntary torque)
    assert np.allclose(r.torque_measured, r.torque_impedance, atol=1e-9 * np.abs(r.torque_measured).max())


@pytest.mark.parametrize("fs, tol", [(2500.0, 0.01), (10000.0, 0.0005)])
def test_wrist_steady_state_matches_the_closed_form_response(fs, tol):
    """Y/U at the handle equals (b_c s + k_c) Z / (Z + b_c s + k_c) near the resonance, where the torque is a
    small difference of large contact terms (an error in u' is amplified about 200 times there)."""
    joint = WristContactJoint(I=0.003, b=0.035, k=5.6, b_c=10, k_c=100)
    n = int(6 * fs)
    t = np.arange(n) / fs
    for f in (1.0, 6.0, 8.0, 19.3):
        r = LTVBackend().run(joint, Handle(), 0.01 * np.cos(2 * np.pi * f * t), np.zeros(n), fs)
        late = slice(n // 2, None)
        A = np.column_stack([np.cos(2 * np.pi * f * t[late]), np.sin(2 * np.pi * f * t[late])])
        c = np.linalg.lstsq(A, r.torque_measured[late], rcond=None)[0]
        s = 2j * np.pi * f
        Z, C = 0.003 * s * s + 0.035 * s + 5.6, 10 * s + 100
        assert abs((c[0] - 1j * c[1]) / 0.01 / (C * Z / (Z + C)) - 1) < tol, f


# ------------------------------------------------------------------------------------------- simulate
def test_voluntary_movement_is_the_unperturbed_trajectory():
    e = exp(XU, perturbation={"kind": "prbs", "amplitude": 1e-9},
            voluntary={"movement_amplitude": "0.5 rad", "movement_frequency": "0.5 Hz"})
    tr = simulate(e, 0)
    assert np.max(np.abs(tr.truth.signals["angle"] - tr.truth.signals["movement"])) < 1e-6
    assert np.ptp(tr.angle) == pytest.approx(1.0, rel=1e-3)


def test_time_varying_truth_and_frozen_response():
    tr = simulate(exp(XU), 3)
    assert tr.imposed == "torque" and np.shape(tr.truth.K) == (tr.n,)
    assert np.allclose(tr.truth.K, 40 + 15 * np.sin(2 * np.pi * 0.5 * (tr.time + 0.5)))
    H = tr.truth.frozen_response([1.0, 2.0], tr.time[:3], tr.time)
    s = 2j * np.pi * np.array([1.0, 2.0])
    ref = 1 / (0.06 * s ** 2 + tr.truth.B[:3, None] * s + tr.truth.K[:3, None])
    assert np.allclose(H, ref)
    w = simulate(exp(WRIST), 3)
    k = w.truth.K[10]
    Z = 0.003 * s ** 2 + 0.035 * s + k
    C = 10 * s + 100
    assert np.allclose(w.truth.frozen_response([1.0, 2.0], w.time[10], w.time), C * Z / (Z + C))


def test_wrist_trial_shape_noise_and_replicate():
    e = exp(WRIST)
    a, b, a2 = simulate(e, 5), simulate(e, 5, replicate=1), simulate(e, 5)
    assert a.fs == 44.0 and a.n == 44 * 10
    assert np.array_equal(a.angle, a2.angle) and np.array_equal(a.torque, a2.torque)
    assert np.array_equal(a.angle, b.angle)                              # same input ...
    assert np.array_equal(a.truth.signals["torque"], b.truth.signals["torque"])
    assert not np.allclose(a.torque, b.torque)                           # ... other noise
    for tr in (a, b):
        noise = tr.torque - tr.truth.signals["torque"]
        assert 10 * np.log10(np.var(tr.truth.signals["torque"]) / np.var(noise)) == pytest.approx(10, abs=1e-9)
    # the noise is coloured: little of it above 15 Hz
    N = np.abs(np.fft.rfft(a.torque - a.truth.signals["torque"])) ** 2
    f = np.fft.rfftfreq(a.n, 1 / 44)
    assert N[f > 18].mean() < 0.5 * N[f < 5].mean()   # |H|² ≈ 0.2 at 20 Hz


def test_noise_variance_ratio():
    e = exp(XU, sensors={"angle": {"noise_variance_ratio": 0.2}})
    tr = simulate(e, 1)
    clean = tr.truth.signals["angle"]
    assert np.var(tr.angle - clean) / np.var(clean) == pytest.approx(0.2, rel=1e-9)
    with pytest.raises(ConfigError, match="at most one"):
        exp(XU, sensors={"angle": {"noise_variance_ratio": 0.2, "noise_snr_db": 3}})


def test_delay_correction_removes_the_bessel_delay():
    flt = SensorFilter(cutoff=150.0, kind="bessel", order=8, delay_correction=True)
    fs = 5000.0
    assert 2e-3 < flt.delay(fs) < 5e-3   # about 3.4 ms for 8 poles at 150 Hz
    t = np.arange(20000) / fs
    x = np.sin(2 * np.pi * 3 * t) + 0.5 * np.sin(2 * np.pi * 20 * t)
    y = flt.apply(x, fs)
    raw = SensorFilter(cutoff=150.0, kind="bessel", order=8).apply(x, fs)
    mid = slice(5000, 15000)
    assert np.max(np.abs(y - x)[mid]) < 5e-3 < 0.1 < np.max(np.abs(raw - x)[mid])  # Bessel droop remains


def test_prbs_levels_clock_and_autocorrelation():
    p = PRBS(amplitude=4, clock=0.01)
    fs = 1000.0
    x = p.generate(45000, fs, np.random.default_rng(0))
    assert set(np.unique(x)) == {-4.0, 4.0}
    assert np.all(np.diff(x)[np.arange(45000 - 1) % 10 != 9] == 0)       # switches only on the clock
    z = x - x.mean()
    r = np.correlate(z, z, "full")[len(z) - 1:] / np.dot(z, z)
    assert np.max(np.abs(r[10:1000])) < 0.1
    assert "prbs" in PERTURBATIONS and "multisine" in PERTURBATIONS
    assert {"time_varying", "wrist_contact"} <= set(JOINTS.names())


def test_multisine_has_exactly_the_requested_lines_and_rms():
    m = Multisine()
    fs, n = 2500.0, 125000
    u = m.generate(n, fs, np.random.default_rng(0))
    act = u[int(5 * fs):n - int(5 * fs)]
    assert np.sqrt(np.mean(act ** 2)) == pytest.approx(0.02, rel=1e-9)
    assert np.all(u[:int(5 * fs)] == 0) and np.all(u[n - int(5 * fs):] == 0)
    U = np.abs(np.fft.rfft(act)) / len(act)
    f = np.fft.rfftfreq(len(act), 1 / fs)
    excited = np.flatnonzero(U > 1e-9)
    assert np.allclose(f[excited], np.arange(0.1, 19.31, 0.8)) and len(excited) == 25
    a = 2 * U[excited]
    assert np.allclose(a[f[excited] <= 6], a[0]) and a[-1] == pytest.approx(a[0] * 6 / 19.3, rel=1e-9)


@pytest.mark.parametrize("settings, fs, duration, periods", [
    ({}, 2500.0, 50.0, 1),                                                  # the study: one period = 25 000 samples
    ({"quiet": 5.0003}, 2500.0, 60.0, 1),                                   # quiet margin between samples
    ({"quiet": 0.0}, 44.0, 40.0, 1),
    ({"period": 10 / 3, "f_min": 0.3, "spacing": 0.6, "f_max": 10}, 1000.0, 30.0, 3),    # 3 periods = 10 000 samples
    ({"period": 10 / 3, "f_min": 0.3, "spacing": 0.6, "f_max": 10}, 1000.37, 30.0, None),  # direct sum
])
def test_multisine_equals_the_sum_of_cosines(settings, fs, duration, periods):
    """The inverse-FFT synthesis against the defining formula summed sample by sample, quiet margins included."""
    from jointbench.sims.perturbation_multisine import _periods_in_whole_samples
    m = Multisine(**settings)
    n = int(duration * fs)
    assert _periods_in_whole_samples(m.period * fs, n) == periods     # which path is tested
    u = m.generate(n, fs, np.random.default_rng(4))
    phases = np.random.default_rng(4).uniform(0.0, 2 * np.pi, len(m.bins))
    t = np.arange(n) / fs
    active = (t >= m.quiet - 1e-9) & (t < n / fs - m.quiet - 1e-9)
    a = m.amplitudes() * m.rms / np.sqrt(np.sum(m.amplitudes() ** 2) / 2)
    ref = np.where(active, np.cos(2 * np.pi * np.outer(t - m.quiet, m.lines) + phases) @ a, 0.0)
    assert np.array_equal(u == 0, ref == 0)
    assert np.max(np.abs(u - ref)) <= 5e-12 * m.rms      # the direct sum's own rounding (large arguments)


def test_decimate_fft_keeps_lines_exactly():
    t = np.arange(125000) / 2500
    x = np.sin(2 * np.pi * 0.8 * t) + 0.3 * np.cos(2 * np.pi * 19.3 * t) + 0.1 * np.sin(2 * np.pi * 300 * t)
    y = decimate_fft(x, 2200)
    t2 = np.arange(2200) / 44
    assert np.allclose(y, np.sin(2 * np.pi * 0.8 * t2) + 0.3 * np.cos(2 * np.pi * 19.3 * t2), atol=1e-12)


@pytest.mark.parametrize("base", [XU, WRIST])
def test_time_varying_simulation_is_deterministic(base):
    e = exp(base)
    a, b = simulate(e, 11), simulate(e, 11)
    assert np.array_equal(a.angle, b.angle) and np.array_equal(a.torque, b.torque)
    assert not np.array_equal(a.torque, simulate(e, 12).torque)


# ------------------------------------------------------------------------ every registered simulator
# One small experiment per registered joint model and per perturbation; a new one must be added here.
JOINT_CASES = {
    "second_order": {"joint": {"model": "second_order", "I": 0.171, "B": 1.22, "K": 53.5},
                     "apparatus": {"kind": "position_servo"}},
    "time_varying": {"joint": XU["joint"], "apparatus": {"kind": "torque_drive"}},
    "wrist_contact": {"joint": WRIST["joint"], "apparatus": {"kind": "handle"}},
    "position_dependent": {"joint": {"model": "position_dependent", "I": 0.015, "B": 0.8,
                                     "K": {"polynomial": [100, 150, 200]}, "angle_range": [-0.6, 0.4]},
                           "apparatus": {"kind": "position_servo"}},
}
PERTURBATION_CASES = {
    "filtered_noise": {"kind": "filtered_noise", "cutoff": "10 Hz", "rms": "0.02 rad"},
    "prbs": {"kind": "prbs", "amplitude": 0.02, "clock": "10 ms"},
    "multisine": {"kind": "multisine", "quiet": "0.5 s", "period": "2 s", "f_min": "0.5 Hz", "spacing": "1.5 Hz"},
    "pralds": {"kind": "pralds", "rms": "0.02 rad", "quiet": "0.5 s"},
    "moving": {"kind": "moving", "movement": {"shape": "sine", "mean": 0, "amplitude": 0.1, "frequency": "0.5 Hz"},
               "perturbation": {"kind": "filtered_noise", "cutoff": "10 Hz", "rms": "0.01 rad"}, "fade": "0.5 s"},
}


def test_every_registered_simulator_has_a_case():
    assert set(JOINT_CASES) == set(JOINTS.names()) and set(PERTURBATION_CASES) == set(PERTURBATIONS.names())


@pytest.mark.parametrize("joint", sorted(JOINT_CASES))
@pytest.mark.parametrize("perturbation", sorted(PERTURBATION_CASES))
def test_every_registered_simulator_is_deterministic(joint, perturbation):
    spec = {**JOINT_CASES[joint], "perturbation": PERTURBATION_CASES[perturbation],
            "sensors": {"torque": {"noise_snr_db": 20}}, "fs_sim": "2 kHz", "duration": "4 s",
            "acquisition": {"detrend": False, "fs": "500 Hz", "trim": "0.5 s"}}
    e = Experiment.from_mapping(spec, "test")
    a, b, c = simulate(e, 3), simulate(e, 3), simulate(e, 4)
    assert np.array_equal(a.angle, b.angle) and np.array_equal(a.torque, b.torque)
    assert np.all(np.isfinite(a.angle)) and np.all(np.isfinite(a.torque))
    assert not np.array_equal(a.torque, c.torque)


def test_voluntary_position_is_the_movement_without_derivatives():
    from jointbench.sims.voluntary import Voluntary
    t = np.arange(12345) / 2000.0
    v = Voluntary(movement_amplitude=0.5, movement_frequency=0.25)
    pos, vel, acc = v.movement(t)
    assert np.array_equal(v.position(t), pos)
    w = 2 * np.pi * 0.25
    assert np.array_equal(acc, -0.5 * w * w * np.sin(w * t)) and np.array_equal(vel, 0.5 * w * np.cos(w * t))
    assert np.array_equal(Voluntary().position(t), np.zeros_like(t))


def test_decimate_of_columns_is_decimate_of_each_column():
    from jointbench.core.signal import decimate
    x = np.random.default_rng(2).standard_normal((5001, 3))
    for q in (2, 5):
        y = decimate(x, q)
        assert y.flags.c_contiguous
        for i in range(3):
            assert np.array_equal(y[:, i], decimate(np.ascontiguousarray(x[:, i]), q))


def test_step_weights_of_a_joint_are_kept_bit_identical_read_only_and_not_for_array_joints():
    """Trials of one joint time course with other seeds share the step weights (sims/backend_ltv.py): the
    same numbers as computed anew, read-only, and never kept for a joint that holds arrays."""
    from jointbench.sims import backend_ltv as bl

    exp = Experiment.from_mapping(XU, "test")
    bl._WEIGHTS.clear()
    a = simulate(exp, 1)
    before = dict(bl._WEIGHTS_STATS)
    b = simulate(exp, 2)                               # another perturbation, the same joint
    assert bl._WEIGHTS_STATS["reused"] > before["reused"] and bl._WEIGHTS_STATS["computed"] == before["computed"]
    bl._WEIGHTS.clear()
    b_alone = simulate(exp, 2)
    for x, y in ((b.angle, b_alone.angle), (b.torque, b_alone.torque)):
        assert np.array_equal(x, y)
    assert not np.array_equal(a.angle, b.angle)
    kept = next(iter(bl._WEIGHTS.values()))[0]
    assert not kept[2].flags.writeable and not kept[4][0].flags.writeable

    class ArrayJoint:                                  # an estimated model's time course: not kept
        def __init__(self, n):
            self.I, self.B, self.K = np.full(n, 0.06), np.full(n, 1.0), np.linspace(30, 50, n)

        def coefficients_at(self, t):
            return tuple(np.interp(t, np.arange(len(self.K)) * 1e-3, v) for v in (self.I, self.B, self.K))

    n0 = len(bl._WEIGHTS)
    LTVBackend().run(ArrayJoint(2000), TorqueDrive(), np.ones(2000), np.zeros(2000), 1000.0)
    assert len(bl._WEIGHTS) == n0
