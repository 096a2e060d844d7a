"""Skirt decomposition (van de Ruit et al. 2018, Sec. II, App. A): exactness, a time-varying wrist,
the frozen TV-FRF interface, line detection and every bad input.

The data are made here (no ``sims``): a random-phase sparse multisine on a 40 s window at 44 Hz
(lines 0.1 ... 19.3 Hz every 0.8 Hz = DFT bins 4, 36, ..., 772; period 10 s; flat to 6 Hz then
-20 dB/decade; 0.02 rad rms) and the wrist-with-contact impedance
``H(s) = (b_c s + k_c)(I s² + b s + k) / (I s² + (b + b_c) s + k + k_c)``.
"""
import numpy as np
import pytest
from scipy import signal as sps

from jointbench import estimators
from jointbench.estimators.skirt import SkirtEstimate, basis
from jointbench.core.errors import ConfigError, InputError
from jointbench.core.types import Trial

FS, T = 44.0, 40.0
N = int(FS * T)
I0, B0, BC, KC, K0 = 0.003, 0.035, 10.0, 100.0, 5.6
LINES = np.arange(0.1, 19.31, 0.8)


# ----------------------------------------------------------------------------------------------- data
def multisine(seed: int = 0, lines=LINES, rms: float = 0.02):
    """Amplitudes and random phases: flat to 6 Hz, -20 dB/decade above, ``rms`` overall."""
    rng = np.random.default_rng(seed)
    lines = np.asarray(lines, float)
    a = np.where(lines <= 6.0, 1.0, 6.0 / lines)
    return lines, a * rms / np.sqrt(np.sum(a ** 2) / 2), rng.uniform(0, 2 * np.pi, len(lines))


def u_of(t, ms, deriv: int = 0) -> np.ndarray:
    """The multisine or its first or second derivative, analytically."""
    f, a, ph = ms
    w = 2 * np.pi * f
    arg = np.outer(t, w) + ph
    return [np.cos(arg) @ a, -np.sin(arg) @ (a * w), -np.cos(arg) @ (a * w * w)][deriv]


def impedance(f, k=K0):
    s = 2j * np.pi * np.asarray(f, float)
    return (BC * s + KC) * (I0 * s ** 2 + B0 * s + k) / (I0 * s ** 2 + (B0 + BC) * s + k + KC)


def lti_trial(seed: int = 0, n: int = N, lines=LINES) -> Trial:
    """Periodic steady state ``y = IDFT(H U)`` (exact for a record of whole periods)."""
    u = u_of(np.arange(n) / FS, multisine(seed, lines))
    y = np.fft.irfft(impedance(np.fft.rfftfreq(n, 1 / FS)) * np.fft.rfft(u), n)
    return Trial.from_arrays(u, y, FS, name="lti")


def ltv_trial(kfun, seed: int = 0, pre: float = 2.0, sub: int = 40) -> Trial:
    """Position-driven wrist with stiffness ``kfun(t)``, simulated by RK4 at ``44 * sub`` Hz from ``-pre`` s.

    The state is the contact deflection ``e = u - theta``:
    ``I e'' + (b + b_c) e' + (k(t) + k_c) e = I u'' + b u' + k(t) u`` and ``y = b_c e' + k_c e``,
    which avoids the cancellation in ``b_c (u' - theta') + k_c (u - theta)``. The analytic input is
    evaluated at the RK4 half steps; every ``sub``-th state is kept, so the 44 Hz samples are taken
    from the continuous-time solution (no decimation filter; nothing above 22 Hz to alias). The fast
    pole (-3.3e3 rad/s) needs h < 0.8 ms; at 1760 Hz the torque is within 3e-4 (relative to its peak)
    of the exact steady state, and the slow pole (time constant 0.1 s) has settled after 2 s.
    ``pre = 0`` switches the multisine on at the window start with the limb at rest, as in the study
    (no perturbation before the window): the step ``u(0)`` through the damper ``b_c`` gives the limb
    the velocity ``b_c u(0) / I``, so ``e(0+) = u(0)``, ``e'(0+) = u'(0) - b_c u(0) / I``.
    """
    ms = multisine(seed)
    h = 1.0 / (FS * sub)
    steps = int(round((pre + T) * FS * sub))
    tt = -pre + np.arange(2 * steps + 1) * (h / 2)
    kt = kfun(tt)
    force = ((I0 * u_of(tt, ms, 2) + B0 * u_of(tt, ms, 1) + kt * u_of(tt, ms)) / I0).tolist()
    stiff = ((kt + KC) / I0).tolist()
    c = (B0 + BC) / I0
    x = v = 0.0
    if pre == 0:
        u0, du0 = u_of([0.0], ms)[0], u_of([0.0], ms, 1)[0]
        x, v = u0, du0 - BC * u0 / I0
    first = int(round(pre * FS * sub))
    out = []
    for i in range(steps):
        if i >= first and (i - first) % sub == 0:
            out.append((x, v))
        j = 2 * i
        a1 = force[j] - c * v - stiff[j] * x
        x2, v2 = x + 0.5 * h * v, v + 0.5 * h * a1
        a2 = force[j + 1] - c * v2 - stiff[j + 1] * x2
        x3, v3 = x + 0.5 * h * v2, v + 0.5 * h * a2
        a3 = force[j + 1] - c * v3 - stiff[j + 1] * x3
        x4, v4 = x + h * v3, v + h * a3
        a4 = force[j + 2] - c * v4 - stiff[j + 2] * x4
        x += h / 6 * (v + 2 * v2 + 2 * v3 + v4)
        v += h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
    e, de = np.array(out).T
    return Trial.from_arrays(u_of(np.arange(N) / FS, ms), BC * de + KC * e, FS, name="ltv")


