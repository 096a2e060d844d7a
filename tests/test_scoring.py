"""Honest scoring (issue 8): kinds of evidence, tolerances with reasons, domains, the checks of the gaps
between two methods and their swap test, the README status block, dirty-tree stamps, and the wiring of
settings and metric definitions (each test here would catch one plausible one-line bug)."""
from __future__ import annotations

import dataclasses
import importlib.util
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from jointbench import estimators
from jointbench.benchmarks import report, status
from jointbench.benchmarks.config import EVIDENCE, Check, load_checks, load_study
from jointbench.benchmarks import locate
from jointbench.benchmarks.protocols import Context
from jointbench.benchmarks.tables import DIRTY_BANNER, stamp
from jointbench.benchmarks.checks import (evidence_counts, headline, judge, method_specific, swap_estimators,
                                          swap_survival)
from jointbench.core.errors import ConfigError
from jointbench.core.signal import decimate_fft
from jointbench.core.types import Trial
from tests.harness_studies import REPO

STUDIES = ("westwick2012", "xu1998", "vanderuit2018_table1")


def _load_generator():
    path = locate.STUDIES / "vanderuit2018_table1" / "generate_checks.py"
    spec = importlib.util.spec_from_file_location("vdr_generate", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


# ------------------------------------------------------------------------------------ parsing checks
def _write(tmp_path, checks, name="pub.yaml") -> Path:
    p = tmp_path / name
    p.write_text(yaml.safe_dump({"study": "s", "source": "s", "checks": checks}))
    return p


def _check(**over) -> dict:
    return {"id": "x", "part": "p", "description": "d", "source": "s", "published": 1, "low": 0, "high": 2,
            "select": {"metric": "m"}, "evidence": "reproduction", "tolerance_reason": "why", **over}


@pytest.mark.parametrize("over, message", [
    ({"evidence": None}, "missing required key 'evidence'"),
    ({"evidence": "anecdote"},
     "'evidence': 'anecdote' not allowed; allowed: reproduction, recording, conditional, calibrated, sanity"),
    ({"evidence": "conditional"}, "evidence 'conditional' needs key 'reading'"),
    ({"evidence": "conditional", "reading": "the first one"}, "needs key 'reading'"),
    ({"reading": "R1"}, "'reading' applies to evidence 'conditional' only"),
    ({"evidence": "calibrated"}, "evidence 'calibrated' needs key 'free_parameter'"),
    ({"free_parameter": "r"}, "'free_parameter' applies to evidence 'calibrated' only"),
    ({"tolerance_reason": None}, "missing required key 'tolerance_reason'"),
    ({"tolerance_reason": "  "}, "state why the band is what it is"),
    ({"domain": {"f": {"lt": 1}}}, "'domain' and 'domain_reason' go together"),
    ({"domain": {"f": {"below": 1}}, "domain_reason": "r"},
     r"domain\.f': unknown key 'below'; allowed: lt, le, gt, ge"),
    ({"domain": {"f": {}}, "domain_reason": "r"}, r"a range takes lt, le, gt, ge, got nothing"),
    ({"domain": {"metric": {"lt": 1}}, "domain_reason": "r"}, "column 'metric' is also in 'select'"),
    ({"select": {"metric": "m", "f": {"lt": "one"}}}, "expected a number"),
    ({"aggregate": "mode"}, "'aggregate': 'mode' not allowed"),
])
def test_checks_parse_strictly(tmp_path, over, message):
    c = {k: v for k, v in _check(**over).items() if v is not None}
    with pytest.raises(ConfigError, match=message) as exc:
        load_checks(_write(tmp_path, [c]), {"p": None})
    assert "pub.yaml" in str(exc.value) and "check x" in str(exc.value)


def test_conditional_reading_must_exist_in_the_study(tmp_path):
    data = yaml.safe_load((locate.STUDIES / "westwick2012" / "study.yaml").read_text())
    pub = yaml.safe_load((locate.STUDIES / "westwick2012" / "published.yaml").read_text())
    pub["checks"][0] = {**pub["checks"][0], "evidence": "conditional", "reading": "R1, R99"}
    (tmp_path / "pub.yaml").write_text(yaml.safe_dump(pub))
    data["published"] = str(tmp_path / "pub.yaml")
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match="R99 is not a reading of study.yaml"):
        load_study(tmp_path / "study.yaml")


