"""Held-out simulated recordings for the tests of ``jointbench estimate`` (issue 13), made by ``sims``.

Three kinds of record a lab brings to the command, each with the imperfections of a real one:

* :func:`lti_ankle`: an ankle-like joint (I 0.01 kg m^2, B 0.8 N m s/rad, K 140 N m/rad) on a stiff
  position servo, 15 Hz low-passed noise perturbation about a 0.15 rad operating point, voluntary torque
  (5 N m mean, 0.5 N m rms below 1 Hz), encoder quantisation and torque noise; simulated at 10 kHz and
  acquired at 500 Hz, the record cut out of a longer run (it starts and ends mid-perturbation: the end
  effect of a real recording).
* :func:`tv_elbow`: the Xu & Hollerbach elbow (K = 40 +- 15 N m/rad at 0.5 Hz), PRBS torque drive,
  torque noise, 1 kHz.
* :func:`gated_wrist`: the van de Ruit wrist with hand contact under a 10 s multisine that is off for
  the first and last 5 s of a 50 s record (a gated multisine), torque noise, decimated in the frequency
  domain to 50 Hz.
"""
from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from jointbench.cli import main
from jointbench.core.types import Trial
from jointbench.sims import simulate
from jointbench.sims.experiment import Experiment

LTI_TRUTH = {"I": 0.01, "B": 0.8, "K": 140.0}


def lti_ankle(seed: int, duration: float = 10.0) -> Trial:
    exp = {"joint": {"model": "second_order", **LTI_TRUTH},
           "apparatus": {"kind": "position_servo", "stiffness": 30000},
           "perturbation": {"kind": "filtered_noise", "cutoff": 15, "order": 2, "rms": 0.02},
           "voluntary": {"mean": 5.0, "rms": 0.5, "cutoff": 1},
           "sensors": {"angle": {"quantization": 6.28e-5}, "torque": {"noise_rms": 0.05}},
           "fs_sim": 10000, "duration": duration + 1.0,
           "acquisition": {"detrend": False, "fs": 500, "trim": 0.5}}
    t = simulate(Experiment.from_mapping(exp), seed=seed, name=f"ankle{seed}")
    return t.replace(angle=t.angle + 0.15)


def tv_elbow(seed: int, duration: float = 20.0) -> Trial:
    exp = {"joint": {"model": "time_varying", "I": 0.06, "damping_ratio": 0.3,
                     "K": {"shape": "sine", "mean": 40, "amplitude": 15, "frequency": 0.5}},
           "apparatus": {"kind": "torque_drive"},
           "perturbation": {"kind": "prbs", "amplitude": 4, "clock": 0.01, "sequence": "mls"},
           "sensors": {"torque": {"noise_rms": 0.5}},
           "fs_sim": 2000, "duration": duration + 1.0, "acquisition": {"detrend": False, "fs": 1000, "trim": 0.5}}
    return simulate(Experiment.from_mapping(exp), seed=seed, name=f"elbow{seed}")


def gated_wrist(seed: int, fs: float = 50.0, duration: float = 50.0, quiet: float = 5.0,
                noise: float = 0.03) -> Trial:
    acq = {"detrend": False} if fs == 2500 else {"detrend": False, "fs": fs, "decimation": "fft"}
    exp = {"joint": {"model": "wrist_contact", "I": 0.003, "b": 0.035, "b_c": 10, "k_c": 100,
                     "k": {"shape": "sine", "mean": 5.6, "amplitude": 0.9, "period": 20}},
           "apparatus": {"kind": "handle"},
           "perturbation": {"kind": "multisine", "period": 10, "f_min": 0.1, "f_max": 19.3, "spacing": 0.8,
                            "corner": 6, "slope": -20, "rms": 0.02, "quiet": quiet},
           "sensors": {"torque": {"noise_filter": {"kind": "butter", "order": 2, "cutoff": 15},
                                  "noise_variance_ratio": noise}},
           "fs_sim": 2500, "duration": duration, "acquisition": acq}
    return simulate(Experiment.from_mapping(exp), seed=seed, name=f"wrist{seed}")


def save(path: Path, t: Trial) -> Path:
    np.savez(path, time=t.time, angle=t.angle, torque=t.torque)
    return path


def run(argv) -> tuple[int, str, str]:
    """``jointbench estimate ARGV`` in this process: exit status, stdout, stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["estimate", *map(str, argv)])
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(autouse=True)
def one_blas_thread_per_test():
    """One BLAS thread, as the command itself runs (jointbench.cli.studies): threads on a loaded 2-core machine
    turn seconds of linear algebra into minutes. Autouse in the modules that import it."""
    with threadpool_limits(limits=1):
        yield