def k_sine(t):
    return 5.6 + 0.9 * np.sin(2 * np.pi * np.asarray(t) / 20.0)


@pytest.fixture(scope="module")
def lti():
    return lti_trial()


@pytest.fixture(scope="module")
def ltv():
    return ltv_trial(k_sine)


def fit(trial, settings: dict | None = None) -> SkirtEstimate:
    return estimators.make("skirt", settings).fit(trial)


# ------------------------------------------------------------------------------------------ accuracy
def test_time_invariant_system_exact_at_the_lines(lti):
    est = fit(lti)
    assert np.allclose(est.lines_hz, LINES)
    assert est.Gp.shape == (8, 25)
    H = impedance(est.lines_hz)
    assert np.abs(est.Gp[0] / H - 1).max() < 1e-3            # required; in fact ~1e-14
    assert np.abs(est.Gp[1:]).max() < 1e-6 * np.abs(H).min()  # nothing varies
    G = est.frequency_response(est.lines_hz, np.array([0.0, 17.0, 39.0]))
    assert np.abs(G / H - 1).max() < 1e-3


def model_data(ramp: float, seed: int = 3):
    """y = sum_p b_p(t) (G_p u)(t) (eq. 5) with random smooth G_p; ``ramp`` scales G_1."""
    ms = multisine(seed)
    t = np.arange(N) / FS
    u = u_of(t, ms)
    f = np.fft.rfftfreq(N, 1 / FS)
    rng = np.random.default_rng(5)
    Gp = np.array([impedance(f)] + [(rng.normal() + 1j * rng.normal()) * impedance(f) / (1 + 1j * f / (3 + p))
                                    for p in range(1, 8)])
    Gp[1] *= ramp
    Gp[:, 0] = Gp[:, 0].real
    y = np.sum(basis(7, t, T) * np.fft.irfft(Gp * np.fft.rfft(u), N, axis=1), axis=0)
    want = np.array([np.interp(LINES, f, g.real) + 1j * np.interp(LINES, f, g.imag) for g in Gp])
    return Trial.from_arrays(u, y, FS), want


@pytest.mark.parametrize("transient_order", [None, 0, 2])
def test_exact_for_model_data_without_ramp(transient_order):
    """Without a ramp term every skirt is confined to +-3 bins: eq. A.1 is then exact."""
    tr, want = model_data(ramp=0.0)
    est = fit(tr, {"transient_order": transient_order})
    assert np.abs(est.Gp - want).max() < 1e-8 * np.abs(want).max()
    assert np.allclose(est.predict(tr.angle), tr.torque, atol=1e-9 * np.abs(tr.torque).max())


def test_model_data_with_ramp():
    """The ramp's 1/(k - l) tails of the lines outside a band are only approximated by I_Y; the image
    terms (negative-frequency lines) matter in the lowest band."""
    tr, want = model_data(ramp=0.1)
    est = fit(tr)
    t = np.linspace(0.0, T, 200)
    truth = basis(7, t, T).T @ want
    err = np.abs(est.frequency_response(LINES, t) - truth) / np.abs(truth)
    assert np.median(err) < 1e-3 and err.max() < 0.1, (np.median(err), err.max())  # observed 2e-4, 0.055


def test_simulator_matches_the_exact_steady_state(lti):
    """The RK4 wrist (constant k) against the periodic steady state: the simulator itself is right."""
    sim = ltv_trial(lambda t: np.full(np.shape(t), K0))
    assert np.abs(sim.torque - lti.torque).max() < 1e-3 * np.abs(lti.torque).max()