def test_default_aggregate_through_the_parser_is_the_median(tmp_path):
    """A check without 'aggregate' combines seeds by their median, not their mean."""
    (c,) = load_checks(_write(tmp_path, [_check(low=1.5, high=2.5)]), {"p": None})
    assert c.aggregate == "median"
    rows = pd.DataFrame({"part": "p", "status": "ok", "metric": "m", "value": [1.0, 2.0, 30.0]})
    out = judge((c,), rows, {"p"}).iloc[0]
    assert out["reproduced"] == 2.0 and out["status"] == "pass"     # the mean, 11, would miss


def test_every_study_states_evidence_reasons_and_what_is_not_reproduced():
    for sid in STUDIES:
        s = load_study(sid)
        assert s.not_reproduced and all(n.item and n.reason for n in s.not_reproduced), sid
        for c in s.checks:
            assert c.evidence in EVIDENCE and c.tolerance_reason, (sid, c.id)
            if c.evidence == "conditional":
                assert c.readings and all(r in {x.id for x in s.readings} for r in c.readings)
        assert any(c.evidence == "reproduction" for c in s.checks), sid


def test_no_hand_typed_claim_about_the_standard_snr_table():
    """The false R1 claim ('keeps all 32 VAF_optim/RMSE_k cells in tolerance') is gone: such counts are
    derived in the report, not typed into configs."""
    for path in (locate.STUDIES / "vanderuit2018_table1" / "study.yaml",
                 locate.STUDIES / "vanderuit2018_table1" / "published.yaml"):
        text = path.read_text()
        for claim in ("32 of 32", "0 of 32", "29 of 32", "every VAF_optim and RMSE_k cell inside its band"):
            assert claim not in text, (path.name, claim)


# ------------------------------------------------------------------------------------ compare
def _rows(**cols) -> pd.DataFrame:
    return pd.DataFrame({"part": "p", "status": "ok", **cols})


def test_compare_records_evidence_reading_reason_and_commit():
    c = Check("c", "p", "d", "s", 1, 0, 2, {"metric": "m"}, evidence="conditional", reading="R2",
              tolerance_reason="because")
    out = judge((c,), _rows(metric="m", value=[1.0]), {"p"}, commit="abc1234").iloc[0]
    assert (out["evidence"], out["reading"], out["tolerance_reason"], out["commit"]) == \
        ("conditional", "R2", "because", "abc1234")
    dirty = judge((c,), _rows(metric="m", value=[1.0]), {"p"}, commit="abc1234-dirty").iloc[0]
    assert DIRTY_BANNER in dirty["commit"] and stamp("abc") == "abc"


def test_domain_scores_inside_and_shows_outside():
    rows = _rows(metric="v", f_v=[0.5, 0.5, 1.0, 2.0], value=[99.0, 98.0, 80.0, 85.0])
    c = Check("x3", "p", "d", "s", "close to 100", 95, 100, {"metric": "v"}, aggregate="min",
              domain={"f_v": {"lt": 1.0}}, domain_reason="tasks below 1 Hz")
    out = judge((c,), rows, {"p"}).iloc[0]
    assert out["reproduced"] == 98.0 and out["status"] == "pass" and out["n"] == 2
    assert out["out_of_domain"] == "f_v -> 1.0: 80, 2.0: 85" and out["domain_reason"] == "tasks below 1 Hz"
    # difference checks: groups outside the domain are shown, not scored
    rows = _rows(metric=["a", "b"] * 3, f=[0.1, 0.1, 0.5, 0.5, 1.0, 1.0], value=[1.0, 0.0, -1.0, 0.0, -2.0, 0.0])
    d = Check("x4", "p", "d", "s", "negative", -math.inf, 0, {"metric": "a"}, kind="difference",
              versus={"metric": "b"}, by="f", domain={"f": {"ge": 0.2}}, domain_reason="resolution")
    out = judge((d,), rows, {"p"}).iloc[0]
    assert out["status"] == "pass" and out["reproduced"] == -1.0 and out["out_of_domain"] == "f -> 0.1: +1"


