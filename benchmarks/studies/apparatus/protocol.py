"""Protocols of the apparatus study: effects the linear models leave out, on the physics backend.

- ``apparatus.servo`` (Westwick & Perreault 2012, Fig. 1 and eqs. 3-8): the elbow behind a position servo
  of finite gain K_a, with voluntary torque. One trial per case; I, B, K fitted to the spectral estimate
  (``ibk_spectral``, as Fig. 6) with the measured angle as the input (the paper's practice) and with
  the position command as the input (eq. 7's approximation Theta ~ Theta_r), at one or more Welch
  segment lengths. Each fit is recorded beside its prediction: the expected Welch spectra of the linear
  loop of Fig. 1 (:func:`servo_prediction`), fitted the same way.
- ``apparatus.gravity`` (Xu & Hollerbach 1998, eqs. 1-2): the torque-driven elbow of Fig. 2 in posture,
  in a vertical plane, with gravity on the forearm; FSEWLS fitted to the trial with gravity and to the
  same trial (same seed, same PRBS) without it: the difference of the mean K-hat is the stiffness
  offset gravity adds, against K_g = m g l cos(posture + theta) along the trajectory (eq. 2).

References
----------
Westwick & Perreault 2012, Sec. II-A (eqs. 3-8) and Sec. V-A; Xu & Hollerbach 1998, Sec. II-A (eqs. 1-2).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np
from scipy import signal as sps

from jointbench import sims
from jointbench.benchmarks.protocols import Context, register
from jointbench.benchmarks.scoring import fit_gated
from jointbench.core.errors import Refused
from jointbench.benchmarks.studies.xu1998.protocol import scored_window
from jointbench.estimators.ibk_spectral import weighted_ibk_fit
from jointbench.core.ensemble import valid_mask
from jointbench.core.schema import param
from jointbench.sims.voluntary import Voluntary

INPUTS = ("measured", "command")


# ------------------------------------------------------------------------------ eqs. 3-8 prediction
def lowpass_psd(f: np.ndarray, order: int, cutoff: float, rms: float, fs_sim: float) -> np.ndarray:
    """One-sided PSD (unit²/Hz) of white noise through the digital Butterworth low-pass that
    :class:`sims.perturbation_filtered_noise.FilteredNoise` and :class:`sims.voluntary.Voluntary` use
    (designed at ``fs_sim``), scaled to ``rms``."""
    sos = sps.butter(order, cutoff, fs=fs_sim, output="sos")
    grid = np.linspace(0.0, fs_sim / 2, 2 ** 16 + 1)
    _, h = sps.sosfreqz(sos, worN=grid, fs=fs_sim)
    scale = rms ** 2 / np.trapezoid(np.abs(h) ** 2, grid)
    _, hf = sps.sosfreqz(sos, worN=np.abs(np.asarray(f, float)), fs=fs_sim)
    return scale * np.abs(hf) ** 2


def servo_loop(Z: np.ndarray, c: np.ndarray, r: np.ndarray):
    """Fig. 1 with the coupling ``T_a = c(s) theta_r - r(s) theta`` (c = K_a + B_a s, r likewise):
    theta = P theta_r + Q T_v, T_m = Tr theta_r + Tv T_v.

    P = c / (Z + r) and Q = 1 / (Z + r) are eqs. 7 and 3 (G = 1/Z); Tr = c Z / (Z + r) and
    Tv = -r / (Z + r) are eqs. 8 and 4.
    """
    D = Z + r
    return c / D, 1.0 / D, c * Z / D, -r / D


def servo_prediction(exp, inp: str, segment: float, window: str = "hann", fmax: float = 20.0,
                     leakage: bool = True, oversample: int = 32):
    """The I, B, K that ``ibk_spectral`` is expected to return, and the expected spectral estimate.

    The spectra of the command (a low-passed white noise), the voluntary torque, the angle's quantization
    and the torque's noise pass through the linear loop of Fig. 1 (:func:`servo_loop`); the expected
    Welch spectra are these spectra convolved with the squared magnitude of the segment window's
    transform (its resolution: the smearing of a sharp servo resonance in the angle), and the estimate
    is their ratio, weighted in the fit by the expected coherence². ``leakage=False``: the exact
    spectra at the Welch frequencies (eqs. 3-8 alone).

    Parameters
    ----------
    exp : Experiment
        Position servo experiment with a ``filtered_noise`` command.
    inp : {'measured', 'command'}
        The identification input: the measured angle, or the command theta_r.
    segment : float
        Welch segment (s); ``window``: its taper.

    Returns
    -------
    (I, B, K), f, H, coh
        Fitted parameters, and the expected estimate at the Welch frequencies up to ``fmax``.
    """
    fs = exp.fs
    L = int(round(segment * fs))
    M = L * oversample
    nu = np.fft.fftfreq(M, 1.0 / fs)                 # two-sided fine grid (negative frequencies wrap)
    s = 2j * np.pi * nu
    I, B, K = (float(np.mean(v)) for v in exp.joint.coefficients_at(np.zeros(1)))
    Z = I * s * s + B * s + K
    cp = exp.apparatus.coupling(exp.joint)
    P, Q, Tr, Tv = servo_loop(Z, cp.g + cp.g_d * s, cp.k_a + cp.b_a * s)
    pert = exp.perturbation
    Srr = lowpass_psd(nu, pert.order, pert.cutoff, pert.rms, exp.fs_sim) / 2      # two-sided
    vol = exp.voluntary
    Svv = lowpass_psd(nu, 2, vol.cutoff, vol.rms, exp.fs_sim) / 2 if vol.rms > 0 else np.zeros(M)
    q = exp.sensors.angle.quantization
    Sqq = np.full(M, q * q / 12.0 / exp.fs_sim)                                   # white at fs_sim
    Snn = np.full(M, (exp.sensors.torque.noise_rms or 0.0) ** 2 / fs)             # white, acquired
    if inp == "measured":
        Sxx = np.abs(P) ** 2 * Srr + np.abs(Q) ** 2 * Svv + Sqq
        Sxy = np.conj(P) * Tr * Srr + np.conj(Q) * Tv * Svv
    else:
        Sxx, Sxy = Srr, Tr * Srr
    Syy = np.abs(Tr) ** 2 * Srr + np.abs(Tv) ** 2 * Svv + Snn
    keep = np.arange(1, int(fmax * segment) + 1) * oversample      # Welch bins 1/segment ... fmax (no DC)
    if leakage:
        w = sps.get_window(window, L)
        kern = np.abs(np.fft.fft(w, M)) ** 2
        kern /= kern.sum()
        K_f = np.fft.fft(kern)
        Sxx, Sxy, Syy = (np.fft.ifft(np.fft.fft(x) * K_f) for x in (Sxx, Sxy, Syy))
        Sxx, Syy = Sxx.real, Syy.real
    f = nu[keep]
    H = Sxy[keep] / Sxx[keep]
    coh = np.abs(Sxy[keep]) ** 2 / (Sxx[keep] * Syy[keep])
    return weighted_ibk_fit(f, H, coh, "prediction", f"0 ... {fmax:g} Hz"), f, H, coh


def _impedance(I: float, B: float, K: float, f: np.ndarray) -> np.ndarray:
    s = 2j * np.pi * np.asarray(f, float)
    return I * s * s + B * s + K


@dataclasses.dataclass(frozen=True)
class ServoParams:
    """One servo stiffness (from the sweep) and whether the subject adds voluntary torque."""

    servo_stiffness: float = param(30000.0, unit="N.m/rad", gt=0, doc="servo gain K_a of Fig. 1")
    voluntary: Literal["present", "absent"] = param("present", doc="the configured voluntary torque, or none")
    segments: tuple[float, ...] = param((2.0,), unit="s", gt=0, doc="Welch segment lengths of the fits; "
                                        "the first is the estimator's reading, the others show its resolution")
    estimator: str = param("ibk_spectral", doc="the part's estimator fitted (an ibk_spectral)")
    curve_seeds: int = param(1, ge=0, doc="the lowest seeds whose spectral estimates are stored")


@register("apparatus.servo", ServoParams)
def servo(ctx: Context) -> None:
    """Eqs. 3-8: I, B, K of the limb behind a servo of gain K_a, from the measured angle and from the
    command, against the prediction of the linear loop (metrics ``I``, ``B``, ``K``, their ``_true``,
    ``_err_pct``, ``_predicted`` and ``_minus_predicted``, ``K_predicted_no_leakage``, labelled ``input``
    and ``segment_s``)."""
    p = ctx.params
    exp = ctx.experiment
    if exp.apparatus.kind != "position_servo":
        raise ValueError(f"apparatus.servo needs a position_servo experiment, got '{exp.apparatus.kind}'")
    exp = dataclasses.replace(exp, apparatus=dataclasses.replace(exp.apparatus, stiffness=p.servo_stiffness),
                              voluntary=exp.voluntary if p.voluntary == "present" else Voluntary())
    est0 = ctx.estimators[p.estimator]
    trial = sims.simulate(exp, ctx.seed)
    I0, B0, K0 = (float(np.mean(v)) for v in exp.joint.coefficients_at(np.zeros(1)))
    ctx.metric("servo_over_joint_stiffness", p.servo_stiffness / K0)
    ctx.metric("servo_mode_hz", math.sqrt((p.servo_stiffness + K0) / I0) / (2 * math.pi))
    for inp in INPUTS:
        tr = trial if inp == "measured" else trial.replace(angle=np.asarray(trial.truth.signals["command"]))
        for seg in p.segments:
            est = type(est0)(dataclasses.replace(est0.settings, segment=seg))
            try:
                fit = fit_gated(est, tr)
            except Refused as exc:           # the output gate: this fit refused, the case's others kept
                ctx.refused(est.name, exc, input=inp, segment_s=seg)
                continue
            (Ip, Bp, Kp), f, Hp, _ = servo_prediction(exp, inp, seg, est.settings.window, est.settings.fmax)
            (_, _, Kn), _, _, _ = servo_prediction(exp, inp, seg, est.settings.window, est.settings.fmax,
                                                   leakage=False)
            labels = {"input": inp, "segment_s": seg}
            for name, value, true, pred in (("I", fit.I, I0, Ip), ("B", fit.B, B0, Bp), ("K", fit.K, K0, Kp)):
                ctx.metric(name, value, est.name, **labels)
                ctx.metric(f"{name}_true", true, est.name, **labels)
                ctx.metric(f"{name}_err_pct", 100.0 * (value - true) / true, est.name, **labels)
                ctx.metric(f"{name}_predicted", pred, est.name, **labels)
                ctx.metric(f"{name}_minus_predicted", value - pred, est.name, **labels)
            ctx.metric("K_predicted_no_leakage", Kn, est.name, **labels)
            ctx.metric("K_predicted_err_pct", 100.0 * (Kp - K0) / K0, est.name, **labels)
            if ctx.seed < p.curve_seeds:   # Re(H - Z): what moves K-hat (the real rows K - I w^2 of the fit)
                basis = fit.basis
                sel = (basis.freq > 0) & (basis.freq <= est.settings.fmax)
                fb = basis.freq[sel]
                ctx.curve("real_error", fb, (basis.H[sel] - _impedance(I0, B0, K0, fb)).real, series="estimate",
                          **labels)
                ctx.curve("real_error", f, (Hp - _impedance(I0, B0, K0, f)).real, series="predicted", **labels)


# ------------------------------------------------------------------------------------------ gravity
@dataclasses.dataclass(frozen=True)
class GravityParams:
    """One posture of the forearm in the vertical plane (from the sweep)."""

    posture_deg: float = param(90.0, doc="angle of theta = 0 from hanging straight down (degrees)")
    discard: float = param(4.0, unit="s", ge=0, doc="seconds not scored at each end (as xu1998, reading R8)")
    estimator: str = param("fsewls", doc="the part's estimator (FSEWLS)")
    curve_seeds: int = param(1, ge=0, doc="the lowest seeds whose K-hat(t) are stored")
    curve_rate: float = param(50.0, unit="Hz", gt=0, doc="rate of the stored time courses")


@register("apparatus.gravity", GravityParams)
def gravity(ctx: Context) -> None:
    """Xu's eq. 2: the stiffness FSEWLS sees with gravity on the forearm, paired with the same trial
    without gravity. Metrics: ``K_hat_mean`` (with gravity), ``K_hat_mean_no_gravity``,
    ``gravity_offset`` (their difference), ``gravity_stiffness`` (mean K_g over the scored window, along
    the simulated trajectory), ``gravity_stiffness_at_posture`` (m g l cos posture), ``offset_minus_K_g``,
    ``K_true_mean``."""
    p = ctx.params
    exp = ctx.experiment
    if exp.gravity is None:
        raise ValueError("apparatus.gravity needs an experiment with 'gravity'")
    exp_g = dataclasses.replace(exp, gravity=dataclasses.replace(exp.gravity, posture=math.radians(p.posture_deg)))
    exp_0 = dataclasses.replace(exp, gravity=None)
    est = ctx.estimators[p.estimator]
    with_g, without = sims.simulate(exp_g, ctx.seed), sims.simulate(exp_0, ctx.seed)
    fit_g, fit_0 = fit_gated(est, with_g), fit_gated(est, without)
    keep = scored_window(with_g.n, with_g.fs, p.discard, valid_mask(fit_g))
    K_true = np.broadcast_to(np.asarray(with_g.truth.K, float), keep.shape)
    K_g = np.asarray(with_g.truth.signals["gravity_stiffness"])
    kg, k0 = float(np.mean(fit_g.K[keep])), float(np.mean(fit_0.K[keep]))
    offset = kg - k0
    ctx.metric("K_hat_mean", kg, est.name)
    ctx.metric("K_hat_mean_no_gravity", k0, est.name)
    ctx.metric("K_true_mean", float(np.mean(K_true[keep])), est.name)
    ctx.metric("gravity_offset", offset, est.name)
    ctx.metric("gravity_stiffness", float(np.mean(K_g[keep])), est.name)
    ctx.metric("gravity_stiffness_at_posture", float(exp_g.gravity.stiffness(0.0)), est.name)
    ctx.metric("offset_minus_K_g", offset - float(np.mean(K_g[keep])), est.name)
    ctx.metric("gravity_moment", exp_g.gravity.moment, est.name)
    ctx.metric("angle_mean_rad", float(np.mean(with_g.truth.signals["angle"][keep])), est.name)
    if ctx.seed < p.curve_seeds:
        t = exp.acquired_times()
        sel = np.flatnonzero(keep)[::max(1, int(round(with_g.fs / p.curve_rate)))]
        ctx.curve("K", t[sel], fit_g.K[sel], series="estimate, gravity")
        ctx.curve("K", t[sel], fit_0.K[sel], series="estimate, no gravity")
        ctx.curve("K", t[sel], K_true[sel], series="joint K(t)")
        ctx.curve("K", t[sel], K_true[sel] + K_g[sel], series="joint K(t) + K_g")
