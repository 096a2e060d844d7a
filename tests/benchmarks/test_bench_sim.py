"""Benchmarks of the simulation side, each with a same-run baseline.

* One simulated trial of the Westwick & Perreault 2012 elbow experiment (Sec. IV), with the LTI
  backend alone on the same input.
* The time-varying backend on the van de Ruit et al. 2018 wrist (50 s at 2.5 kHz, sinusoidal
  stiffness), and its two kernels against the implementations they replaced (issue 12), kept here
  only as baselines: the per-step matrices in two-coefficient form against the four-component Taylor
  series, the blocked recursion against the parallel prefix scan.
* The multisine by one inverse FFT of a period against the sum of cosines over every sample.
* A sensor's Bessel filter with its cached design against designing it on every call.

Run with ``--benchmark-enable`` for timings (``make bench``); by default (``--benchmark-disable``) each
runs once as a test of equality with its baseline. With timings, the fast paths must also beat their
baselines by the stated factor, measured interleaved in the same test (the ``speedup`` fixture).
"""
import math

import numpy as np
import pytest
from scipy import signal as sps

from jointbench.sims import Experiment, simulate
from jointbench.sims.backend_lti import LTIBackend
from jointbench.sims.backend_ltv import LTVBackend, affine_recursion, step_coefficients, step_matrices
from jointbench.sims.sensors import SensorFilter
from tests.test_sims import SPEC   # the paper's experiment: 30 s at 5 kHz, servo, sensors, to 500 Hz
from tests.test_sims_tv import WRIST, exp


# ------------------------------------------------------------------------------ Westwick 2012 elbow
@pytest.fixture(scope="module")
def experiment():
    return Experiment.from_mapping(SPEC, "bench")


@pytest.fixture(scope="module")
def inputs(experiment):
    """The drive and voluntary torque of seed 0 at the simulation rate."""
    e = experiment
    ss = np.random.SeedSequence(0).spawn(2)
    return (e.perturbation.generate(e.n_sim, e.fs_sim, np.random.default_rng(ss[0])),
            e.voluntary.generate(e.n_sim, e.fs_sim, np.random.default_rng(ss[1])))


@pytest.mark.benchmark(group="simulate-trial")
def test_bench_simulate_trial(benchmark, experiment):
    trial = benchmark(simulate, experiment, 0)
    assert trial.n == 14500 and trial.fs == 500.0


@pytest.mark.benchmark(group="simulate-trial")
def test_bench_backend_alone_baseline(benchmark, experiment, inputs):
    e = experiment
    drive, tv = inputs
    resp = benchmark(LTIBackend().run, e.joint, e.apparatus, drive, tv, e.fs_sim)
    assert resp.angle.shape == (150_000,)


@pytest.mark.benchmark(group="simulate-trial")
def test_bench_ltv_backend_same_input(benchmark, experiment, inputs):
    """The time-varying backend on the same constant joint and input (ratio to the LTI baseline)."""
    e = experiment
    drive, tv = inputs
    resp = benchmark(LTVBackend().run, e.joint, e.apparatus, drive, tv, e.fs_sim)
    ref = LTIBackend().run(e.joint, e.apparatus, drive, tv, e.fs_sim)
    # the backends start differently (lti: inputs ramp up over the sample before t = 0; ltv: at rest at
    # t = 0): compare once that start-up transient (the servo mode decays in ~0.26 s) has died out (5 s)
    late = slice(int(5 * e.fs_sim), None)
    assert np.max(np.abs(resp.angle - ref.angle)[late]) <= 1e-8 * np.max(np.abs(ref.angle))


# ------------------------------------------------------------------ the baselines replaced in issue 12
_TAYLOR_TERMS = 12


def _mul(a, b):
    a00, a01, a10, a11 = a
    b00, b01, b10, b11 = b
    return (a00 * b00 + a01 * b10, a00 * b01 + a01 * b11, a10 * b00 + a11 * b10, a10 * b01 + a11 * b11)


