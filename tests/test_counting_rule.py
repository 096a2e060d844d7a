"""Issue 35, one counting rule for every study (beside test_fidelity.py, issue 19): no published value in two
checks; values measured on real subjects (``evidence: recording``) never in the headline; the Table I gap checks
chosen from the paper alone; a note's figures from the rows, never typed; discrimination recorded for the checks of
compared methods."""
import ast
import re
from collections import defaultdict
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from jointbench.benchmarks.checks import (discriminating_counts, evidence_counts, headline, judge, render_note)
from jointbench.benchmarks.config import Check, load_study
from jointbench.benchmarks.status import overview

REPO = Path(__file__).resolve().parents[1]
STUDIES = sorted(p.parent for p in (REPO / "benchmarks" / "studies").glob("*/published.yaml"))
#: a figure in a note: a decimal number, or a whole number of percent
FIGURE = re.compile(r"(?<![\w.{])[-+]?\d+\.\d+|(?<![\w.{])\d+(?= ?%)")


def _published(study: Path) -> list[dict]:
    return yaml.safe_load((study / "published.yaml").read_text()).get("checks") or []


def _number(text) -> bool:
    try:
        float(text)
        return True
    except (TypeError, ValueError):
        return False


@pytest.mark.parametrize("study", STUDIES, ids=lambda p: p.name)
def test_no_published_value_in_two_checks(study):
    """Every published number or claim is one check: two counted checks (not sanity, not a method difference of
    cells checked already) quoting the same published text judge the same value twice (W5-overall repeated
    Table I's 500 Hz row; A3 one sentence at two segment lengths). A bare number may recur only as distinct
    cells of a table (different rows selected)."""
    seen = defaultdict(list)
    for c in _published(study):
        if c.get("count") == "method_difference" or c.get("evidence") == "sanity":
            continue
        seen[" ".join(str(c.get("published")).split()).lower()].append(c)
    twice = []
    for text, cs in seen.items():
        if len(cs) < 2:
            continue
        if _number(text) and len({repr(sorted(c.get("select", {}).items())) for c in cs}) == len(cs):
            continue
        twice.append((text, [c["id"] for c in cs]))
    assert not twice, f"published values judged by more than one check: {twice}"


@pytest.mark.parametrize("study", STUDIES, ids=lambda p: p.name)
def test_note_figures_are_the_papers_or_placeholders(study):
    """A figure in a note (``if_missed``, ``if_missed_below``/``_above``, ``cause``) is a placeholder filled from the
    rows, or one the paper gives (quoted in the study's config or a check's published value, band, description,
    source or reasons): a figure typed from one run goes stale ("about half the estimation variance" stayed
    after N_p changed)."""
    paper = set()

    def collect(x):
        if isinstance(x, dict):
            for v in x.values():
                collect(v)
        elif isinstance(x, list):
            for v in x:
                collect(v)
        elif x is not None:
            paper.update(m.group().lstrip("+") for m in FIGURE.finditer(str(x)))

    collect(yaml.safe_load((study / "study.yaml").read_text()))
    checks = _published(study)
    for c in checks:
        for key in ("published", "low", "high", "description", "source", "tolerance_reason", "domain_reason",
                    "select", "domain", "versus", "discrimination_reason"):
            collect(c.get(key))
    typed = []
    for c in checks:
        for field in ("if_missed", "if_missed_below", "if_missed_above", "cause"):
            text = re.sub(r"\{[^}]*\}", "", str(c.get(field) or ""))
            typed += [(c["id"], field, m.group()) for m in FIGURE.finditer(text) if m.group().lstrip("+") not in paper]
    assert not typed, f"figures typed in notes (use {{CHECK-ID}}, {{value}} or quote the paper): {typed}"


@pytest.mark.parametrize("study", STUDIES, ids=lambda p: p.name)
def test_committed_notes_are_the_rendered_templates(study):
    """The committed checks.csv holds each miss's note as rendered from its row: a note's number agrees with its
    row (a note edited in the YAML without a rerun, or a stale committed note, fails)."""
    path = REPO / "results" / study.name / "checks.csv"
    if not path.exists():
        pytest.skip("no committed results")
    comp = pd.read_csv(path, keep_default_na=False, na_values=[""])
    if "discriminating" not in comp:
        pytest.skip("results written before issue 35's columns: regenerate")
    s = load_study(study / "study.yaml")
    by_id = {c.id: c for c in s.checks}
    figures = {r.check: (float(r.reproduced), by_id[r.check].published) for r in comp.itertuples() if r.check in by_id}
    for r in comp.itertuples():
        c = by_id.get(r.check)
        if c is None or r.status == "pass" or not np.isfinite(float(r.reproduced)):
            continue
        rep = float(r.reproduced)
        side = c.if_missed_below if rep < float(r.low) else c.if_missed_above if rep > float(r.high) else ""
        want = render_note(side or c.if_missed, c, rep, figures)
        assert (r.note if isinstance(r.note, str) else "") == want, r.check


