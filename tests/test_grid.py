"""Comparison grids from YAML: expansion, skipped combinations and their reasons in the report, bad input
(one line naming the axis, the value and what is allowed), the time budget, and --set overrides."""
from __future__ import annotations

import pandas as pd
import pytest

from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.compare.grid import stiffness_profile, Stiffness
from jointbench.benchmarks.runner import expand_study
from jointbench.benchmarks.study import OverBudget, run_study
from jointbench.core.errors import ConfigError
from tests.harness_studies import cli_here as cli, tiny_grid_part, tiny_study


def _study(tmp_path, **part):
    return tiny_study(tmp_path, extra_parts={"grid": {**tiny_grid_part(), **part}})


def test_grid_expands_and_skips_what_an_estimator_cannot_run(tmp_path):
    grid = tiny_grid_part(["ibk_spectral", "kbr", "sds", "ensemble_irf"], data=["trial", "ensemble"])
    study = load_study(tiny_study(tmp_path, extra_parts={"grid": grid}))
    cases, skipped = expand_study(study, ["grid"])
    ran = {(c.sweep["estimator"], c.sweep["data"]) for c in cases}
    # ibk_spectral takes single trials; sds both; ensemble_irf ensembles only; kbr needs a multisine
    assert ran == {("ibk_spectral", "trial"), ("sds", "trial"), ("sds", "ensemble"), ("ensemble_irf", "ensemble")}
    why = {(s["estimator"], s["data"]): s["reason"] for s in skipped}
    assert "multisine" in why[("kbr", "trial")] and "multisine" in why[("kbr", "ensemble")]
    assert "not an ensemble" in why[("ibk_spectral", "ensemble")]
    assert "not a single trial" in why[("ensemble_irf", "trial")]
    assert len(cases) + len(skipped) == study.parts["grid"].grid.size()
    one = next(c for c in cases if c.sweep["estimator"] == "sds")
    assert one.experiment["joint"]["K"] == {"shape": "square", "mean": 50, "amplitude": 10, "period": 4.0}
    assert one.estimators == {"sds": grid["estimators"]["sds"]}


def test_skipped_combinations_are_reported_with_their_reason(tmp_path):
    run = run_study(_study(tmp_path / "c"), out_root=tmp_path / "r", serial=True, progress=False)
    assert not run.failed
    skipped = run.rows[run.rows["metric"] == "skipped"]
    assert set(skipped["estimator"]) == {"kbr"} and len(skipped) == 2
    assert skipped["reason"].str.contains("needs a 'multisine' perturbation").all()
    report = (run.folder / "report.md").read_text()
    assert "Combinations skipped or not fitted, and why" in report and "needs a 'multisine'" in report
    assert "value [90 % interval] #rank" in report and (run.folder / "grid_heatmap.png").is_file()
    assert (run.folder / "grid_tradeoff.png").is_file()
    scores = pd.read_csv(run.folder / "grid_scores.csv")
    assert {"vaf_stiffness", "bias_rms", "random_error", "total_error", "rise_time_s", "vaf_output",
            "fit_time_s"} <= set(scores["metric"])


def test_a_combination_that_cannot_be_built_is_skipped_with_the_reason(tmp_path):
    cases, skipped = expand_study(load_study(_study(tmp_path, grid={**tiny_grid_part()["grid"],
                                                                     "fs": ["native", "300 Hz"]})), ["grid"])
    bad = [s for s in skipped if s["fs"] == 300.0]
    assert bad and all("does not divide fs_sim" in s["reason"] for s in bad)
    assert all(c.sweep["fs"] == "native" for c in cases)


def test_an_estimator_that_refuses_the_data_is_reported_not_fitted(tmp_path):
    part = tiny_grid_part(["ensemble_irf"])
    part["estimators"]["ensemble_irf"] = {"lag_before": "20 ms", "lag_after": "20 ms"}   # 9 lags, 2 realizations
    run = run_study(tiny_study(tmp_path / "c", extra_parts={"grid": part}), parts=["grid"],
                    out_root=tmp_path / "r", serial=True, progress=False)
    nf = run.rows[run.rows["metric"] == "not_fitted"]
    assert len(nf) == 2 and nf["reason"].str.contains("needs at least as many realizations as lags").all()


