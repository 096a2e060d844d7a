"""The Python API (jointbench.api): the CLI's numbers from a notebook, and docs/api.md's examples run."""
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from jointbench import api, estimators
from jointbench.core.errors import ConfigError, InputError
from tests.estimate_data import gated_wrist
from tests.harness_studies import cli_here

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def gated_record(tmp_path_factory):
    """A gated multisine (quiet 5 s at both ends) on the simulated wrist, saved as CSV."""
    t = gated_wrist(103)
    path = tmp_path_factory.mktemp("gated") / "wrist.csv"
    pd.DataFrame({"time": t.time, "angle": t.angle, "torque": t.torque}).to_csv(path, index=False)
    return t, path


def test_a_notebook_fit_and_jointbench_estimate_give_the_same_numbers(gated_record, tmp_path):
    trial, path = gated_record
    out = tmp_path / "skirt.csv"
    cmd = cli_here("estimate", "-e", "skirt", "-i", path, "-o", out)        # in-process: both paths absolute
    assert cmd.returncode == 0, cmd.stderr
    assert "gated multisine" in cmd.stdout
    fit = api.fit("skirt", path)                                  # what a notebook does, no options
    assert fit.notes and "gated multisine" in fit.notes[0]         # cropped to the whole periods, as the command
    command = pd.read_csv(out)
    assert list(command.columns) == list(fit.frame.columns)
    np.testing.assert_allclose(command.to_numpy(float), fit.frame.to_numpy(float), rtol=1e-9, atol=1e-12)
    (printed,) = [float(v) for v in re.findall(r"^\s+wrist\.csv\s+(-?[\d.]+) %", cmd.stdout, re.M)]
    assert fit.vaf == [pytest.approx(printed, abs=0.051)]                  # one VAF per record
    # and the same from arrays (a simulated trial, its truth kept for scoring)
    again = api.fit("skirt", angle=trial.angle, torque=trial.torque, fs=trial.fs)
    np.testing.assert_allclose(again.frame.to_numpy(float), command.to_numpy(float), rtol=1e-6, atol=1e-9)
    # without the pipeline (the whole record, quiet ends included) the plain fit finds no lines: the crop matters
    with pytest.raises(InputError, match="no clearly excited lines"):
        estimators.make("skirt").fit(trial)


def test_errors_name_the_arguments_and_the_command_names_its_flags(gated_record, tmp_path):
    trial, path = gated_record
    with pytest.raises(ConfigError, match=r"^window: the end \(3 s\) must come after the start \(5 s\)"):
        api.fit("irf2_ls", trial, window=(5, 3))
    with pytest.raises(ConfigError, match=r"^window: .*5x"):
        api.fit("irf2_ls", trial, window="5x:")
    with pytest.raises(ConfigError, match=r"^decimate: expected a whole number >= 1"):
        api.fit("irf2_ls", trial, decimate=0)
    with pytest.raises(ConfigError, match=r"^settings \(estimator 'irf2_ls'\): key 'lag_before': must be >= 0"):
        api.fit("irf2_ls", trial, settings={"lag_before": -1})
    with pytest.raises(InputError, match=r"^window: record 'wrist103' is 50 s long"):
        api.fit("irf2_ls", trial, window=(0, 60))
    from tests.estimate_data import run

    code, _, err = run(["-e", "irf2_ls", "-i", path, "-o", tmp_path / "o.csv", "--window", "0:60"])
    assert code == 2 and "--window: record 'wrist.csv' is 50 s long" in err
    code, _, err = run(["-e", "irf2_ls", "-i", path, "-o", tmp_path / "o.csv", "--set", "lag_before=-1"])
    assert code == 2 and "--set (estimator 'irf2_ls'): key 'lag_before'" in err
    with pytest.raises(ConfigError, match="give data"):
        api.fit("irf2_ls")


def test_simulate_names_joint_models_and_scenarios_and_exposes_the_scored_stiffness():
    exp = {"joint": "wrist_vanderuit2018", "apparatus": {"kind": "handle"},
           "perturbation": {"kind": "multisine", "period": 10, "f_min": 0.1, "f_max": 19.3, "spacing": 0.8,
                            "quiet": 0},
           "fs_sim": "2500 Hz", "duration": "10 s", "acquisition": {"fs": "100 Hz", "decimation": "fft"}}
    t = api.simulate(exp, seed=1)
    assert t.fs == 100 and t.n == 1000
    k_static = t.frozen_stiffness()          # k in series with the hand contact: below the intrinsic k
    assert np.all(k_static < np.asarray(t.truth.K)) and np.all(k_static > 0)
    assert np.array_equal(api.simulate(exp, seed=1).torque, t.torque)          # same seed, same numbers
    sc = api.scenario("matrix:xu1998_elbow")
    assert {"experiment", "stiffness", "discard"} <= set(sc) and isinstance(sc["experiment"]["joint"], dict)
    short = api.simulate("matrix:xu1998_elbow", seed=0, duration="10 s")
    assert 8.0 <= short.duration <= 10.0           # 10 s simulated, the acquisition's edges trimmed
    with pytest.raises(ConfigError, match="no model file nope.yaml"):
        api.simulate({**exp, "joint": "nope"})
    names = set(api.scenarios()["name"])
    assert {"matrix:xu1998_elbow", "westwick2012:fig6"} <= names


