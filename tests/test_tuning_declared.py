"""Fair to every method (issue 36): an estimator declares its smoothing setting and default candidates in its
own settings (``param(..., tune=Tune())``), so a plugin is tuned like a built-in with no study edit, and a
study's ``tuning`` still overrides; a choice on the edge of the candidates is flagged in the rows and the
report; a plugin's distribution, version and source hash are in every row, the report, the history and
``jointbench diff``; a comment edit of a plugin recomputes nothing (its key is the hash of its parsed code).
"""
from __future__ import annotations

import json
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml

from jointbench.benchmarks.compare.protocol import INSIDE, edge_of
from jointbench.benchmarks.compare.tuning import declared_search, edge_sentence
from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.runner import expand_study
from jointbench.core.schema import Tune, param
from tests.harness_studies import cli_env, cli_here, tiny_grid_part, tiny_study

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "plugin_estimator"


# ------------------------------------------------------------------------------ the declared candidates
def test_the_declared_candidates_are_the_configured_value_half_and_twice_it():
    # a rate in 1/s: half and twice the configured 2 1/s (the paper value itself is the paper candidate)
    assert declared_search("fsewls", {"forgetting": "2 1/s"}) == {"forgetting": ("1 1/s", "4 1/s")}
    # an integer: 7 x 0.5 = 3.5 rounds half up to 4; 1 x 0.5 rounds to 1, the configured value: left out
    assert declared_search("skirt", {"n_p": 7}) == {"n_p": (4, 14)}
    assert declared_search("skirt", {"n_p": 1}) == {"n_p": (2,)}
    # a configured 'auto' is the paper candidate; the field's default (20 s), half and twice it follow
    assert declared_search("kbr", {"sigma": "auto"}) == {"sigma": ("20 s", "10 s", "40 s")}
    # the time-invariant fits and the published ensemble IRF declare none
    assert declared_search("irf2_ls", {}) == {} and declared_search("ensemble_irf", {}) == {}


def test_a_declaration_is_checked():
    with pytest.raises(ValueError, match="factors must be finite numbers > 0"):
        Tune(factors=(0.5, -2))
    with pytest.raises(ValueError, match="at least one"):
        Tune(factors=())
    with pytest.raises(TypeError, match="expected a jointbench.core.schema.Tune"):
        param(1.0, tune=(0.5, 2))


def _doc_tuning_block() -> dict:
    """The YAML block of docs/comparison_rows.md's tuning policy (the one the text says the tests parse)."""
    text = (REPO / "docs" / "comparison_rows.md").read_text()
    after = text.split("This block is parsed by the tests", 1)[1]
    return yaml.safe_load(re.search(r"```yaml\n(.*?)```", after, re.S).group(1))


def test_the_docs_tuning_example_gives_the_searches_it_says(tmp_path):
    """docs/comparison_rows.md's example, as the keys of a grid part: fsewls (not named) gets its declared
    search, sds the study's (the scenario's over the part's), guarin (an empty mapping) nothing."""
    block = _doc_tuning_block()
    part = tiny_grid_part(block["grid"]["estimator"], noise=[0.05], tuning=block["grid"]["tuning"])
    part["tuning"] = block["tuning"]
    part["scenarios"]["elbow"]["tuning"] = block["scenarios"]["elbow"]["tuning"]
    cases, skipped = expand_study(load_study(tiny_study(tmp_path, extra_parts={"grid": part})), ["grid"])
    search = {c.sweep["estimator"]: c.params["search"] for c in cases if c.sweep.get("tuning") == "tuned"}
    assert search["fsewls"] == [{}, {"forgetting": "10 1/s"}, {"forgetting": "40 1/s"}]   # default 20 1/s
    sds = part["estimators"]["sds"]                                                         # window 0.5 s
    assert search["sds"] == [sds, {**sds, "window": "4 s"}]          # the scenario's 0.5 s is the paper's
    assert "guarin" not in search
    why = {s["estimator"]: s["reason"] for s in skipped if s.get("tuning") == "tuned"}
    assert why["guarin"].startswith("nothing to tune: the study's tuning gives guarin no values to try")