def test_slowly_varying_stiffness(ltv):
    est = fit(ltv)
    t = np.arange(0.0, 30.0, 1 / FS)
    truth = np.abs(impedance(LINES[0], k_sine(t)))           # frozen |H(j w_1, t)|
    rmse = np.sqrt(np.mean((est.stiffness(t) - truth) ** 2))
    assert rmse < 0.1, rmse                                   # observed ~0.003
    frozen = impedance(LINES[None, :], k_sine(t)[:, None])
    rel = np.abs(est.frequency_response(LINES, t) - frozen) / np.abs(frozen)
    assert np.median(rel) < 0.01
    y = ltv.torque
    assert 1 - np.var(y - est.predict(ltv.angle)) / np.var(y) > 0.999


def test_switch_on_transient_at_the_window_start():
    """The multisine starts at t = 0 with the limb at rest: a torque spike at sample 0 and a 0.1 s
    transient. Its DFT is smooth over frequency (a spike is flat): the transient term absorbs it."""
    tr = ltv_trial(k_sine, pre=0.0)
    assert abs(tr.torque[0]) > 100 * np.abs(tr.torque[10:]).max()
    t = np.arange(0.0, 30.0, 1 / FS)
    truth = np.abs(impedance(LINES[0], k_sine(t)))
    rmse = np.sqrt(np.mean((fit(tr).stiffness(t) - truth) ** 2))
    assert rmse < 0.1, rmse                                   # observed ~0.005
    assert np.sqrt(np.mean((fit(tr, {"transient_order": None}).stiffness(t) - truth) ** 2)) > 10


def test_pooled_identical_records_give_the_single_record_estimate(ltv):
    one, two = fit(ltv), fit([ltv, ltv])
    assert np.allclose(one.Gp, two.Gp, rtol=1e-9, atol=1e-12)


def test_explicit_lines_equal_detected_lines(ltv):
    given = fit(ltv, {"lines_hz": list(LINES)})
    assert np.allclose(given.Gp, fit(ltv).Gp, rtol=1e-12, atol=0)
    parsed = estimators.make("skirt", {"lines_hz": "[0.1, 0.9Hz, 1.7]"})
    assert parsed.settings.lines_hz == pytest.approx((0.1, 0.9, 1.7))


