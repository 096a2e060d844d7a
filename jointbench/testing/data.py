"""The kit's records: simulated trials of an estimator's own kind, and the narrow-band record of issue 33.

:func:`kind_of` reads the kind from the estimator's class (``accepts``, ``perturbations``, its tags);
:func:`reference` simulates a record of that kind through the simulators' public entrance
(:func:`jointbench.sims.simulate` on an :class:`~jointbench.sims.Experiment` built from a mapping, the
joint models and perturbations looked up in their registries); :func:`narrow_band` draws the narrow-band record.
Every draw comes from an explicit seed.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from jointbench.core.ensemble import Ensemble
from jointbench.core.types import Trial, Truth

#: the narrow-band record's impedance (issue 33): I (kg m^2), B (N m s/rad), K (N m/rad)
NARROW_BAND_TRUTH = {"I": 0.02, "B": 0.6, "K": 120.0}

#: the second-order joint of the time-invariant and ensemble kinds (an ankle: Westwick & Perreault 2012)
ANKLE = {"model": "second_order", "I": 0.01, "B": 0.8, "K": 140.0}

#: the experiments of the kinds, as mappings read by :meth:`jointbench.sims.Experiment.from_mapping`
EXPERIMENTS: dict[str, dict[str, Any]] = {
    # a position servo imposing low-passed noise on the ankle; torque noise (Westwick & Perreault 2012, Sec. IV);
    # integrated at 5 kHz: at 1 kHz the integrator's error alone takes a quarter off the apparent I
    "trial": {"joint": ANKLE, "apparatus": {"kind": "position_servo", "stiffness": 30000},
              "perturbation": {"kind": "filtered_noise", "cutoff": 15, "order": 2, "rms": 0.02},
              "sensors": {"torque": {"noise_variance_ratio": 0.1}},
              "fs_sim": 5000, "duration": 11.0, "acquisition": {"detrend": False, "fs": 250, "trim": 0.5}},
    # realizations of the same condition at 100 Hz, wide-band (van de Ruit et al. 2018, Sec. V-E)
    "ensemble": {"joint": ANKLE, "apparatus": {"kind": "position_servo", "stiffness": 30000},
                 "perturbation": {"kind": "filtered_noise", "cutoff": 30, "order": 2, "rms": 0.02},
                 "sensors": {"torque": {"noise_variance_ratio": 0.1}},
                 "fs_sim": 5000, "duration": 3.0, "acquisition": {"detrend": False, "fs": 100, "trim": 0.5}},
    # the wrist with hand contact under a sparse multisine (van de Ruit et al. 2018, eq. 13), constant k
    "multisine": {"joint": {"model": "wrist_contact", "I": 0.003, "b": 0.035, "b_c": 10, "k_c": 100, "k": 5.6},
                  "apparatus": {"kind": "handle"},
                  "perturbation": {"kind": "multisine", "period": 10, "f_min": 0.5, "f_max": 19.3, "spacing": 0.8,
                                   "corner": 6, "slope": -20, "rms": 0.02, "quiet": 0},
                  "sensors": {"torque": {"noise_variance_ratio": 0.1}},
                  "fs_sim": 2500, "duration": 20.0, "acquisition": {"detrend": False, "fs": 50, "decimation": "fft"}},
    # the ankle moved slowly through its range by the servo with a random perturbation on top (the lpv study's
    # experiment, Sobhani Tehrani & Kearney 2022's REKLAB pilot trial), its impedance constant so the truth of
    # K(sigma) is exact at every sigma: a parameter-varying estimator's own kind (tag lpv), long enough for its
    # segment-robust band
    "moving": {"joint": ANKLE, "apparatus": {"kind": "position_servo", "stiffness": 30000},
               "perturbation": {"kind": "moving",
                                "movement": {"shape": "sine", "mean": -0.105, "amplitude": 0.305, "frequency": 0.1},
                                "perturbation": {"kind": "filtered_noise", "cutoff": 15, "order": 2, "rms": 0.02},
                                "fade": 1.0},
               "sensors": {"torque": {"noise_variance_ratio": 0.1}},
               "fs_sim": 2000, "duration": 61.0, "acquisition": {"detrend": False, "fs": 100, "trim": 1.0}},
    # a torque drive with a random binary torque (Xu & Hollerbach 1998's elbow): the angle is the output
    "torque_drive": {"joint": {"model": "second_order", "I": 0.06, "B": 0.93, "K": 40.0},
                     "apparatus": {"kind": "torque_drive"},
                     "perturbation": {"kind": "prbs", "amplitude": 4, "clock": 0.01, "sequence": "mls"},
                     "sensors": {"torque": {"noise_rms": 0.5}},
                     "fs_sim": 2000, "duration": 9.0, "acquisition": {"detrend": False, "fs": 500, "trim": 0.5}},
}

#: the multisine kind's lowest line (Hz): where KBR and skirt report the stiffness
MULTISINE_LOWEST_LINE = 0.5

#: realizations of an ensemble record (twice the ensemble IRF's lags at its defaults: with as many realizations as
#: lags its per-time regression is barely determined and predicts nothing)
REALIZATIONS = 20
#: realizations of the narrow-band ensemble: more than the ensemble IRF's lags at 40 ms and 500 Hz (41)
NARROW_BAND_REALIZATIONS = 50


@dataclasses.dataclass(frozen=True)
class Kind:
    """The data an estimator is checked on.

    Attributes
    ----------
    name : str
        A key of :data:`EXPERIMENTS`.
    ensemble : bool
        Records given as an :class:`~jointbench.core.ensemble.Ensemble` of :data:`REALIZATIONS` realizations.
    stiffness_hz : float
        Where the estimate's low-frequency stiffness is compared with the truth's frozen response
        (``|H(stiffness_hz)|``): 0 (K itself), or a multisine's lowest line.
    """

    name: str
    ensemble: bool = False
    stiffness_hz: float = 0.0


def kind_of(cls) -> Kind:
    """The kind of record ``cls`` identifies from: a multisine where it needs one (``perturbations``), an
    ensemble where it takes nothing else (``accepts``), a torque drive for a recursive time-varying method
    (tag ``recursive``: FSEWLS, Xu & Hollerbach's elbow), a slow movement with a perturbation on top for a
    parameter-varying one (tag ``lpv``), else one position-servo trial. An estimator
    tagged ``ensemble`` that takes ensembles is checked on ensembles (its intervals come from the realizations)."""
    from jointbench import estimators

    tags = set(estimators.REGISTRY.tags(cls.name)) if cls.name in estimators.REGISTRY.names() else set()
    if "multisine" in cls.perturbations:
        return Kind("multisine", ensemble="trial" not in cls.accepts, stiffness_hz=MULTISINE_LOWEST_LINE)
    if "ensemble" in cls.accepts and ("ensemble" in tags or not {"trial", "pooled"} & cls.accepts):
        return Kind("ensemble", ensemble=True)
    if "recursive" in tags:
        return Kind("torque_drive")
    if "lpv" in tags:
        return Kind("moving")
    return Kind("trial")


def reference(kind: Kind, seed: int) -> Trial | Ensemble:
    """A record of ``kind`` simulated with ``seed`` (its truth attached)."""
    from jointbench import sims

    exp = sims.Experiment.from_mapping(EXPERIMENTS[kind.name], f"conformance kit ({kind.name})")
    if not kind.ensemble:
        return sims.simulate(exp, seed, name=f"{kind.name}{seed}")
    trials = tuple(sims.simulate(exp, seed, name=f"{kind.name}{seed}r{r}", realization=r) for r in range(REALIZATIONS))
    return Ensemble(trials, name=f"{kind.name}{seed}")


def narrow_band(seed: int, fs: float = 500.0, duration: float = 30.0, fmax: float = 12.0,
                noise: float = 0.1) -> Trial:
    """Issue 33's narrow-band record: a random-phase multisine angle (lines every 0.1 Hz to ``fmax``) and its
    exact torque ``I u'' + B u' + K u`` (:data:`NARROW_BAND_TRUTH`), plus noise of ``noise`` times the torque's
    variance low-passed at 30 Hz (4th-order Butterworth).

    The angle and torque are exact sums of cosines (the derivatives analytic), so the truth is exact.
    """
    from scipy import signal

    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration * fs))) / fs
    lines = np.arange(1, int(round(fmax * 10)) + 1) / 10.0
    amp = np.full(len(lines), 0.02 / np.sqrt(len(lines) / 2))          # 0.02 rad rms
    w = 2 * np.pi * lines
    T = NARROW_BAND_TRUTH
    Z = T["K"] + 1j * w * T["B"] - T["I"] * w ** 2
    arg = np.outer(t, w) + rng.uniform(0, 2 * np.pi, len(lines))
    angle = np.cos(arg) @ amp
    torque = np.cos(arg + np.angle(Z)) @ (amp * np.abs(Z))
    b, a = signal.butter(4, 30.0 / (fs / 2))
    e = signal.lfilter(b, a, rng.standard_normal(len(t)))
    e *= np.sqrt(noise * np.var(torque) / np.var(e))
    truth = Truth(T["I"], T["B"], T["K"], signals={"angle": angle, "torque": torque},
                  num=np.array([T["I"], T["B"], T["K"]]), den=np.array([1.0]))
    return Trial.from_arrays(angle, torque + e, fs, truth=truth, name=f"narrow_band{seed}")


def narrow_band_records(kind: Kind, seed: int, realizations: int = NARROW_BAND_REALIZATIONS, duration: float = 30.0):
    """The narrow-band record in the shape ``kind`` takes: one trial, or an ensemble of realizations (each
    its own phases: seeds ``1000 seed + r``)."""
    if not kind.ensemble:
        return narrow_band(seed, duration=duration)
    trials = tuple(narrow_band(1000 * seed + r, duration=duration).replace(name=f"narrow_band{seed}r{r}")
                   for r in range(realizations))
    return Ensemble(trials, name=f"narrow_band{seed}")
