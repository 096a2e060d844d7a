"""Config strictness, the runner (failures, determinism, cache) and the comparison table."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from jointbench.benchmarks import protocols
from jointbench.benchmarks.config import Check, load_study
from jointbench.benchmarks.locate import STUDIES
from jointbench.benchmarks.runner import Cache, expand, run_cases
from jointbench.benchmarks.study import run_study
from jointbench.benchmarks.checks import judge
from jointbench.core.errors import ConfigError
from tests.harness_studies import study_copy

STUDY = STUDIES / "westwick2012" / "study.yaml"


def write_study(tmp_path: Path, edit) -> Path:
    """A copy of the Westwick study config, edited by ``edit(dict)``, with absolute published path."""
    return study_copy(tmp_path, "westwick2012", edit, name="study.yaml")


def test_study_config_loads_and_names_every_part():
    s = load_study("westwick2012")
    assert set(s.parts) == {"fig2", "fig3", "fig4", "fig5", "fig6", "fig6_torque_delay", "table1", "fig8"}
    assert all(c.part in s.parts for c in s.checks)
    assert {r.id for r in s.readings} >= {"R1", "R5", "R12"}


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["parts"]["fig4"].update(colour="red"), r"parts\.fig4: unknown key 'colour'; allowed: protocol"),
    (lambda d: d["parts"]["fig4"]["params"].update(N="many"), r"key 'N': expected a whole number"),
    (lambda d: d["parts"]["fig5"]["params"].update(fs="200 kg"), r"key 'fs': unit 'kg' is not a frequency unit"),
    (lambda d: d["parts"]["fig6"]["experiment"]["joint"].update(I=-0.1) if isinstance(
        d["parts"]["fig6"]["experiment"]["joint"], dict) else d["parts"]["fig6"]["experiment"].update(
        joint={"model": "second_order", "I": -0.1, "B": 1, "K": 50}), r"I.*> 0"),
    (lambda d: d["parts"]["fig6"].update(estimators={"no_such_method": {}}),
     r"unknown estimator 'no_such_method'; known: .*irf2_ls"),
    (lambda d: d["parts"]["fig6"].update(estimators={"ibk_spectral": {"fmaxx": 20}}), r"unknown key 'fmaxx'"),
    (lambda d: d["parts"]["fig6"].update(seeds=0), r"key 'seeds': need at least 1 seed"),
    (lambda d: d["parts"]["fig6"]["experiment"].update(joint="no_such_model"), r"no model file no_such_model.yaml"),
])
def test_bad_config_names_file_key_and_allowed(tmp_path, edit, message):
    p = write_study(tmp_path, edit)
    with pytest.raises(ConfigError, match=message) as exc:
        expand(load_study(p))
    assert str(p) in str(exc.value) or "no_such" in str(exc.value)


def test_unknown_part_and_protocol(tmp_path):
    with pytest.raises(ConfigError, match="unknown part 'fig99'"):
        expand(load_study("westwick2012"), ["fig99"])
    p = write_study(tmp_path, lambda d: d["parts"]["fig4"].update(protocol="nope"))
    with pytest.raises(ConfigError, match="unknown protocol 'nope'"):
        expand(load_study(p))


def test_failing_case_is_recorded_and_others_run(tmp_path):
    """A case that raises is returned as failed with its error; the rest of the study still runs."""
    def edit(d):
        d["parts"]["fig8"]["params"]["fall_db"] = 500     # never reached -> RuntimeError in the case
        d["parts"]["fig8"]["seeds"] = 1
        d["parts"]["fig8"]["experiment"]["duration"] = "6 s"
    run = run_study(write_study(tmp_path, edit), parts=["fig2", "fig8"], out_root=tmp_path / "out",
                    serial=True, progress=False)
    status = {r.case.part: r.status for r in run.results}
    assert status == {"fig2": "ok", "fig8": "failed"}
    failed = run.failed[0]
    assert "never falls 500" in failed.error and "Traceback" in failed.detail
    cases = pd.read_csv(run.folder / "cases.csv")
    assert (cases.loc[cases["part"] == "fig8", "status"] == "failed").all()
    comp = pd.read_csv(run.folder / "checks.csv")
    w6 = comp[comp["check"] == "W6-eq17"].iloc[0]
    assert w6["status"] == "miss" and "failed" in w6["note"]
    assert (run.folder / "failures.log").is_file()
    assert "## Failed cases" in (run.folder / "report.md").read_text()


def test_same_seed_same_numbers_serial_and_parallel(tmp_path):
    def edit(d):
        d["parts"]["fig6"]["seeds"] = 2
        d["parts"]["fig6"]["experiment"]["duration"] = "8 s"
    cases = expand(load_study(write_study(tmp_path, edit)), ["fig6"])
    off = Cache(tmp_path / "c", enabled=False)
    a = run_cases(cases, off, serial=True, progress=False)
    b = run_cases(cases, off, workers=2, progress=False)
    assert [r.rows for r in a] == [r.rows for r in b]
    assert a[0].rows != a[1].rows                       # different seeds differ


def test_cache_serves_finished_cases(tmp_path, monkeypatch):
    from jointbench.benchmarks.harness import fingerprint

    cases = expand(load_study("westwick2012"), ["fig4"])
    cache = Cache(tmp_path)
    first = run_cases(cases, cache, serial=True, progress=False)
    assert len(list(tmp_path.glob("??/*.json"))) == 1
    hit = cache.get(cases[0])
    assert hit is not None and hit.rows == first[0].rows and hit.cached
    monkeypatch.setattr(fingerprint, "code_hash", lambda: "other-code")
    monkeypatch.setattr(fingerprint, "case_code_hash", lambda entries=(): "other-code")
    assert Cache(tmp_path).get(cases[0]) is None                 # code change invalidates
    monkeypatch.undo()
    monkeypatch.setattr(fingerprint, "key_environment", lambda: {"python": "3.11.7", "numpy": "0.0"})
    assert Cache(tmp_path).get(cases[0]) is None                 # a library upgrade invalidates


def test_compare_aggregates_and_flags_misses():
    rows = pd.DataFrame({"part": "p", "status": "ok", "metric": "m", "fs_hz": [50, 50, 50, 100],
                         "value": [1.0, 2.0, 10.0, 7.0]})
    checks = (Check("c1", "p", "d", "s", 2, 1.5, 2.5, {"metric": "m", "fs_hz": 50}),
              Check("c2", "p", "d", "s", 5, 4, 6, {"metric": "m", "fs_hz": 100}, if_missed="why"),
              Check("c3", "p", "d", "s", 5, 0, 1, {"metric": "absent"}))
    out = judge(checks, rows, {"p"}).set_index("check")
    assert out.loc["c1", "reproduced"] == 2.0 and out.loc["c1", "status"] == "pass"   # median of 1, 2, 10
    assert out.loc["c2", "status"] == "miss" and out.loc["c2", "note"] == "why"
    assert out.loc["c3", "status"] == "miss" and np.isnan(out.loc["c3", "reproduced"])
    assert list(out.reset_index().columns[:7]) == ["check", "description", "published", "reproduced",
                                                     "low", "high", "status"]


def test_trend_and_difference_checks():
    # medians per f: posture 90, 85, 86 (a 1-point rise), movement 80, 70, 60
    rows = pd.DataFrame({"part": "p", "status": "ok", "metric": "m",
                         "cond": ["post"] * 6 + ["move"] * 6,
                         "f": [0.1, 0.1, 1.0, 1.0, 0.5, 0.5] * 2,
                         "value": [89, 91, 86, 86, 84, 86, 79, 81, 60, 60, 70, 70]})
    base = dict(part="p", description="d", source="s", published="falls", low=-np.inf, high=np.inf)
    checks = (
        Check("t1", select={"metric": "m", "cond": "post"}, kind="trend", over="f", slack=2.0, **base),
        Check("t2", select={"metric": "m", "cond": "post"}, kind="trend", over="f", slack=0.5, **base),
        Check("t3", select={"metric": "m", "cond": "move"}, kind="trend", over="f", direction="increasing",
              **base),
        Check("d1", **{**base, "high": 0}, select={"metric": "m", "cond": "move"}, kind="difference",
              versus={"metric": "m", "cond": "post"}, by="f"),
        Check("d2", **{**base, "low": -12}, select={"metric": "m", "cond": "move"}, kind="difference",
              versus={"metric": "m", "cond": "post"}, by="f"),
    )
    out = judge(checks, rows, {"p"}).set_index("check")
    # sorted by f: 0.1 -> 90, 0.5 -> 85, 1.0 -> 86: largest rise 1
    assert out.loc["t1", "reproduced"] == 1.0 and out.loc["t1", "status"] == "pass"
    assert out.loc["t2", "status"] == "miss"
    assert out.loc["t3", "reproduced"] == 10.0 and out.loc["t3", "status"] == "miss"   # falls by 10 twice
    # move - post: -10, -15, -26: all <= 0; the one closest to the bound 0 is -10
    assert out.loc["d1", "reproduced"] == -10.0 and out.loc["d1", "status"] == "pass"
    assert out.loc["d2", "reproduced"] == -26.0 and out.loc["d2", "status"] == "miss"
    assert "0.1: -10" in out.loc["d1", "spread"]


def test_one_claim_over_several_groups():
    """Issue 35 (one claim, one check): a list in ``select`` takes the rows of any of its values, and a trend
    ``by`` a column is judged per value of it (the largest move against the direction of any group)."""
    rows = pd.DataFrame({"part": "p", "status": "ok", "metric": ["a"] * 3 + ["b"] * 3 + ["c"] * 3,
                         "f": [0.1, 0.5, 1.0] * 3, "value": [90, 85, 80, 70, 72, 60, 1, 2, 3]})
    base = dict(part="p", description="d", source="s", published="falls", low=-np.inf, high=np.inf)
    checks = (
        Check("ab", select={"metric": ["a", "b"]}, kind="trend", over="f", by="metric", slack=1.0, **base),
        Check("a", select={"metric": ["a"]}, kind="trend", over="f", by="metric", slack=1.0, **base),
        Check("v", **{**base, "low": 0, "high": 100}, select={"metric": ["a", "c"]}, aggregate="max"),
    )
    out = judge(checks, rows, {"p"}).set_index("check")
    assert out.loc["ab", "reproduced"] == 2.0 and out.loc["ab", "status"] == "miss"    # b rises 70 -> 72
    assert "a: f -> " in out.loc["ab", "spread"] and "b: f -> " in out.loc["ab", "spread"]
    assert out.loc["a", "reproduced"] == -5.0 and out.loc["a", "status"] == "pass"
    assert out.loc["v", "reproduced"] == 90 and out.loc["v", "n"] == 6


@pytest.mark.parametrize("check, message", [
    ({"kind": "trend"}, "needs key 'over'"),
    ({"kind": "trend", "over": "f", "versus": {"metric": "m"}}, "'versus' does not apply to check kind 'trend'"),
    ({"kind": "difference", "versus": {"metric": "m"}, "over": "f"}, "'over' does not apply"),
    ({"kind": "ratio"}, "'kind': 'ratio' not allowed"),
    ({"kind": "value"}, "needs key 'high'"),
    ({"kind": "trend", "over": "f", "direction": "up"}, "'direction'"),
])
def test_bad_check_kinds(tmp_path, check, message):
    import yaml
    from jointbench.benchmarks.config import load_checks
    c = {"id": "x", "part": "p", "description": "d", "source": "s", "published": 1,
         "select": {"metric": "m"}, "evidence": "reproduction", "tolerance_reason": "why", **check}
    if check.get("kind") == "value":
        c["low"] = 0
    p = tmp_path / "pub.yaml"
    p.write_text(yaml.safe_dump({"study": "s", "source": "s", "checks": [c]}))
    with pytest.raises(ConfigError, match=message):
        load_checks(p, {"p": None})


def test_protocols_are_registered():
    assert {"westwick2012.differentiators", "westwick2012.sampling_rate", "westwick2012.input_bandlimit",
            "westwick2012.sampling_rate_experiment", "westwick2012.input_noise",
            "parametric_fit"} <= set(protocols.REGISTRY.names())


def test_partial_run_keeps_other_parts_from_cache(tmp_path):
    out = tmp_path / "out"
    run_study("westwick2012", parts=["fig2", "fig3"], out_root=out, serial=True, progress=False)
    run = run_study("westwick2012", parts=["fig2"], out_root=out, serial=True, progress=False)
    comp = pd.read_csv(run.folder / "checks.csv")
    assert {"fig2", "fig3"} == set(comp["part"])          # fig3 served from the cache
    text = (run.folder / "report.md").read_text()
    assert "come from the cache" in text and "Not included" in text
    fresh = run_study("westwick2012", parts=["fig2"], out_root=out, serial=True, progress=False,
                      use_cache=False)
    assert set(fresh.checks["part"]) == {"fig2"}


def test_run_options_as_one_object_or_as_keywords(tmp_path):
    """run_study takes its options as a RunOptions, as keywords (every caller before RunOptions), or both
    (the keywords replace the object's fields); an unknown option is refused before anything runs."""
    from jointbench.api import History
    from jointbench.benchmarks.study import RunOptions

    opts = RunOptions(parts=["fig2"], out_root=tmp_path / "out", serial=True, progress=False)
    first = run_study("westwick2012", opts)
    again = run_study("westwick2012", parts=["fig2"], out_root=tmp_path / "out", serial=True, progress=False)
    fresh = run_study("westwick2012", opts, use_cache=False)
    assert not any(r.cached for r in first.results) and all(r.cached for r in again.results)
    assert not any(r.cached for r in fresh.results) and opts.use_cache
    value = ["case_id", "metric", "value"]
    pd.testing.assert_frame_equal(first.rows[value], fresh.rows[value])
    with pytest.raises(TypeError, match="srial"):
        run_study("westwick2012", opts, srial=True)
    assert len(History(tmp_path / "out").runs()) == 3                   # the refused run is not recorded


def test_report_section_puts_a_part_under_interpretation():
    import dataclasses as dc
    from jointbench.benchmarks import report
    from jointbench.benchmarks.figures import PartReport
    s = load_study("westwick2012")
    parts = dict(s.parts)
    parts["fig2"] = dc.replace(parts["fig2"], report_section="interpretation")
    s = dc.replace(s, parts=parts)
    meta = {"commit": "x", "command": "c", "n_cases": 2, "n_cached": 0, "wall_s": 1.0, "workers": 1,
            "parts": list(s.parts), "from_cache": []}
    text = report.render(s, pd.DataFrame(), {"fig2": PartReport(text="CANDIDATE-XYZ"),
                                            "fig3": PartReport(text="RESULT-ABC")}, [], meta)
    interp = text.index("## Interpretation")
    assert text.index("CANDIDATE-XYZ") > interp > text.index("RESULT-ABC")
    assert "### fig2:" in text and "## fig3:" in text


def test_bad_report_section(tmp_path):
    p = write_study(tmp_path, lambda d: d["parts"]["fig4"].update(report_section="appendix"))
    with pytest.raises(ConfigError, match="'report_section': 'appendix' not allowed; allowed: results, interpretation"):
        load_study(p)


# ---------------------------------------------------------------- issue 11: one clear line, exit 2
def one_line_error(capsys, argv: list[str]) -> str:
    """Run the CLI in-process; it must exit 2 with exactly one line on stderr (no traceback)."""
    from jointbench.cli import main

    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:            # argparse errors
        code = exc.code
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_duplicate_yaml_key_names_file_key_and_line(tmp_path, capsys):
    from tests.harness_studies import tiny_study

    p = tiny_study(tmp_path)
    text = p.read_text().replace("  fit:\n    protocol: parametric_fit\n",
                                 "  fit:\n    protocol: parametric_fit\n    protocol: parametric_fit\n")
    p.write_text(text)
    line = text.splitlines().index("    protocol: parametric_fit") + 2
    err = one_line_error(capsys, ["run", p, "--out", tmp_path / "out"])
    assert f"{p}: line {line}: duplicate key 'protocol' (first given on line {line - 1})" in err


def test_duplicate_part_name_blames_the_study_file(tmp_path, capsys):
    from tests.harness_studies import tiny_study

    p = tiny_study(tmp_path)
    text = p.read_text()
    fit = text[text.index("  fit:\n"):]
    p.write_text(text + fit)                       # the part 'fit' twice
    err = one_line_error(capsys, ["run", p, "--out", tmp_path / "out"])
    assert err.startswith(f"jointbench: error: {p}: line ") and "duplicate key 'fit'" in err
    assert "published" not in err


def test_yaml_merge_keys_may_override(tmp_path):
    from jointbench.benchmarks.config import load_yaml

    p = tmp_path / "m.yaml"
    p.write_text("base: &b {x: 1, y: 2}\nderived:\n  <<: *b\n  x: 3\n")
    assert load_yaml(p)["derived"] == {"x": 3, "y": 2}


@pytest.mark.parametrize("seeds, message", [
    (1_000_000_000, "key 'seeds': 1000000000 seeds is more than the 100000 a part may run"),
    ("1e9", "key 'seeds': expected a count (e.g. 7) or a list of whole numbers, got '1e9'"),
    (1.0e9, "key 'seeds': expected a count"),
])
def test_absurd_seed_counts_are_one_line(tmp_path, capsys, seeds, message):
    from tests.harness_studies import tiny_study

    p = tiny_study(tmp_path)
    data = yaml.safe_load(p.read_text())
    data["parts"]["fit"]["seeds"] = seeds
    p.write_text(yaml.safe_dump(data))
    assert message in one_line_error(capsys, ["run", p, "--out", tmp_path / "out"])


@pytest.mark.parametrize("workers", ["-2", "0", "two"])
def test_bad_worker_count_is_one_line(capsys, workers):
    err = one_line_error(capsys, ["run", "westwick2012", "--workers", workers])
    assert "argument --workers: expected a whole number >= 1" in err


def test_estimator_that_cannot_run_on_the_perturbation_is_refused_at_expansion(tmp_path, capsys):
    """skirt needs a multisine: on a PRBS it is a config error before any case runs, not a dropped or
    failed estimator."""
    from tests.harness_studies import tiny_study

    p = tiny_study(tmp_path, perturbation={"kind": "prbs", "amplitude": 0.02, "clock": "0.01 s"},
                   estimators={"ibk_spectral": {}, "skirt": {}})
    err = one_line_error(capsys, ["run", p, "--out", tmp_path / "out"])
    assert (f"{p}: parts.fit: estimators.skirt: cannot run on this part's experiment: skirt needs a "
            "'multisine' perturbation, the experiment has 'prbs'") in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("study_id", ["../../x", "a/b", "..", ".hidden", "x y"])
def test_study_id_cannot_leave_the_results_folder(tmp_path, capsys, study_id):
    from tests.harness_studies import tiny_study

    p = tiny_study(tmp_path / "cfg")
    data = yaml.safe_load(p.read_text())
    data["study"] = study_id
    p.write_text(yaml.safe_dump(data))
    out = tmp_path / "deep" / "er" / "results"
    err = one_line_error(capsys, ["run", p, "--out", out])
    assert f"{p}: key 'study': {study_id!r} is not a plain name" in err
    assert not (tmp_path / "x").exists() and not (tmp_path / "deep").exists()