# ------------------------------------------------------------------------------------- edge choices
def test_an_edge_choice_is_named_by_setting_and_side():
    cands = [{"window": "1 s"}, {"window": "0.5 s"}, {"window": "2 s"}]
    assert edge_of("sds", cands, 2, [1.0, 2.0, 3.0]) == "window=highest"
    assert edge_of("sds", cands, 1, [1.0, 2.0, 0.5]) == "window=lowest"
    assert edge_of("sds", cands, 0, [3.0, 2.0, 1.0]) == INSIDE
    # a candidate that could not be fitted (NaN) is not tried: 1 s is then the highest of those scored
    assert edge_of("sds", cands, 0, [3.0, 2.0, math.nan]) == "window=highest"
    two = [{"window": "1 s", "lag_after": "20 ms"}, {"window": "2 s", "lag_after": "10 ms"},
           {"window": "1.5 s", "lag_after": "40 ms"}]
    assert edge_of("sds", two, 1, [0.0, 1.0, 0.5]) == "lag_after=lowest; window=highest"


def test_the_report_sentence_counts_the_edge_choices_of_the_rows():
    rows = pd.DataFrame({"case_id": ["a", "a", "b", "c", "d"], "method": ["m1", "m1", "m1", "m2", "m2"],
                         "tuning": ["tuned", "tuned", "tuned", "tuned", "paper"],
                         "tuning_edge": ["window=lowest", "window=lowest", INSIDE, "sigma=highest", None]})
    text = edge_sentence(rows)
    assert "in 2 of the 3 tuned cases" in text
    assert "m1 1 of 2 (window=lowest in 1)" in text and "m2 1 of 1 (sigma=highest in 1)" in text
    assert "every one of the 1 tuned cases" in edge_sentence(rows[rows["case_id"] == "b"])
    assert edge_sentence(rows.drop(columns="tuning_edge")) == ""