def test_std_aggregate_and_range_select():
    rows = _rows(metric="m", fs_hz=[50, 50, 50, 100, 250, 500], value=[1.0, 2.0, 3.0, 7.0, 9.0, 11.0])
    sd = Check("sd", "p", "d", "s", 1, 0.5, 1.5, {"metric": "m", "fs_hz": 50}, aggregate="std")
    mx = Check("mx", "p", "d", "s", 1, 0, 10, {"metric": "m", "fs_hz": {"ge": 100, "lt": 500}}, aggregate="max")
    out = judge((sd, mx), rows, {"p"}).set_index("check")
    assert out.loc["sd", "reproduced"] == pytest.approx(1.0)        # sample SD (ddof 1) of 1, 2, 3
    assert out.loc["mx", "reproduced"] == 9.0 and out.loc["mx", "n"] == 2


def test_headline_counts_reproduction_only():
    comp = pd.DataFrame({"check": list("abcdefg"), "status": ["pass", "miss", "pass", "pass", "pass", "miss", "pass"],
                         "evidence": ["reproduction", "reproduction", "calibrated", "calibrated", "sanity",
                                      "conditional", "conditional"]})
    assert evidence_counts(comp) == {"reproduction": (1, 2), "conditional": (1, 2), "calibrated": (2, 2),
                                     "sanity": (1, 1)}
    assert headline(comp) == ("reproduction 1 of 2 pass; beside them: conditional 1 of 2, calibrated 2 of 2 "
                              "(not counted), sanity 1 of 1")
    old = comp.drop(columns="evidence")          # a comparison written before the evidence column
    assert evidence_counts(old) == {"unrecorded": (5, 7)}


# ------------------------------------------------------------------------------------ the report
def _meta(commit="abc1234", **kw):
    return {"commit": commit, "command": "jointbench run x", "n_cases": 1, "n_cached": 0, "wall_s": 1.0,
            "workers": 1, "parts": None, "from_cache": [], **kw}


def test_report_groups_checks_by_evidence_with_reasons_and_not_reproduced():
    s = load_study("xu1998")
    comp = judge(s.checks, pd.DataFrame(columns=["part", "status", "metric", "value"]), set(s.parts), "abc1234")
    text = report.render(s, comp, {}, [], _meta(parts=list(s.parts)))
    head = text.index("**Reproduction:")
    assert head < text.index("### Reproduction checks") < text.index("### Conditional checks") < \
        text.index("### Sanity checks") < text.index("## Not reproduced") < text.index("## Interpretation")
    n_rep = sum(c.evidence == "reproduction" for c in s.checks)
    assert f"**Reproduction: 0 of {n_rep} checks pass.**" in text
    assert "Why the bands are what they are:" in text and s.checks[0].tolerance_reason in text
    for n in s.not_reproduced:
        assert f"- **{n.item}**: {n.reason}" in text
    assert "WARNING" not in text and "-dirty" not in text


def test_report_from_a_dirty_tree_says_so_loudly():
    s = load_study("westwick2012")
    text = report.render(s, pd.DataFrame(), {}, [], _meta(commit="abc1234-dirty", parts=list(s.parts)))
    assert text.splitlines()[2].startswith(f"> **WARNING: {DIRTY_BANNER}.**")