def _add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def step_matrices_before(p, q, h):
    """Baseline: E, J1, J2 as four components each, Taylor series at h / 2^m then m doublings."""
    norm = float(np.max(np.abs(p) + np.abs(q) + 1.0)) * h
    m = max(0, int(np.ceil(np.log2(norm / 0.25)))) if norm > 0.25 else 0
    tau = h / 2.0 ** m
    zero, one = np.zeros_like(p), np.ones_like(p)
    A = (zero, one * tau, p * tau, q * tau)
    ident = (one, zero, zero, one)
    S2 = tuple(c / math.factorial(_TAYLOR_TERMS + 2) for c in ident)
    for k in range(_TAYLOR_TERMS - 1, -1, -1):
        S2 = _add(_mul(A, S2), tuple(c / math.factorial(k + 2) for c in ident))
    S1 = _add(ident, _mul(A, S2))
    E = _add(ident, _mul(A, S1))
    J1 = tuple(c * tau for c in S1)
    J2 = tuple(c * tau * tau for c in S2)
    for _ in range(m):
        J2 = _add(_add(J2, tuple(c * tau for c in J1)), _mul(E, J2))
        J1 = _add(J1, _mul(E, J1))
        E = _mul(E, E)
        tau *= 2.0
    return E, J1, J2


def affine_scan_before(E, v0, v1, x0):
    """Baseline: states of x_k+1 = E_k x_k + v_k by a parallel prefix scan (log2 n vectorised passes)."""
    P = [c.copy() for c in E]
    q0, q1 = v0.copy(), v1.copy()
    n1 = len(q0)
    s = 1
    while s < n1:
        a = [c[s:] for c in P]
        b = [c[:-s] for c in P]
        nq0 = a[0] * q0[:-s] + a[1] * q1[:-s] + q0[s:]
        nq1 = a[2] * q0[:-s] + a[3] * q1[:-s] + q1[s:]
        nP = _mul(a, b)
        for c, new in zip(P, nP):
            c[s:] = new
        q0[s:], q1[s:] = nq0, nq1
        s *= 2
    x, y = np.empty(n1 + 1), np.empty(n1 + 1)
    x[0], y[0] = x0
    x[1:] = P[0] * x0[0] + P[1] * x0[1] + q0
    y[1:] = P[2] * x0[0] + P[3] * x0[1] + q1
    return x, y


def multisine_cos_before(ms, n, fs, rng):
    """Baseline: the multisine as a (samples x lines) matrix of cosines."""
    phases = rng.uniform(0.0, 2 * np.pi, len(ms.bins))
    t = np.arange(n) / fs
    active = (t >= ms.quiet - 1e-9) & (t < n / fs - ms.quiet - 1e-9)
    a = ms.amplitudes()
    a = a * (ms.rms / np.sqrt(np.sum(a ** 2) / 2.0))
    u = np.zeros(n)
    u[active] = np.cos(2 * np.pi * np.outer(t[active] - ms.quiet, ms.lines) + phases) @ a
    return u


# ------------------------------------------------------------------ van de Ruit 2018 wrist, ltv backend
@pytest.fixture(scope="module")
def wrist():
    """The study's wrist: 50 s at 2.5 kHz, multisine with 5 s quiet margins, k(t) sinusoidal (period 20 s)."""
    joint = {**WRIST["joint"], "k": {"shape": "sine", "mean": 5.6, "amplitude": 0.9, "period": "20 s"}}
    e = exp(WRIST, joint=joint, duration="50 s", perturbation={"kind": "multisine", "quiet": "5 s"},
            acquisition={"detrend": False, "fs": "44 Hz", "decimation": "fft", "trim": "5 s"})
    drive = e.perturbation.generate(e.n_sim, e.fs_sim, np.random.default_rng(0))
    h = 1.0 / e.fs_sim
    c = e.apparatus.coupling(e.joint)
    I, B, K = e.joint.coefficients_at((np.arange(e.n_sim - 1) + 0.5) * h)
    p, q = -(K + c.k_a) / I, -(B + c.b_a) / I
    rng = np.random.default_rng(1)
    v = (1e-6 * rng.standard_normal(e.n_sim - 1), 1e-3 * rng.standard_normal(e.n_sim - 1))
    return e, drive, p, q, h, v


@pytest.mark.benchmark(group="ltv-wrist-50s-2500Hz")
def test_bench_ltv_backend_wrist(benchmark, wrist):
    e, drive, *_ = wrist
    resp = benchmark(LTVBackend().run, e.joint, e.apparatus, drive, np.zeros_like(drive), e.fs_sim)
    assert resp.angle.shape == (125_000,) and np.all(np.isfinite(resp.torque_measured))


