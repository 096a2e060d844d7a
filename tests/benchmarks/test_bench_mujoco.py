"""Benchmark: one 50 s trial at 2500 Hz (van de Ruit et al.'s wrist with handle and contact, 125 000
steps) on the MuJoCo backend, with the analytic backend on the same input as the same-run baseline.

One trial is one ``mujoco.rollout`` call (the whole control sequence at once, no Python loop over
steps). Run with ``make bench`` for timings; in ``make test`` each runs once, untimed.
"""
import dataclasses

import numpy as np
import pytest

from jointbench.sims import Experiment, simulate
from tests.test_backend_mujoco import WRIST

pytest.importorskip("mujoco")


@pytest.fixture(scope="module")
def experiments():
    analytic = Experiment.from_mapping(WRIST, "bench")
    return analytic, dataclasses.replace(analytic, backend="mujoco")


@pytest.fixture(scope="module")
def inputs(experiments):
    e = experiments[0]
    rng = np.random.default_rng(np.random.SeedSequence(0).spawn(1)[0])
    return e.perturbation.generate(e.n_sim, e.fs_sim, rng), np.zeros(e.n_sim)


@pytest.mark.benchmark(group="mujoco-trial-50s-2500Hz")
def test_bench_mujoco_backend(benchmark, experiments, inputs):
    """The physics alone: controls, one rollout of 125 000 steps, the response."""
    from jointbench.sims.backend_mujoco import MujocoBackend

    e = experiments[1]
    MujocoBackend().respond(e, *inputs)            # the compiled model is cached, as in a study
    resp = benchmark(MujocoBackend().respond, e, *inputs)
    assert resp.angle.shape == (125_000,) and np.all(np.isfinite(resp.torque_measured))


@pytest.mark.benchmark(group="mujoco-trial-50s-2500Hz")
def test_bench_analytic_backend_baseline(benchmark, experiments, inputs):
    """The same input through the analytic backend (ltv: exponential midpoint, parallel prefix scan)."""
    from jointbench.sims.backend import AnalyticBackend

    resp = benchmark(AnalyticBackend().respond, experiments[0], *inputs)
    assert resp.angle.shape == (125_000,)


@pytest.mark.benchmark(group="mujoco-trial-50s-2500Hz")
def test_bench_mujoco_whole_trial(benchmark, experiments):
    """The whole trial on MuJoCo: multisine, physics, sensors, frequency-domain decimation to 44 Hz."""
    trial = benchmark(simulate, experiments[1], 0)
    assert trial.n == 1760


@pytest.mark.benchmark(group="mujoco-trial-50s-2500Hz")
def test_bench_analytic_whole_trial_baseline(benchmark, experiments):
    trial = benchmark(simulate, experiments[0], 0)
    assert trial.n == 1760
