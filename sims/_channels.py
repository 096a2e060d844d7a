"""The measured channels of a simulated trial: random streams, sensor noise and its scaling, detrending.

Private module of :mod:`sims.experiment` (the leading underscore keeps it out of the registries): the
pieces of :func:`sims.experiment.simulate` after the backend's response.

References
----------
Westwick & Perreault 2012, Fig. 1 and eqs. 3-8 (Sec. II-A: the measured angle and torque).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from jointbench.sims.sensors import Sensor

#: the independent random streams, in the order they are spawned from the seed (append new ones at the end)
STREAMS = ("perturbation", "voluntary", "angle_noise", "torque_noise")


def detrend_linear(x: np.ndarray) -> np.ndarray:
    """Remove the least-squares straight line along axis 0 (closed form; same as
    ``scipy.signal.detrend(x, axis=0, type="linear")`` to rounding, and much faster)."""
    t = np.arange(len(x)) - (len(x) - 1) / 2.0
    tt = float(t @ t)
    slope = (t @ x) / tt if tt > 0 else np.zeros(x.shape[1:])
    return x - x.mean(axis=0) - np.multiply.outer(t, slope)


def measure(sensor: Sensor, filtered: np.ndarray, clean: np.ndarray,
            unit_noise: Callable[[], tuple[np.ndarray, np.ndarray]],
            acquire: Callable[[np.ndarray], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """One channel after its analog filter: (measured, noise-free measured), both acquired.

    ``clean`` is ``acquire(filtered)`` (computed once per response, filter and acquisition: see
    :func:`sims.reuse.lookup_sensed`); ``unit_noise()`` gives the channel's unit-variance noise at the
    simulation rate and acquired (:func:`unit_noise`). The noise is scaled so that its rms (or the SNR) is
    exact in the acquired record; quantization acts before acquisition.
    """
    if not sensor.noisy:
        if sensor.quantization:
            return acquire(sensor.quantize(filtered)), clean
        return clean.copy(), clean
    w, w_acq = unit_noise()
    gain = sensor.noise_gain(clean, w_acq)
    if sensor.quantization:
        return acquire(sensor.quantize(filtered + gain * w)), clean
    return clean + gain * w_acq, clean  # acquisition is linear: the same as acquiring filtered + gain * w


def unit_noise(sensor: Sensor, n: int, rng: np.random.Generator, acquire: Callable[[np.ndarray], np.ndarray],
               fs_sim: float) -> tuple[np.ndarray, np.ndarray]:
    """A channel's unit noise: white at the simulation rate, drawn from the channel's own stream (coloured
    by the sensor's ``noise_filter`` if any), and the same after acquisition."""
    w = rng.standard_normal(n)
    if sensor.noise_filter is not None:
        w = sensor.noise_filter.apply(w, fs_sim)
    return w, acquire(w)


def streams(seed: int | np.random.SeedSequence, replicate: int,
            realization: int = 0) -> dict[str, np.random.Generator]:
    """One generator per entry of :data:`STREAMS`; ``replicate`` > 0 redraws only the noise streams,
    ``realization`` > 0 every stream (a child slot of its own, far from the replicates')."""
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    if realization:
        ss = np.random.SeedSequence(ss.entropy, spawn_key=tuple(ss.spawn_key) + (100000 + realization,))
    children = ss.spawn(len(STREAMS))
    if replicate:
        # a child slot far from the primary streams' (0 ... len(STREAMS) - 1), one per replicate
        noise = np.random.SeedSequence(ss.entropy, spawn_key=tuple(ss.spawn_key) + (1000 + replicate,))
        children[2:4] = noise.spawn(2)
    return dict(zip(STREAMS, (np.random.default_rng(c) for c in children)))