def test_detection_ignores_a_small_trend(lti):
    """A trend (e.g. left by detrending a longer record) raises the lowest bins 20-30 dB above the
    floor but smoothly: lines must also stand above their neighbours."""
    u = lti.angle + 3e-5 * np.linspace(-1.0, 1.0, N)
    p = np.abs(np.fft.rfft(u)[1:4]) ** 2
    assert np.all(p > 100 * np.median(np.abs(np.fft.rfft(u)[1:N // 2]) ** 2))
    est = fit(Trial.from_arrays(u, lti.torque, FS))
    assert np.allclose(est.lines_hz, LINES)


def test_deterministic(ltv):
    a, b = fit(ltv), fit(ltv)
    assert np.array_equal(a.Gp, b.Gp)
    assert a.to_frame().equals(b.to_frame()) and a.response_frame().equals(b.response_frame())


# --------------------------------------------------------------------------------------- interface
def test_estimate_interface(ltv):
    est = fit(ltv)
    f = np.array([0.1, 0.5, 0.9])
    assert est.frequency_response(f, np.arange(5.0)).shape == (5, 3)
    assert est.frequency_response(f, 2.0).shape == (3,)
    mid = est.frequency_response([0.5], 2.0)[0]                # halfway between two lines: linear interpolation
    assert mid == pytest.approx(np.mean(est.frequency_response([0.1, 0.9], 2.0)))
    with pytest.raises(ValueError, match="give the time"):
        est.frequency_response(f)
    assert np.ndim(est.stiffness(3.0)) == 0
    assert est.stiffness(3.0) == pytest.approx(abs(est.frequency_response([0.1], 3.0)[0]))
    frame = est.to_frame()
    assert list(frame.columns) == ["time", "stiffness", "stiffness_lo", "stiffness_hi"] and len(frame) == N
    resp = est.response_frame()
    assert len(resp) == 8 * 25
    assert list(resp.columns) == ["p", "basis", "freq_hz", "re", "im", "mag", "phase_rad"]
    assert list(resp["basis"].unique()) == ["1", "ramp", "cos1", "sin1", "cos2", "sin2", "cos3", "sin3"]
    assert est.summary()["n_p"] == 7


def test_basis_functions():
    t = np.arange(N) / FS
    b = basis(7, t, T)
    assert b.shape == (8, N)
    assert np.allclose(b[1], 2 * t / T - 1)
    assert np.allclose(b[6], np.cos(2 * np.pi * 3 * t / T)) and np.allclose(b[7], np.sin(2 * np.pi * 3 * t / T))
    assert basis(0, t, T).shape == (1, N) and basis(2, t, T).shape == (3, N)


# ------------------------------------------------------------------------------------------ bad input
def test_white_noise_is_not_a_multisine():
    rng = np.random.default_rng(1)
    with pytest.raises(InputError, match="no clearly excited lines"):
        fit(Trial.from_arrays(rng.standard_normal(N), rng.standard_normal(N), FS))


def test_filtered_noise_is_not_a_sparse_multisine():
    rng = np.random.default_rng(2)
    u = sps.lfilter(*sps.butter(2, 2.0, fs=FS), rng.standard_normal(N))
    with pytest.raises(InputError, match="not a sparse multisine"):
        fit(Trial.from_arrays(u, u, FS))


def test_lines_off_a_regular_grid():
    bins = np.array([4, 36, 69, 99, 132])                     # gaps 32, 33, 30, 33: gcd 1
    tr = lti_trial(lines=bins / T)
    with pytest.raises(InputError, match="regular grid"):
        fit(tr)


@pytest.mark.parametrize("duration, words", [(5.0, "shorter than one period"), (15.0, "whole number of periods")])
def test_record_not_whole_periods(lti, duration, words):
    n = int(duration * FS)
    short = Trial.from_arrays(lti.angle[:n], lti.torque[:n], FS)
    with pytest.raises(InputError, match="shorter than one period"):
        fit(short)                                            # detected: the lines leak
    with pytest.raises(InputError, match=words):
        fit(short, {"lines_hz": list(LINES)})                      # given: period 10 s from the lines


def test_lines_too_close_for_n_p(lti):
    with pytest.raises(InputError, match=r"too close for n_p = 64.*2\*32\+1 = 65 bins"):
        fit(lti, {"n_p": 64})                                      # spacing 32 bins < 65
    dense = lti_trial(lines=np.arange(4, 40, 4) / T)          # 0.1 Hz spacing = 4 bins < 7
    with pytest.raises(InputError, match="too close for n_p = 7"):
        fit(dense)
    assert fit(dense, {"n_p": 2}).Gp.shape == (3, 9)               # +-1 bin skirts fit between


def test_too_few_lines():
    with pytest.raises(InputError, match="at least 3 excited lines"):
        fit(lti_trial(lines=[0.1, 0.9]))
    with pytest.raises(ConfigError, match="at least 3 lines"):
        estimators.make("skirt", {"lines_hz": [0.1, 0.9]})


def test_given_line_not_excited(lti):
    with pytest.raises(InputError, match="1.3 Hz of lines_hz is not excited"):
        fit(lti, {"lines_hz": [0.1, 0.9, 1.3, 1.7]})


@pytest.mark.parametrize("halfwidth", [2, 29])
def test_band_halfwidth_out_of_range(lti, halfwidth):
    with pytest.raises(InputError, match=r"band_halfwidth = \d+ bins.*use 3 ... 28 bins"):
        fit(lti, {"band_halfwidth": halfwidth})


def test_too_many_unknowns_for_a_band(lti):
    with pytest.raises(InputError, match="unknowns"):
        fit(lti, {"transient_order": 80})


def test_lowest_line_too_low_for_its_skirt():
    tr = lti_trial(lines=np.arange(2, 700, 32) / T)           # bin 2: its skirt would reach bin -1
    with pytest.raises(InputError, match="skirts"):
        fit(tr)


def test_pooled_records_must_match(lti):
    short = Trial.from_arrays(lti.angle[:880], lti.torque[:880], FS)
    with pytest.raises(InputError, match="same length"):
        fit([lti, short])
    other = lti_trial(lines=LINES[:-1])
    with pytest.raises(InputError, match="other lines"):
        fit([lti, other])


def test_no_input_power():
    with pytest.raises(InputError, match="no power"):
        fit(Trial.from_arrays(np.full(N, 0.3), np.zeros(N), FS))


@pytest.mark.parametrize("settings", [{"n_p": -1}, {"band_halfwidth": -1}, {"transient_order": -1},
                                      {"lines_hz": [0.1, 0.1, 0.9]}, {"lines_hz": [0.1, -0.9, 1.7]},
                                      {"threshold_db": 0}])
def test_bad_settings(settings):
    with pytest.raises(ConfigError, match=next(iter(settings))):
        estimators.make("skirt", settings)