def test_gap_checks_are_chosen_from_the_paper_alone():
    """Which published KBR - skirt gaps of Table I are checked depends on the printed values and their precision,
    never on this implementation's results: the generator reads no results file and holds no measured spread."""
    src = (REPO / "benchmarks" / "studies" / "vanderuit2018_table1" / "generate_checks.py").read_text()
    tree = ast.parse(src)
    docs = {id(n.body[0].value) for n in ast.walk(tree)
            if isinstance(n, (ast.Module, ast.FunctionDef, ast.ClassDef)) and n.body
            and isinstance(n.body[0], ast.Expr) and isinstance(n.body[0].value, ast.Constant)}
    strings = [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)
               and id(n) not in docs]
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    assert not any(w in s for s in strings for w in ("cases.csv", "checks.csv", ".parquet", "--spreads", "results/")), \
        "the generator names a results file"
    assert "SPREAD" not in names and "read_csv" not in src, "the generator takes a spread measured on a run"


# ------------------------------------------------------------------------------ the counting rule itself
def _check(**kw):
    base = dict(id="C", part="p", description="d", source="s", published=1.0, low=0.5, high=1.5,
                select={"metric": "m"}, tolerance_reason="r")
    base.update(kw)
    return Check(**base)


def _rows(**cols):
    n = max(len(v) for v in cols.values() if isinstance(v, list))
    return pd.DataFrame({"part": ["p"] * n, "status": ["ok"] * n, **cols})


def test_a_recording_is_shown_never_counted():
    rows = _rows(metric=["m", "r"], value=[1.0, 9.0])
    comp = judge((_check(id="A"), _check(id="B", evidence="recording", select={"metric": "r"})), rows, {"p"})
    assert evidence_counts(comp)["reproduction"] == (1, 1) and evidence_counts(comp)["recording"] == (0, 1)
    assert headline(comp).startswith("reproduction 1 of 1 pass") and "recording 0 of 1" in headline(comp)
    row = overview({"s": comp}).iloc[0]
    assert row["reproduction (headline)"] == "1 of 1" and row["recordings (not counted)"] == "0 of 1"


def test_notes_take_their_figures_from_the_rows():
    rows = _rows(metric=["m", "o"], value=[3.0, 0.25])
    below = "{value:.2f} is below {published}; the other is {B:.3g} (published {B.published}); missing {Z}"
    a = _check(id="A", if_missed="either side", if_missed_below=below, if_missed_above="above")
    b = _check(id="B", select={"metric": "o"}, published=0.5, low=0.0, high=1.0)
    comp = judge((a, b), rows, {"p"}).set_index("check")
    assert comp.loc["A", "note"] == "above"
    rows = _rows(metric=["m", "o"], value=[0.125, 0.25])
    comp = judge((a, b), rows, {"p"}).set_index("check")
    assert comp.loc["A", "note"] == "0.12 is below 1.0; the other is 0.25 (published 0.5); missing n/a"


def test_a_note_naming_an_unknown_check_is_refused(tmp_path):
    from jointbench.benchmarks.config import load_checks
    from jointbench.core.errors import ConfigError

    entry = dict(id="A", part="p", description="d", source="s", published=1, low=0, high=2, evidence="reproduction",
                 tolerance_reason="r", select={"metric": "m"}, if_missed="see {NOPE}")
    path = tmp_path / "published.yaml"
    path.write_text(yaml.safe_dump({"study": "s", "source": "x", "checks": [entry]}))
    with pytest.raises(ConfigError, match=r"unknown placeholder \{NOPE\}"):
        load_checks(path, {"p": None})


def test_discrimination_of_the_compared_methods():
    """A check of one method passing with the other's reproduced values too, or whose band holds the other's
    published cell (unless argued), does not tell the methods apart; the headline says how many passes do."""
    from jointbench.benchmarks.config import MethodSwap

    swap = MethodSwap(part="p", estimators=("a", "b"))
    ca = _check(id="A-a", select={"metric": "m", "estimator": "a"}, published=1.0, low=0.9, high=1.1)
    cb = _check(id="A-b", select={"metric": "m", "estimator": "b"}, published=2.0, low=1.8, high=2.2)
    near = _check(id="N-a", select={"metric": "n", "estimator": "a"}, published=1.0, low=0.5, high=1.5)
    near_b = _check(id="N-b", select={"metric": "n", "estimator": "b"}, published=1.2, low=0.6, high=1.8)
    rows = _rows(metric=["m", "m", "n", "n"], estimator=["a", "b", "a", "b"], value=[1.0, 2.0, 1.0, 3.0])
    comp = judge((ca, cb, near, near_b), rows, {"p"}, swap=swap).set_index("check")
    assert comp.loc["A-a", "discriminating"] == "yes" and comp.loc["A-b", "discriminating"] == "yes"
    assert comp.loc["N-a", "discriminating"] == "no"
    assert "published 1.2 lies inside" in comp.loc["N-a", "discrimination"]
    argued = _check(id="N-a", select={"metric": "n", "estimator": "a"}, published=1.0, low=0.5, high=1.5,
                    discrimination_reason="printed to one digit")
    comp = judge((ca, cb, argued, near_b), rows, {"p"}, swap=swap).set_index("check")
    assert comp.loc["N-a", "discriminating"] == "yes"
    same = _rows(metric=["m", "m"], estimator=["a", "b"], value=[1.0, 1.05])
    comp = judge((ca, cb), same, {"p"}, swap=swap)
    assert comp.set_index("check").loc["A-a", "discriminating"] == "no"
    assert discriminating_counts(comp) == (0, 1)