@pytest.mark.parametrize("change, words", [
    ({"grid": {"estimator": ["ibk_spectral", "fsewl"]}}, "grid.estimator[1]: unknown estimator 'fsewl'; allowed: "),
    ({"grid": {"estimator": ["sds"], "scenario": ["knee"]}},
     "grid.scenario[0]: unknown scenario 'knee'; allowed: elbow"),
    ({"grid": {"estimator": ["sds"], "variation": ["triangle"]}},
     "grid.variation[0]: unknown variation 'triangle'; allowed: native, square, sine"),
    ({"grid": {"estimator": ["sds"], "noise": [0.1, "loud"]}}, "grid.noise[1]: expected a number >= 0"),
    ({"grid": {"estimator": ["sds"], "backend": ["bullet"]}}, "grid.backend[0]: unknown simulation backend 'bullet'"),
    ({"grid": {"estimator": ["sds"], "data": ["pooled"]}},
     "grid.data[0]: 'pooled' not allowed; allowed: trial, ensemble"),
    ({"grid": {"estimator": ["sds"], "joint": ["knee_model"]}}, "no model file knee_model.yaml"),
    ({"grid": {"estimator": ["sds"], "colour": ["red"]}}, "grid: unknown key 'colour'; allowed: scenario"),
    ({"grid": {"estimator": ["sds"], "fs": ["fast"]}}, "grid: key 'fs[0]': expected a number in Hz"),
    ({"grid": {"scenario": ["elbow"]}}, "grid: missing required key 'estimator'"),
    ({"grid": {"estimator": ["sds", "sds"]}}, "grid.estimator: a value is listed twice"),
    ({"estimators": {"sdss": {}}}, "estimators: unknown estimator 'sdss'"),
    ({"estimators": {"sds": {"window": "-1 s"}}}, "estimators.sds (scenario elbow)"),
    ({"budget": "soon"}, "key 'budget': expected a number in min, got 'soon'"),
    ({"budget": 0}, "key 'budget': must be > 0 min"),
    ({"protocol": "parametric_fit"}, "a part with a 'grid' runs protocol 'compare'"),
])
def test_bad_grid_input_is_one_line_naming_the_path(tmp_path, change, words):
    path = _study(tmp_path, **change)
    with pytest.raises(ConfigError) as exc:
        load_study(path)
    msg = str(exc.value)
    assert words in msg and "\n" not in msg and "parts.grid" in msg, msg


def test_bad_grid_input_on_the_command_line_is_one_line_and_exit_2(tmp_path):
    path = _study(tmp_path, grid={"estimator": ["fsewl"]})
    r = cli("run", path, "--out", tmp_path / "out")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "unknown estimator 'fsewl'" in r.stderr


def test_a_grid_over_its_budget_says_so_before_running(tmp_path):
    path = _study(tmp_path, budget=0.001)
    with pytest.raises(OverBudget) as exc:
        run_study(path, parts=["grid"], out_root=tmp_path / "r", serial=True, progress=False)
    msg = str(exc.value)
    assert "4 cases" in msg and "2 combinations skipped" in msg and "estimated" in msg and "--yes" in msg
    assert not (tmp_path / "r" / "cache").exists() or not list((tmp_path / "r" / "cache").rglob("*.json"))
    r = cli("run", path, "--parts", "grid", "--out", tmp_path / "out", "--serial", "--quiet")
    assert r.returncode == 2 and "more than the 0.001-minute budget" in r.stderr and "--yes" in r.stderr
    r = cli("run", path, "--parts", "grid", "--out", tmp_path / "out", "--serial", "--quiet", "--yes")
    assert r.returncode == 0, r.stderr
    r = cli("run", path, "--parts", "grid", "--out", tmp_path / "out", "--serial", "--quiet")
    assert r.returncode == 0, r.stderr          # everything cached now: nothing left to estimate