# ----------------------------------------------------------- the plugin example, end to end (CLI runs)
def _run(study: Path, out: Path, cwd: Path) -> str:
    r = subprocess.run([sys.executable, "-m", "jointbench", "run", str(study), "--out", str(out), "--workers", "1",
                        "--quiet"], cwd=cwd, env=cli_env(), capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    """The plugin example copied (not installed: its study's ``plugins:`` finds the folder beside it) and run
    once: (source copy, results folder, rows, report text, stdout)."""
    root = tmp_path_factory.mktemp("example")
    src = root / "src"
    shutil.copytree(EXAMPLE, src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    out = root / "results"
    stdout = _run(src / "comparison.yaml", out, root)
    folder = out / "plugin_comparison"
    return src, out, pd.read_csv(folder / "cases.csv"), (folder / "report.md").read_text(), stdout


def test_the_plugin_example_gets_a_tuned_column_without_a_tuning_entry(example):
    src, _, rows, _, stdout = example
    study = yaml.safe_load((src / "comparison.yaml").read_text())
    assert "tuning" not in study["parts"]["grid"] and "tuned" in study["parts"]["grid"]["grid"]["tuning"]
    assert "6 cases (0 from cache, 6 computed)" in stdout
    scored = rows[rows["metric"] == "total_error"]
    assert set(zip(scored["estimator"], scored["tuning"])) == {
        ("sliding_ibk", "paper"), ("sliding_ibk", "tuned"), ("fsewls", "paper"), ("fsewls", "tuned"),
        ("irf2_ls", "paper")}
    search = rows[(rows["metric"] == "tuning_vaf_output") & (rows["estimator"] == "sliding_ibk")]
    windows = [json.loads(c)["window"] for c in search["candidate"]]
    assert windows == ["0.4 s", "0.2 s", "0.8 s"]          # the configured window, half and twice it
    skipped = rows[rows["metric"] == "skipped"]
    assert list(skipped["estimator"]) == ["irf2_ls"] and skipped["reason"].str.startswith(
        "nothing to tune: irf2_ls declares no smoothing setting").all()


def _expected_edge(group: pd.DataFrame) -> str:
    """The edge of a one-setting search from its candidate rows alone (not edge_of): the chosen value against
    the lowest and highest of those with a finite score."""
    (key,) = {k for c in group["candidate"] for k, v in json.loads(c).items()
              if len({json.loads(d)[k] for d in group["candidate"]}) > 1}
    value = {c: float(str(json.loads(c)[key]).split()[0]) for c in group["candidate"]}
    tried = [value[c] for c, s in zip(group["candidate"], group["value"]) if math.isfinite(s)]
    chosen = value[group.loc[group["chosen"].astype(str) == "True", "candidate"].iloc[0]]
    return f"{key}=lowest" if chosen == min(tried) else f"{key}=highest" if chosen == max(tried) else INSIDE


def test_edge_choices_are_flagged_in_the_rows_and_the_report(example):
    _, _, rows, report, _ = example
    tuned = rows[rows["tuning"] == "tuned"]
    flags = {}
    for est, g in tuned[tuned["metric"] != "skipped"].groupby("estimator"):
        assert g["tuning_edge"].nunique() == 1 and g["tuning_edge"].notna().all()     # on every row of the case
        flags[est] = g["tuning_edge"].iloc[0]
        assert flags[est] == _expected_edge(g[g["metric"] == "tuning_vaf_output"])
    assert rows.loc[rows["tuning"] == "paper", "tuning_edge"].isna().all()
    # this run (seeded) chose on an edge: the report says so, with the counts of the rows
    at_edge = {e: f for e, f in flags.items() if f != INSIDE}
    assert at_edge, f"no edge choice in this run ({flags}): the flag is not exercised"
    assert f"in {len(at_edge)} of the {len(flags)} tuned cases the chosen candidate is the lowest or highest" in report
    for est, flag in at_edge.items():
        assert f"{est} 1 of 1 ({flag} in 1)" in report
    assert "| edge |" in report                                   # the tuning table's column


def test_the_plugin_version_is_in_every_row_and_the_report(example):
    src, _, rows, report, _ = example
    version = re.search(r'__version__ = "(.+)"', (src / "sliding_ibk" / "__init__.py").read_text()).group(1)
    mine = rows[rows["estimator"] == "sliding_ibk"]
    (text,) = set(mine["plugin"])
    assert re.fullmatch(rf"sliding_ibk=={re.escape(version)} [0-9a-f]{{20}}", text)
    assert rows.loc[rows["estimator"] != "sliding_ibk", "plugin"].isna().all()      # built-ins: the commit
    assert f"`sliding_ibk` from `{text}`" in report


def test_a_comment_edit_recomputes_nothing_and_a_code_edit_is_named_by_diff(example):
    """docs/harness.md: editing a comment or a docstring recomputes nothing, for a plugin too (its key is the
    hash of its parsed code); a code edit with a new version recomputes its cases, only they, and
    ``jointbench diff`` names the plugin's version and hash before and after (it said 'code: (none) changed')."""
    src, out, rows, _, _ = example
    init = src / "sliding_ibk" / "__init__.py"
    code = init.read_text()
    init.write_text(code.replace('"""A JointBench plugin:', '"""A JointBench plugin (docstring edited):', 1)
                    + "\n# a comment added: nothing to recompute\n")
    assert "6 cases (6 from cache, 0 computed)" in _run(src / "comparison.yaml", out, src.parent)
    init.write_text(code.replace('__version__ = "0.1.0"', '__version__ = "0.1.1"\n_EDITED = True'))
    assert "6 cases (4 from cache, 2 computed)" in _run(src / "comparison.yaml", out, src.parent)
    after = pd.read_csv(out / "plugin_comparison" / "cases.csv")
    (old,) = set(rows.loc[rows["estimator"] == "sliding_ibk", "plugin"])
    (new,) = set(after.loc[after["estimator"] == "sliding_ibk", "plugin"])
    assert new.startswith("sliding_ibk==0.1.1 ") and new.split()[1] != old.split()[1]
    same = cli_here("diff", 1, 2, "--out", out)
    assert same.returncode == 0 and "plugin sliding_ibk" not in same.stdout
    diff = cli_here("diff", 1, 3, "--out", out)
    assert diff.returncode == 0
    line = next(line for line in diff.stdout.splitlines() if "plugin sliding_ibk" in line)
    assert old in line and new in line
    shown = cli_here("history", 3, "--out", out).stdout
    assert f"sliding_ibk: {new}" in shown