def code_blocks(path: Path) -> list[str]:
    """The ```python blocks of a markdown file."""
    return re.findall(r"^```python\n(.*?)^```", path.read_text(), re.S | re.M)


def test_docs_api_examples_run(tmp_path, monkeypatch):
    """Every ```python block of docs/api.md runs, in order, in one namespace (as a notebook would), in an
    empty folder; the blocks assert what they claim."""
    blocks = code_blocks(REPO / "docs" / "api.md")
    assert len(blocks) >= 5
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "docs_api"}
    before = set(estimators.REGISTRY._items)
    try:
        for i, block in enumerate(blocks):
            exec(compile(block, f"docs/api.md block {i + 1}", "exec"), namespace)   # noqa: S102 - our own docs
    finally:                 # the docs register a toy estimator: not for the other tests (built-in ones
        #                      registered lazily while the blocks ran stay: their modules are imported once)
        for name in set(estimators.REGISTRY._items) - before - set(estimators.REGISTRY._deferred):
            estimators.REGISTRY._items.pop(name)
            estimators.REGISTRY._tags.pop(name, None)


REKLAB = REPO.parent / "shared" / "data" / "reklab-ankle" / "ankle_stationary.npz"


@pytest.mark.skipif(not REKLAB.is_file(), reason="../shared/data/reklab-ankle absent (developers' checkout only)")
def test_the_ankle_example_on_the_api_writes_the_committed_table(tmp_path, monkeypatch, capsys):
    """docs/ankle_example.py (api.fit on the REKLAB records) gives docs/ankle_example.md as committed. The
    script runs as ``__main__`` in this process (its imports are this process's already: 1.7 CPU-s instead of
    4 in an interpreter of its own)."""
    import runpy

    monkeypatch.setattr(sys, "argv", [str(REPO / "docs" / "ankle_example.py"), str(REKLAB), str(tmp_path)])
    runpy.run_path(sys.argv[0], run_name="__main__")
    assert (tmp_path / "ankle_example.md").read_text() == (REPO / "docs" / "ankle_example.md").read_text()
    assert (tmp_path / "ankle_z_df_ibk_irf.png").stat().st_size > 10_000


def test_score_gives_the_fits_own_vaf_on_its_records_and_refuses_another_rate(gated_record):
    """api.score is the fit's own scoring (pipeline.score): on the records as fitted it gives Fit.vaf; a record
    at another rate is refused naming the rates, not scored against a mismatched prediction."""
    trial, _ = gated_record
    fit = api.fit("irf2_ls", trial, window=(5, 45), decimate=2)
    scored = api.score(fit, fit.trials)
    assert list(scored["record"]) == [t.name for t in fit.trials]
    assert list(scored["vaf"]) == fit.vaf and scored["samples"].iloc[0] == fit.predictions[0].used.sum()
    with pytest.raises(ConfigError, match=r"sampled at 50 Hz, the estimate at 25 Hz"):
        api.score(fit, trial)
    flipped = api.score(fit.estimate, [t.replace(torque=-t.torque) for t in fit.trials], torque_sign=-1)
    assert list(flipped["vaf"]) == fit.vaf


def test_the_history_object_answers_what_the_command_prints(tmp_path):
    """One history object (api.History) behind `jointbench history` and `jointbench diff`."""
    from tests.harness_studies import cli_here, tiny_study

    study = tiny_study(tmp_path / "cfg", seeds=1, duration="2 s")
    out = tmp_path / "out"
    for _ in range(2):
        assert cli_here("run", study, "--out", out, "--serial", "--quiet").returncode == 0
    h = api.History(out)
    runs = h.runs()
    assert list(runs["study"]) == ["tiny", "tiny"] and h.run(int(runs["id"].min()))["status"] == "ok"
    first, second = sorted(int(i) for i in runs["id"])
    assert len(h.checks(first)) == 2 and len(h.cases(first)) == 1 and len(h.rows(first)) > 0
    d = h.diff(first, second)
    assert d.study == "tiny" and not d.regressions
    shown = cli_here("history", str(first), "--out", out)
    assert shown.returncode == 0 and f"run {first} (run" in shown.stdout
    with pytest.raises(Exception, match="history"):
        api.History(tmp_path / "nowhere").runs()


@pytest.mark.parametrize("executor", ["serial", "process"])
def test_run_refuses_a_scheduler_without_dask_in_python_words(executor):
    """api.run checks its executor arguments for every kind, serial included (a serial run takes the runner's
    own path, but a scheduler given with it is still an error, worded for a Python caller)."""
    with pytest.raises(ConfigError, match=r"^scheduler applies to executor='dask', not "):
        api.run("westwick2012", executor=executor, scheduler="tcp://127.0.0.1:1", progress=False)
