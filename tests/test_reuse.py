"""Reuse of simulated responses (sims.reuse) and the grouping of cases that share them: bit-identical
results to computing every trial and every case alone, and the counts of responses actually computed."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from jointbench import sims
from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.harness.case import run_case, run_group
from jointbench.benchmarks.runner import expand, group_cases
from jointbench.sims.reuse import reuse_responses
from tests.harness_studies import study_copy


def _same_trial(a, b) -> None:
    assert np.array_equal(a.angle, b.angle) and np.array_equal(a.torque, b.torque)
    assert a.truth.signals.keys() == b.truth.signals.keys()
    for k in a.truth.signals:
        assert np.array_equal(a.truth.signals[k], b.truth.signals[k]), k


@pytest.fixture(scope="module")
def wrist():
    part = load_study("vanderuit2018_table1").parts["table1"]
    return sims.Experiment.from_mapping({**part.experiment, "acquisition": {"detrend": False, "fs": "44 Hz",
                                                                            "decimation": "fft", "trim": "5 s"}},
                                        "test")


def test_trials_with_other_noise_replicates_and_rates_reuse_one_response(wrist):
    torque = dataclasses.replace(wrist.sensors.torque, noise_variance_ratio=0.1)
    noisy = dataclasses.replace(wrist, sensors=dataclasses.replace(wrist.sensors, torque=torque))
    faster = dataclasses.replace(noisy, acquisition=dataclasses.replace(noisy.acquisition, fs=100.0))
    calls = [(wrist, {}), (noisy, {}), (noisy, {"replicate": 1}), (faster, {}), (wrist, {"realization": 1}),
             (noisy, {"realization": 1, "replicate": 2})]
    alone = [sims.simulate(e, 7, **kw) for e, kw in calls]
    with reuse_responses() as memo:
        shared = [sims.simulate(e, 7, **kw) for e, kw in calls]
    assert (memo.computed, memo.reused) == (2, 4)          # realization 0 and realization 1
    for a, b in zip(alone, shared):
        _same_trial(a, b)
    # what a block keeps is handed out read-only in fresh containers: no caller can change what it keeps
    with reuse_responses() as memo:
        first = sims.simulate(wrist, 7)
        with pytest.raises(ValueError, match="read-only"):
            first.truth.signals["command"][:] = 0.0
        first.truth.signals["command"] = np.zeros(3)       # the caller's own dict, not the memo's
        _same_trial(sims.simulate(wrist, 7), alone[0])
    assert sims.simulate(wrist, 7).torque.flags.writeable   # outside a block: the caller's own arrays


def test_what_changes_the_response_is_never_reused(wrist):
    other_k = dataclasses.replace(wrist, joint=dataclasses.replace(wrist.joint, k=5.0))
    with reuse_responses() as memo:
        a, b, c = sims.simulate(wrist, 1), sims.simulate(wrist, 2), sims.simulate(other_k, 1)
    assert (memo.computed, memo.reused) == (3, 0)
    assert not np.array_equal(a.torque, b.torque) and not np.array_equal(a.torque, c.torque)
    ss = np.random.SeedSequence(5)         # a SeedSequence given twice spawns other streams the second time
    with reuse_responses() as memo:
        x, y = sims.simulate(wrist, ss), sims.simulate(wrist, ss)
    assert memo.reused == 0 and not np.array_equal(x.angle, y.angle)


def _rows(results) -> list:
    """Every row of every case without the timings (which differ from run to run)."""
    out = []
    for r in results:
        assert r.status == "ok", r.error
        out.append([{k: v for k, v in row.items()} for row in r.rows if row["metric"] != "fit_time_s"])
        out.append(r.curves)
    return out


def _small(study: str, part: str, tmp_path, change) -> list:
    path = study_copy(tmp_path, study, lambda d: change(d["parts"][part]))
    return expand(load_study(path), [part])


def test_grouped_cases_are_bit_identical_to_every_case_alone(tmp_path):
    """xu1998's readings part (variants that change the estimator, the scoring or the response) and
    vanderuit2018_table1 (noise levels, estimation and validation trials): grouped, each distinct response
    is simulated once, and every row equals the case computed alone without any reuse."""
    def xu(r):
        r["seeds"] = 1
        r["experiment"] = {**r["experiment"], "duration": "14 s"}
        r["sweep"] = {"variant": ["chosen", "zeta_0.1", "tau_v_measured", "lambda_17", "exact_derivatives"],
                      "condition": ["movement"], "f_v": [0.5]}

    def vdr(t):
        t["seeds"] = 1
        t["sweep"] = {"variation": ["square10"], "snr_db": [5, 10, float("inf")]}
        t["params"] = {**t["params"], "curve_seeds": [], "image_variations": []}
        t["estimators"] = {"skirt": t["estimators"]["skirt"]}

    for cases, groups, responses in ((_small("xu1998", "readings", tmp_path, xu), [[0, 2, 3, 4], [1]], 2),
                                     (_small("vanderuit2018_table1", "table1", tmp_path, vdr), [[0, 1, 2]], 1)):
        assert group_cases(cases) == groups
        with reuse_responses(enabled=False):
            alone = [run_case(c) for c in cases]
        assert all(e[2] == 0 for r in alone for e in r.sim_times)          # nothing reused
        grouped = [res for g in groups for res in run_group([cases[i] for i in g])]
        order = [i for g in groups for i in g]
        grouped = [grouped[order.index(i)] for i in range(len(cases))]
        assert _rows(grouped) == _rows(alone)
        computed = sum(1 for r in grouped for e in r.sim_times if not e[2])
        assert computed == responses, [r.sim_times for r in grouped]


def test_the_full_studies_need_the_counts_of_the_issue():
    """vanderuit2018_table1: 300 cases of 2 trials = 600 simulated trials (with the N_p = 7 skirt part of
    reading R12, 60 cases), still 40 distinct responses (4 variations x 10 seeds); xu1998's readings part:
    600 cases, 120 distinct responses (2 conditions x 2 f_v x 3 damping ratios x 10 seeds; the issue counted
    520 cases before the two exact-derivative variants)."""
    vdr = expand(load_study("vanderuit2018_table1"))
    assert len(vdr) == 300 and len(group_cases(vdr)) == 40
    xu = expand(load_study("xu1998"), ["readings"])
    assert len(xu) == 600 and len(group_cases(xu)) == 120


def test_a_trial_asked_for_again_is_the_same_trial(wrist):
    """Cases that fit one trial with different estimators share the whole trial, not only its response."""
    alone = sims.simulate(wrist, 3, name="validation", replicate=1)
    with reuse_responses() as memo:
        a = sims.simulate(wrist, 3, name="validation", replicate=1)
        b = sims.simulate(wrist, 3, name="validation", replicate=1)
        c = sims.simulate(wrist, 3, name="estimation")
    assert (memo.computed, memo.reused) == (1, 1) and (memo.trials.computed, memo.trials.reused) == (2, 1)
    _same_trial(a, alone)
    _same_trial(b, alone)
    assert a.name == b.name == "validation" and c.name == "estimation"
    assert a is not b and a.angle is b.angle and not a.angle.flags.writeable   # the same arrays, read-only


def test_sensed_channels_are_filtered_once_per_response_filter_and_acquisition(wrist):
    """Trials that differ only in noise or quantization share the filtered, acquired noise-free channels
    (delay-corrected sensor filters, noise on both channels); another filter or rate filters anew. A channel's
    unit noise is drawn once per seed, replicate, noise filter and acquisition, whatever its level."""
    flt = {"kind": "bessel", "order": 8, "cutoff": 150.0, "delay_correction": True}
    sensors = sims.Experiment.from_mapping({**load_study("vanderuit2018_table1").parts["table1"].experiment,
                                            "sensors": {"angle": {"filter": flt}, "torque": {"filter": flt}}},
                                           "test").sensors
    base = dataclasses.replace(wrist, sensors=sensors)

    def with_sensors(angle=None, torque=None):
        return dataclasses.replace(base, sensors=dataclasses.replace(
            base.sensors, angle=dataclasses.replace(base.sensors.angle, **(angle or {})),
            torque=dataclasses.replace(base.sensors.torque, **(torque or {}))))

    other_filter = dataclasses.replace(sensors.torque.filter, cutoff=100.0)
    calls = [(base, {}), (with_sensors(torque={"noise_variance_ratio": 0.2}), {}),
             (with_sensors(angle={"noise_rms": 1e-4, "quantization": 1e-4}), {"replicate": 1}),
             (with_sensors(angle={"quantization": 1e-4}), {}),
             (with_sensors(torque={"filter": other_filter, "noise_rms": 0.01}), {}),
             (dataclasses.replace(base, acquisition=dataclasses.replace(base.acquisition, fs=100.0)), {})]
    alone = [sims.simulate(e, 4, **kw) for e, kw in calls]
    with reuse_responses() as memo:
        shared = [sims.simulate(e, 4, **kw) for e, kw in calls]
    assert (memo.computed, memo.reused) == (1, 5)
    assert (memo.sensed.computed, memo.sensed.reused) == (3, 3)      # base; other torque filter; other rate
    assert (memo.noise.computed, memo.noise.reused) == (2, 1)        # torque (replicate 0) drawn once for two levels
    for a, b in zip(alone, shared):
        _same_trial(a, b)
    assert not np.array_equal(shared[0].torque, shared[1].torque)    # the noise is drawn anew
