"""How identifiable a scenario's time-varying stiffness is, from the simulation's truth (never an estimator's).

A method can only see the stiffness through the stiffness torque ``k(t) θ(t)`` in the measured torque, and
its time variation only through ``(k(t) − mean k) θ(t)``. Two figures say whether a scenario can be won by
anything but a constant (issue 18: the Westwick elbow's time-varying part was 0.007 % of the torque variance,
far below its noise):

* the share of the measured torque's variance due to stiffness, ``var(k θ) / var(τ)`` (and the share of its
  time-varying part, ``var((k − k̄) θ) / var(τ)``, and of the noise);
* the signal-to-noise ratio of the time-varying stiffness torque, ``10 log10 var((k − k̄) θ) / var(n)``,
  ``n = τ − τ_noise-free``.

Pure functions of arrays (:func:`identifiability`) and of a simulated trial (:func:`trial_identifiability`).

References
----------
van de Ruit, Mugge, Cavallo, Lataire, Ludvig & Schouten, "Quantitative comparison of time-varying system
identification methods to describe human joint impedance" (the comparison framework; ../shared/specs/studies.md
D); issue 18 (the figures it quotes for the Westwick elbow).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

#: the figures, in the order the rows are written
FIGURES = ("stiffness_share", "tv_share", "noise_share", "tv_snr_db")


def identifiability(k, theta, torque, torque_clean, mask=None) -> dict[str, float]:
    """The identifiability figures of one record (module docstring).

    Parameters
    ----------
    k : array_like
        The stiffness at every sample (N·m/rad), or a constant.
    theta : array_like
        The noise-free angle (rad).
    torque, torque_clean : array_like
        The measured torque and the same without the sensor noise (N·m).
    mask : array_like of bool, optional
        The samples used (the scored ones); default all.

    Returns
    -------
    dict
        ``stiffness_share``, ``tv_share``, ``noise_share`` (% of var(torque)) and ``tv_snr_db`` (dB; ``-inf``
        for a constant stiffness, ``inf`` without noise).
    """
    theta, k = np.asarray(theta, float), np.asarray(k, float)
    torque, torque_clean = np.asarray(torque, float), np.asarray(torque_clean, float)
    if k.ndim == 0:
        k = np.full(theta.shape, float(k))
    if not (k.shape == theta.shape == torque.shape == torque_clean.shape):
        raise ValueError(f"k, theta, torque and torque_clean differ in shape: {k.shape}, {theta.shape}, "
                         f"{torque.shape}, {torque_clean.shape}")
    m = np.ones(theta.shape, bool) if mask is None else np.asarray(mask, bool)
    if m.sum() < 2:
        raise ValueError("identifiability: fewer than 2 samples")
    k, theta, torque, torque_clean = k[m], theta[m], torque[m], torque_clean[m]
    v_tau = float(np.var(torque))
    if not v_tau > 0:
        raise ValueError("identifiability: the measured torque is constant")
    v_k = float(np.var(k * theta))
    v_tv = float(np.var((k - k.mean()) * theta))
    v_n = float(np.var(torque - torque_clean))
    if v_tv == 0:
        snr = -math.inf
    elif v_n == 0:
        snr = math.inf
    else:
        snr = 10 * math.log10(v_tv / v_n)
    return {"stiffness_share": 100 * v_k / v_tau, "tv_share": 100 * v_tv / v_tau, "noise_share": 100 * v_n / v_tau,
            "tv_snr_db": snr}


def trial_identifiability(trial, clean, k, mask=None) -> dict[str, float]:
    """:func:`identifiability` of a simulated trial with the scored stiffness ``k``: the noise-free angle from
    the trial's truth (``truth.signals['angle']``), the measured torque from ``trial`` and its noise-free
    value from ``clean``, the same realization simulated without torque noise (the same response: the
    difference is the noise alone, also where the measured torque holds more than the joint's torque, e.g.
    an apparatus's inertia)."""
    return identifiability(k, trial.truth.signals["angle"], torque_channel(trial), torque_channel(clean), mask)


def torque_channel(trial) -> np.ndarray:
    """The measured torque of a trial: its output when the angle is imposed, its input when the torque is."""
    return trial.output if trial.imposed == "angle" else trial.input


def without_torque_noise(exp):
    """The experiment ``exp`` (a :class:`sims.Experiment`) with no noise on its torque channel."""
    torque = dataclasses.replace(exp.sensors.torque, noise_rms=None, noise_snr_db=None, noise_variance_ratio=None)
    return dataclasses.replace(exp, sensors=dataclasses.replace(exp.sensors, torque=torque))