def test_relative_variations_take_the_scenario_levels():
    lv = Stiffness(mean=40, amplitude=15, period=2)
    assert stiffness_profile({"shape": "square"}, lv) == {"shape": "square", "mean": 40, "amplitude": 15, "period": 2}
    assert stiffness_profile({"shape": "sine", "frequency": 1, "amplitude": 5}, lv) == {
        "shape": "sine", "frequency": 1, "amplitude": 5, "mean": 40}
    assert stiffness_profile({"shape": "ramp", "duration": 10, "start": 5}, lv) == {
        "shape": "ramp", "duration": 10, "start": 5, "initial": 25, "final": 55}
    assert stiffness_profile({"shape": "constant"}, lv) == 40.0


# ------------------------------------------------------------------------------------------- --set
def test_set_overrides_values_before_the_strict_parse():
    st = load_study("vanderuit2018_table1", overrides=["table1.seeds=3", "table1.sweep.snr_db=[10]",
                                                        "table1.estimators.kbr.sigma=15 s"])
    p = st.parts["table1"]
    assert p.seeds == (0, 1, 2) and p.sweep["snr_db"] == (10,) and p.estimators["kbr"]["sigma"] == "15 s"
    # the anchored estimators/experiment of the other parts are untouched
    assert st.parts["table1_snr_standard"].estimators["kbr"]["sigma"] == "20 s"
    assert len(st.parts["table1_snr_standard"].seeds) == 10
    every = load_study("xu1998", overrides=["*.seeds=2", "fig2.experiment.joint.I=0.07",
                                            "fig2.experiment.duration=20 s"])
    assert all(len(p.seeds) == 2 for p in every.parts.values())
    assert every.parts["fig2"].experiment["joint"]["I"] == 0.07 and every.parts["fig2"].experiment["duration"] == "20 s"
    assert every.parts["fig3"].experiment["joint"]["I"] == "0.06 kg.m2"
    assert every.parts["fig3"].experiment["duration"] == "49 s"


def test_set_on_a_grid_axis(tmp_path):
    st = load_study(_study(tmp_path), overrides=["grid.grid.noise=[0.1]", "grid.params.realizations=2"])
    g = st.parts["grid"]
    assert g.grid.axes["noise"] == (0.1,) and g.params["realizations"] == 2


@pytest.mark.parametrize("override, words", [
    ("table1.seeds", "expected PART.KEY=VALUE"),
    ("seeds=3", "name the part and the key"),
    ("tabel1.seeds=3", "has no part 'tabel1'; parts: table1, table1_snr_standard"),
    ("table1.seeds=[1, 2", "the value is not valid YAML"),
    ("table1.seeds.first=3", "'table1.seeds' is 10, not a mapping"),
    ("table1.sed=3", "parts.table1 (with --set table1.sed=3): unknown key 'sed'"),
    ("table1.seeds=-1", "parts.table1 (with --set table1.seeds=-1): key 'seeds': need at least 1 seed"),
    ("table1.params.score=[5 s]", "(with --set table1.params.score=[5 s])"),
])
def test_bad_set_is_one_line_naming_the_path(override, words):
    with pytest.raises(ConfigError) as exc:
        load_study("vanderuit2018_table1", overrides=[override])
        from jointbench.benchmarks.runner import expand

        expand(load_study("vanderuit2018_table1", overrides=[override]))
    assert words in str(exc.value) and "\n" not in str(exc.value), str(exc.value)


def test_set_on_the_command_line(tmp_path):
    path = tiny_study(tmp_path / "c", seeds=4)
    r = cli("run", path, "--out", tmp_path / "out", "--serial", "--quiet", "--set", "fit.seeds=2")
    assert r.returncode == 0, r.stderr
    assert "tiny: 2 cases" in r.stdout
    r = cli("run", path, "--out", tmp_path / "out", "--set", "fit.seeds=two")
    assert r.returncode == 2 and "--set fit.seeds=two" in r.stderr and r.stderr.count("\n") == 1
