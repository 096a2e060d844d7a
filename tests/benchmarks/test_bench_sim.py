"""Benchmark: one simulated trial of the Westwick & Perreault 2012 elbow experiment (Sec. IV), with the
LTI backend alone on the same input as a same-run baseline."""
import numpy as np
import pytest

from sims import Experiment, simulate
from sims.backend_lti import LTIBackend

SPEC = {
    "joint": {"model": "second_order", "I": 0.171, "B": 1.22, "K": 53.5},
    "apparatus": {"kind": "position_servo", "stiffness": 30000},
    "perturbation": {"kind": "filtered_noise", "cutoff": "10 Hz", "order": 2, "rms": "0.02 rad"},
    "voluntary": {"mean": 1.0, "rms": 0.3, "cutoff": "1 Hz"},
    "sensors": {"angle": {"quantization": "6.28e-5 rad"},
                "torque": {"filter": {"kind": "bessel", "order": 5, "cutoff": "500 Hz"}, "noise_rms": 0.01}},
    "fs_sim": "5 kHz",
    "duration": "30 s",
    "acquisition": {"detrend": True, "fs": "500 Hz", "trim": "0.5 s"},
}


@pytest.fixture(scope="module")
def experiment():
    return Experiment.from_mapping(SPEC, "bench")


@pytest.mark.benchmark(group="simulate-trial")
def test_bench_simulate_trial(benchmark, experiment):
    trial = benchmark(simulate, experiment, 0)
    assert trial.n == 14500 and trial.fs == 500.0


@pytest.mark.benchmark(group="simulate-trial")
def test_bench_backend_alone_baseline(benchmark, experiment):
    e = experiment
    ss = np.random.SeedSequence(0).spawn(2)
    drive = e.perturbation.generate(e.n_sim, e.fs_sim, np.random.default_rng(ss[0]))
    tv = e.voluntary.generate(e.n_sim, e.fs_sim, np.random.default_rng(ss[1]))
    resp = benchmark(LTIBackend().run, e.joint, e.apparatus, drive, tv, e.fs_sim)
    assert resp.angle.shape == (150_000,)