def test_cli_summary_line_is_the_headline(tmp_path, capsys, monkeypatch):
    from jointbench import cli
    import jointbench.benchmarks.study as study_mod

    orig = study_mod.run_study
    monkeypatch.setattr(study_mod, "run_study",
                        lambda *a, **k: orig(*a, **{**k, "out_root": tmp_path / "out", "serial": True}))
    assert cli.main(["run", "westwick2012", "--parts", "fig2", "fig4", "--quiet"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == ("westwick2012: 2 cases (0 from cache, 2 computed), 0 failed, 0 refused; reproduction 3 of 3 "
                      "pass; beside them: sanity 4 of 4")                # W1-h1-idft is sanity (issue 19)
    assert out[1].split()[:3] == ["pass", "sanity", "W1-h1-idft"]


# ------------------------------------------------------------------------------------ van de Ruit gaps
def _table1_rows(values: dict) -> pd.DataFrame:
    """One row per Table I cell: (metric, estimator, variation, snr_db) -> value."""
    recs = [{"part": "table1", "status": "ok", "metric": m, "estimator": e, "variation": v, "snr_db": snr,
             "value": x} for (m, e, v, snr), x in values.items()]
    return pd.DataFrame(recs)


def _published_cells(checks) -> dict:
    out = {}
    for c in checks:
        if c.id.startswith("T1-"):
            sel = c.select
            out[(sel["metric"], sel["estimator"], sel["variation"], float(sel["snr_db"]))] = float(c.published)
    return out


def test_table1_gap_checks_cover_every_resolvable_cell():
    """A sign check of KBR - skirt for every cell whose printed gap is larger than the printed rounding of its
    two cells, and a size check (a factor 2 on the gap after that rounding) unless its band would be a near-copy
    of the sign (inner edge below SIZE_INNER_MIN of the gap); the size band always excludes zero (so it implies
    the sign). All count as method differences (issue 35: the set follows from the printed table alone)."""
    gen = _load_generator()
    s = load_study("vanderuit2018_table1")
    ids = {c.id: c for c in s.checks}
    expected = [(v, snr, col) for v in gen.VARIATIONS for snr in gen.SNRS for col in gen.COLUMNS
                if gen.resolvable(v, snr, col) is not None]
    assert len(expected) == 36            # 40 printed gaps; 0.0 (twice), 0.01 and 0.1 are within the rounding
    n_size = 0
    for v, snr, col in expected:
        sign, size = ids[f"D-{v}-{snr}-{col}-sign"], ids.get(f"D-{v}-{snr}-{col}-size")
        gap = gen.resolvable(v, snr, col)
        assert sign.kind == "difference" and sign.count == "method_difference"
        assert sign.evidence == "conditional" and sign.readings == ("R12",)       # the skirt's basis (issue 19)
        assert (sign.low, sign.high) == ((0.0, math.inf) if gap > 0 else (-math.inf, 0.0))
        if size is None:
            continue
        n_size += 1
        u = 2 * gen.ROUND[col]
        assert sorted(map(abs, (size.low, size.high))) == pytest.approx([(abs(gap) - u) / 2, 2 * (abs(gap) + u)])
        assert size.kind == "difference" and size.count == "method_difference"
        assert size.low <= gap <= size.high and (size.low > 0 or size.high < 0)
        assert min(abs(size.low), abs(size.high)) >= gen.SIZE_INNER_MIN * abs(gap) - 1e-9
    assert n_size == len(expected)            # with the printed rounding as the only widening, none is a near-copy
    assert len([c for c in s.checks if c.id.startswith("D-")]) == len(expected) + n_size


def test_generated_block_of_the_table1_yaml_is_the_generators_output():
    gen = _load_generator()
    text = gen.YAML.read_text()
    assert text.count(gen.BEGIN) == 1 and gen.block() in text


def test_swapping_the_methods_fails_every_gap_check_with_published_values():
    """A property of the check set: with the published values every gap check passes, with the two
    methods' values swapped every one fails."""
    s = load_study("vanderuit2018_table1")
    rows = _table1_rows(_published_cells(s.checks))
    gaps = [c for c in s.checks if c.id.startswith("D-")]
    before = judge(tuple(gaps), rows, {"table1"})
    after = judge(tuple(gaps), swap_estimators(rows, "table1", ("kbr", "skirt")), {"table1"})
    assert (before["status"] == "pass").all(), list(before.loc[before["status"] != "pass", "check"])
    assert (after["status"] == "miss").all(), list(after.loc[after["status"] != "miss", "check"])


def test_swapping_the_reproduced_values_fails_every_passing_gap_check():
    """With the reproduced medians of the committed comparison (a synthetic rows frame built from it), no
    check of a KBR - skirt gap passes both as reproduced and with the methods swapped."""
    s = load_study("vanderuit2018_table1")
    committed = pd.read_csv(REPO / "results" / "vanderuit2018_table1" / "checks.csv").set_index("check")
    cells = {}
    for c in s.checks:
        if c.id.startswith("T1-") and c.id in committed.index:
            sel = c.select
            cells[(sel["metric"], sel["estimator"], sel["variation"], float(sel["snr_db"]))] = \
                float(committed.loc[c.id, "reproduced"])
    assert len(cells) == 80
    rows = _table1_rows(cells)
    out = swap_survival(tuple(c for c in s.checks if c.id.startswith(("T1-", "D-"))), rows, "table1",
                        ("kbr", "skirt"))
    assert out["difference_survivors"] == [] and out["differences"] > 0
    assert out["n"] == 80 + out["differences"]
    # the per-cell bands alone do not tell the methods apart: many of them survive the swap
    assert out["pass_swapped"] > 0 and len(out["survivors"]) > 0


def test_method_specific_checks():
    s = load_study("vanderuit2018_table1")
    spec = method_specific(s.checks, ("kbr", "skirt"))
    assert len(spec) == len(s.checks)          # every check of this study names a method
    assert not method_specific(load_study("westwick2012").checks, ("kbr", "skirt"))


# ------------------------------------------------------------------------------------ README status
def test_readme_status_block_is_generated_from_the_committed_checks():
    assert status.readme_block() == status.block(), (
        "README.md's status block is not what `jointbench status --write-readme` gives from the committed "
        "results/*/checks.csv: run it (make reproduce does)")


def test_status_writes_between_markers(tmp_path):
    res = tmp_path / "results" / "s1"
    res.mkdir(parents=True)
    pd.DataFrame({"check": ["A1-x", "A1-y", "B2-z"], "status": ["pass", "miss", "pass"],
                  "evidence": ["reproduction", "reproduction", "sanity"],
                  "commit": ["abc1234"] * 3}).to_csv(res / "checks.csv", index=False)
    grid = tmp_path / "results" / "grid1"                    # a comparison study: no published value
    grid.mkdir()
    pd.DataFrame(columns=["check", "status", "evidence", "commit"]).to_csv(grid / "checks.csv", index=False)
    readme = tmp_path / "README.md"
    readme.write_text(f"intro\n{status.BEGIN}\nold text\n{status.END}\noutro\n")
    path, changed = status.write_readme(tmp_path / "results", readme)
    text = readme.read_text()
    assert changed and text.startswith("intro\n") and text.endswith("outro\n") and "old text" not in text
    assert "#### `s1`: reproduction 1 of 2 pass; beside them: sanity 1 of 1" in text
    assert "| A1 | reproduction | 1 of 2 | A1-y |" in text and "| abc1234 |" in text
    assert "`grid1`" not in text.split("Studies with no published value")[0]
    assert "(comparison studies; their reports hold the results): [`grid1`](results/grid1/report.md)." in text
    assert status.write_readme(tmp_path / "results", readme) == (path, False)     # idempotent
    readme.write_text("no markers\n")
    with pytest.raises(ConfigError, match="status:begin"):
        status.write_readme(tmp_path / "results", readme)


def test_committed_results_are_not_from_a_dirty_tree():
    """No committed report or comparison was generated from an uncommitted tree."""
    folders = sorted(p for p in (REPO / "results").glob("*/") if (p / "report.md").is_file())
    comps = [pd.read_csv(p / "checks.csv") for p in folders]
    if not all("commit" in c.columns for c in comps):
        pytest.skip("the committed results predate the stamped format (no 'commit' column): they are "
                    "regenerated at a clean commit with `make reproduce` after the last merge")
    for folder, comp in zip(folders, comps):
        assert "-dirty" not in (folder / "report.md").read_text(), folder.name
        assert not comp["commit"].astype(str).str.contains("dirty").any(), folder.name


# ------------------------------------------------------------------------------------ wiring
def test_context_rng_is_one_generator_per_case():
    ctx = Context(part="p", seed=3, params=None, experiment=None, estimators={})
    a, b = ctx.rng.normal(size=4), ctx.rng.normal(size=4)
    assert not np.array_equal(a, b)                                 # two draws in one case differ
    again = Context(part="p", seed=3, params=None, experiment=None, estimators={})
    assert np.array_equal(np.concatenate([a, b]), again.rng.normal(size=8))   # same seed, same stream
    other = Context(part="p", seed=4, params=None, experiment=None, estimators={})
    assert not np.array_equal(a, other.rng.normal(size=4))


@pytest.mark.parametrize("m", [100, 101])
def test_decimate_fft_keeps_every_bin_below_the_new_nyquist(m):
    n = 1000
    k = (m - 1) // 2                                                # the highest bin below the new Nyquist
    t_in, t = np.arange(n) / n, np.arange(m) / m
    x = np.cos(2 * np.pi * k * t_in) + 0.5 * np.sin(2 * np.pi * 3 * t_in)
    assert np.allclose(decimate_fft(x, m), np.cos(2 * np.pi * k * t) + 0.5 * np.sin(2 * np.pi * 3 * t), atol=1e-12)
    above = np.cos(2 * np.pi * (m // 2 + 1) * t_in)                # above the new Nyquist: removed
    assert np.allclose(decimate_fft(above, m), 0, atol=1e-12)
    if m % 2 == 0:   # the new Nyquist bin itself is kept, real part only: one of the pair k = +-m/2, i.e. half
        nyq = np.cos(2 * np.pi * (m // 2) * t_in)
        assert np.allclose(decimate_fft(nyq, m), 0.5 * np.cos(np.pi * np.arange(m)), atol=1e-12)


def test_ibk_spectral_weights_the_fit_by_coherence_squared():
    """The I, B, K of ibk_spectral are the least-squares fit to its own FRF estimate weighted by gamma^2."""
    rng = np.random.default_rng(5)
    fs, n = 200.0, 200 * 60
    from scipy import signal as sps
    u = sps.lfilter(*sps.butter(2, 15, fs=fs), rng.standard_normal(n))
    w = 2 * np.pi * np.fft.rfftfreq(n, 1 / fs)
    H = 50 + 1j * w * 1.5 - 0.15 * w ** 2 + 3.0 * (1j * w) ** 3 / (1j * w + 60) ** 2   # not second order
    y = np.fft.irfft(np.fft.rfft(u) * H, n)
    y = y + sps.lfilter(*sps.butter(1, 3, fs=fs), rng.standard_normal(n)) * 4 * np.std(y)  # coloured noise
    # the paper's fixed 0-20 Hz band (input_band: false): the weighting is the point here, not the band
    est = estimators.make("ibk_spectral", {"fmax": "20 Hz", "input_band": False}).fit(Trial.from_arrays(u, y, fs,
                                                                                                      name="t"))
    f, Hh, coh = est.basis.freq, est.basis.H, est.basis.coherence
    sel = (f <= 20) & (coh > 0)
    assert coh[sel].min() < 0.5 * coh[sel].max()                    # the weights really differ
    ws = 2 * np.pi * f[sel]
    A = np.concatenate([np.column_stack([-ws ** 2, 0 * ws, np.ones_like(ws)]), np.column_stack([0 * ws, ws, 0 * ws])])
    b = np.concatenate([Hh.real[sel], Hh.imag[sel]])
    g2 = np.concatenate([coh[sel], coh[sel]])
    def wls(weight):            # minimise sum weight |row residual|^2
        r = np.sqrt(weight)
        return np.linalg.lstsq(A * r[:, None], b * r, rcond=None)[0]

    ref = wls(g2)
    assert (est.I, est.B, est.K) == pytest.approx(tuple(ref), rel=1e-7)
    assert not np.allclose(wls(np.sqrt(g2)), ref, rtol=1e-4)        # weighting by gamma would differ


def test_fsewls_settings_reach_the_ewls_and_its_start():
    """FSEWLS's output equals eq. 6 integrated independently (plain RK4 in P, Theta) from P(0) = the inverse
    of sum(Phi Phi^T) dt over init_window and Theta(0) the least-squares fit there, with lambda as set."""
    from jointbench.estimators._fsewls_kernels import ewls_riccati_rk4, svf, svf_pole

    fs, n = 1000.0, 4000
    rng = np.random.default_rng(2)
    from scipy import signal as sps
    theta = sps.lfilter(*sps.butter(2, 10, fs=fs), rng.standard_normal(n))
    k = 40 + 15 * (np.arange(n) > n // 2)
    tau = 0.06 * np.gradient(np.gradient(theta)) * fs ** 2 + 0.3 * np.gradient(theta) * fs + k * theta
    tau = tau + 0.05 * rng.standard_normal(n)
    trial = Trial.from_arrays(theta, tau, fs, imposed="torque", name="t")
    for lam, init in ((20.0, 0.5), (7.0, 0.25)):
        est = estimators.make("fsewls", {"highpass_cutoff": None, "forgetting": f"{lam} 1/s",
                                         "init_window": f"{init} s", "svf_cutoff": "3 Hz"})
        fit = est.fit(trial)
        s = est.settings
        x = np.stack([theta - theta.mean(), tau - tau.mean()])
        Phi, y = svf(x[0], x[1], fs, svf_pole(s.svf_cutoff, s.svf_order, s.svf_cutoff_means), s.svf_order,
                     s.svf_causal, s.svf_form)
        m = int(round(init * fs))
        R0 = Phi[:m].T @ Phi[:m] / fs                                # information in the window, dt = 1/fs
        th0 = np.linalg.lstsq(Phi[:m], y[:m], rcond=None)[0]
        ref = ewls_riccati_rk4(Phi, y, 1 / fs, lam, np.linalg.inv(R0), th0)
        got = np.column_stack([fit.I, fit.B, fit.K])
        scale = np.abs(ref).max(axis=0)
        assert np.abs(got - ref).max(axis=0) / scale == pytest.approx(np.zeros(3), abs=1e-4), (lam, init)


def test_vaf_optim_is_against_the_noise_free_torque():
    """In the van de Ruit protocol, VAF_optim compares the prediction with the noise-free output, VAF_self
    with the noisy one: a model predicting the noise-free torque exactly has VAF_optim 100 %."""
    from jointbench.benchmarks.studies.vanderuit2018_table1.protocol import Table1Params, table1
    from jointbench.core.estimate import Estimate
    from jointbench.core.schema import parse
    from jointbench import sims

    s = load_study("vanderuit2018_table1")
    part = s.parts["table1"]
    exp = sims.Experiment.from_mapping({**part.experiment, "duration": "22 s"}, "test")

    @dataclasses.dataclass(eq=False)
    class Perfect(Estimate):         # a real Estimate: the protocol's fit passes the output gate
        truth: object
        time: np.ndarray
        fs: float
        estimator: str = "oracle"

        def predict(self, u):
            return np.asarray(self.truth.signals["torque"], float)

        def stiffness(self, t):
            return np.full(len(t), 5.0)

    class Oracle:
        name = "oracle"

        def fit(self, trial):
            return Perfect(trial.truth, trial.time, trial.fs)

    params = parse(Table1Params, {**part.params, "variation": "sine20", "snr_db": 5.0, "score": ["2 s", "10 s"],
                                  "curve_seeds": [], "image_variations": [], "band_step": "0 s"}, "test")
    ctx = Context(part="table1", seed=0, params=params, experiment=exp, estimators={"oracle": Oracle()})
    table1(ctx)
    got = {r["metric"]: r["value"] for r in ctx.rows if r["estimator"] == "oracle"}
    assert got["vaf_optim"] == pytest.approx(100.0) and got["vaf_optim_window"] == pytest.approx(100.0)
    assert got["vaf_self"] < 95 and got["vaf_val"] < 95          # the noise (r = 0.11) is in both


def test_golden_pin_fails_on_a_flip_and_updates_only_with_a_reason(tmp_path, monkeypatch):
    from tests import golden

    monkeypatch.setattr(golden, "GOLDEN", tmp_path)
    comp = pd.DataFrame({"check": ["a", "b"], "evidence": ["reproduction", "sanity"], "status": ["pass", "miss"]})
    monkeypatch.delenv("JOINTBENCH_GOLDEN_REASON", raising=False)
    with pytest.raises(AssertionError, match="no pinned outcome"):
        golden.check_golden("s", comp)
    monkeypatch.setenv("JOINTBENCH_GOLDEN_REASON", "first")
    golden.check_golden("s", comp)
    monkeypatch.delenv("JOINTBENCH_GOLDEN_REASON")
    golden.check_golden("s", comp)                                   # unchanged: passes
    flipped = comp.assign(status=["miss", "miss"])
    with pytest.raises(AssertionError, match="a: status pass -> miss"):
        golden.check_golden("s", flipped)
    monkeypatch.setenv("JOINTBENCH_GOLDEN_REASON", "the band of a was tightened")
    golden.check_golden("s", flipped)
    assert "the band of a was tightened" in (tmp_path / "CHANGES.md").read_text()
    assert "- a: status pass -> miss" in (tmp_path / "CHANGES.md").read_text()


# ------------------------------------------------------------------------------------ new metrics
def test_rule_of_thumb_is_one_decade_with_the_pass_band_snr():
    from jointbench.benchmarks.studies.westwick2012.protocol import rule_of_thumb_decades

    assert rule_of_thumb_decades(5.0, 2, 40.0) == pytest.approx(np.log10((1e4 - 1) ** 0.25), rel=1e-12)
    assert rule_of_thumb_decades(5.0, 1, 40.0) == pytest.approx(2.0, abs=1e-4)      # -20 dB/decade: 2 decades
    # referred to the variance over 0 ... fs/2 (Fig. 5's R4) the noise density is lower: the crossing moves up
    assert rule_of_thumb_decades(5.0, 2, 40.0, fs=200.0) > 1.2


def test_shape_difference_is_scale_free_and_sees_shape():
    from jointbench.benchmarks.studies.westwick2012.protocol import shape_difference

    lags = np.arange(-50, 51)
    h = np.exp(-(lags / 10.0) ** 2) * np.cos(lags / 4.0)
    sub = lags[::5] // 5                                            # the same curve at a fifth of the rate
    assert shape_difference((lags, h, 500.0), (sub, 7.0 * h[::5], 100.0)) == pytest.approx(0, abs=1e-12)
    other = np.exp(-(lags / 10.0) ** 2)
    assert shape_difference((lags, h, 500.0), (sub, other[::5], 100.0)) > 5
    with pytest.raises(ValueError, match="whole multiple"):
        shape_difference((lags, h, 500.0), (sub, h[::5], 300.0))


def test_coherence_band_is_the_contiguous_band_around_the_maximum():
    from jointbench.benchmarks.protocols.generic import coherence_band

    f = np.arange(10.0)
    c = np.array([0.2, 0.95, 0.5, 0.92, 0.99, 0.95, 0.91, 0.3, 0.97, 0.1])
    assert coherence_band(f, c, 0.9) == (3.0, 6.0)
    assert all(np.isnan(coherence_band(f, c, 0.999)))


def test_exact_derivative_control_leaves_only_the_ewls():
    """Fed the exact perturbed response, the EWLS's regression is exact and slow variations are tracked."""
    from jointbench import sims
    from jointbench.benchmarks.studies.xu1998 import protocol as X
    from jointbench.core.schema import parse

    part = load_study("xu1998").parts["fig2"]
    exp0 = sims.Experiment.from_mapping({**part.experiment, "duration": "14 s"}, "test")
    est0 = estimators.make("fsewls", part.estimators["fsewls"], "test")
    scores = {}
    for f in (0.25, 1.5):
        p = parse(X.TrackParams, {"condition": "posture", "f_v": f, "regressors": "exact"}, "test")
        trial = sims.simulate(X.case_experiment(exp0, p), 0)
        fit = X.exact_fit(X.case_estimator(est0, p), trial)
        keep = X.scored_window(trial.n, trial.fs, 4.0)
        assert X.vaf(fit.y[keep], fit.yhat[keep]) > 99             # exact regressors: only the lag is left
        scores[f] = X._scores(fit, trial.truth, keep, 1 / trial.fs)["vafv_K"]
    assert scores[0.25] > 95 and scores[1.5] < scores[0.25]          # what is left: the forgetting lag
    with pytest.raises(ConfigError, match="'exact' is a noise-free control"):
        parse(X.TrackParams, {"regressors": "exact", "nsr": 0.1}, "test")


def test_dirty_means_a_change_that_can_move_a_result(tmp_path):
    """Regenerated results or the README's status block do not make a tree dirty (make reproduce writes them
    between studies); a change to code or configs does."""
    import subprocess

    from jointbench.benchmarks.harness.fingerprint import git_commit

    def git(*args):
        subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=tmp_path, check=True,
                       capture_output=True)

    for rel in ("benchmarks/a.py", "configs/b.yaml", "results/s/report.md", "README.md"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("x\n")
    git("init", "-q")
    git("add", "-A")
    git("commit", "-qm", "c")
    clean = git_commit(tmp_path)
    assert clean and not clean.endswith("-dirty") and clean != "unknown"
    (tmp_path / "results/s/report.md").write_text("new\n")
    (tmp_path / "README.md").write_text("new\n")
    assert git_commit(tmp_path) == clean
    (tmp_path / "configs/b.yaml").write_text("y\n")
    assert git_commit(tmp_path) == clean + "-dirty"
