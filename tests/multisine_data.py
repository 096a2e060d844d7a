"""Test data for the estimators that need a periodic multisine input (tag ``multisine``): an elbow
I-B-K impedance in periodic steady state, computed exactly line by line (no simulator involved)."""
import numpy as np

from jointbench.core.types import Trial

#: van de Ruit et al. 2018, Sec. IV-D: period 10 s, lines 0.1 ... 19.3 Hz every 0.8 Hz
LINES = np.arange(0.1, 19.31, 0.8)


def multisine_impedance_trial(I: float, B: float, K: float, fs: float = 50.0, duration: float = 40.0,
                              seed: int = 0, rms: float = 0.02, offset: tuple[float, float] = (0.0, 0.0),
                              name: str = "multisine") -> Trial:
    """Angle: random-phase multisine (flat to 6 Hz, -20 dB/decade above); torque = I θ'' + B θ' + K θ,
    exact at every sample (each line is a whole number of cycles per 10 s period)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration * fs))) / fs
    amp = np.where(LINES <= 6.0, 1.0, 6.0 / LINES)
    amp *= rms / np.sqrt(np.sum(amp ** 2) / 2)
    phase = rng.uniform(0, 2 * np.pi, len(LINES))
    w = 2 * np.pi * LINES
    Z = K + 1j * w * B - I * w ** 2
    arg = np.outer(t, w) + phase
    angle = np.cos(arg) @ amp
    torque = np.cos(arg + np.angle(Z)) @ (amp * np.abs(Z))
    return Trial.from_arrays(angle + offset[0], torque + offset[1], fs, name=name)