@pytest.mark.benchmark(group="ltv-step-matrices-125k")
def test_bench_step_coefficients(benchmark, speedup, wrist):
    _, _, p, q, h, _ = wrist
    benchmark(step_coefficients, p, q, h)
    new, old = step_matrices(p, q, h), step_matrices_before(p, q, h)
    for a, b in zip(new, old):                       # the same matrices, to rounding
        for x, y in zip(a, b):
            assert np.max(np.abs(x - y)) <= 1e-13 * np.max(np.abs(y))
    speedup(lambda: step_coefficients(p, q, h), lambda: step_matrices_before(p, q, h), 2.0)


@pytest.mark.benchmark(group="ltv-step-matrices-125k")
def test_bench_step_matrices_before_issue12_baseline(benchmark, wrist):
    _, _, p, q, h, _ = wrist
    benchmark(step_matrices_before, p, q, h)


@pytest.mark.benchmark(group="ltv-recursion-125k")
def test_bench_affine_recursion(benchmark, speedup, wrist):
    _, _, p, q, h, (v0, v1) = wrist
    E = step_matrices(p, q, h)[0]
    x, y = benchmark(affine_recursion, E, v0, v1, (1e-3, 0.0))
    xr, yr = affine_scan_before(E, v0, v1, (1e-3, 0.0))
    assert np.max(np.abs(x - xr)) <= 1e-13 * np.max(np.abs(xr)) and np.max(np.abs(y - yr)) <= 1e-13 * np.max(np.abs(yr))
    speedup(lambda: affine_recursion(E, v0, v1, (1e-3, 0.0)),
            lambda: affine_scan_before(E, v0, v1, (1e-3, 0.0)), 2.0)


@pytest.mark.benchmark(group="ltv-recursion-125k")
def test_bench_affine_scan_before_issue12_baseline(benchmark, wrist):
    _, _, p, q, h, (v0, v1) = wrist
    E = step_matrices(p, q, h)[0]
    benchmark(affine_scan_before, E, v0, v1, (1e-3, 0.0))


# -------------------------------------------------------------------------------------------- multisine
@pytest.mark.benchmark(group="multisine-50s-2500Hz")
def test_bench_multisine(benchmark, speedup, wrist):
    e = wrist[0]
    ms, n, fs = e.perturbation, e.n_sim, e.fs_sim
    u = benchmark(lambda: ms.generate(n, fs, np.random.default_rng(7)))
    ref = multisine_cos_before(ms, n, fs, np.random.default_rng(7))
    assert np.array_equal(u == 0, ref == 0)                    # the same quiet margins
    assert np.max(np.abs(u - ref)) <= 1e-11 * ms.rms           # the cosines' own rounding: ~1e-12 rms
    speedup(lambda: ms.generate(n, fs, np.random.default_rng(7)),
            lambda: multisine_cos_before(ms, n, fs, np.random.default_rng(7)), 10.0)


@pytest.mark.benchmark(group="multisine-50s-2500Hz")
def test_bench_multisine_cosines_before_issue12_baseline(benchmark, wrist):
    e = wrist[0]
    benchmark(lambda: multisine_cos_before(e.perturbation, e.n_sim, e.fs_sim, np.random.default_rng(7)))


# -------------------------------------------------------------------------------------- sensor filter
def bessel_designed_per_call(x, fs):
    return sps.sosfilt(sps.bessel(5, 500.0, btype="low", norm="mag", fs=fs, output="sos"), x, axis=0)


@pytest.mark.benchmark(group="bessel-filter-2s-5kHz")
def test_bench_sensor_filter_cached_design(benchmark):
    x = np.random.default_rng(0).standard_normal((10_000, 3))
    flt = SensorFilter(cutoff=500.0)
    y = benchmark(flt.apply, x, 5000.0)
    assert np.array_equal(y, bessel_designed_per_call(x, 5000.0))


@pytest.mark.benchmark(group="bessel-filter-2s-5kHz")
def test_bench_sensor_filter_designed_per_call_baseline(benchmark):
    x = np.random.default_rng(0).standard_normal((10_000, 3))
    benchmark(bessel_designed_per_call, x, 5000.0)
