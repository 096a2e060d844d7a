"""``jointbench nightly`` / ``make nightly``: comparison with the previous nightly, the exit status, and
the static HTML report opened in headless Chromium."""
from __future__ import annotations

import os
import re
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from jointbench.benchmarks.locate import CONFIGS, study_ids
from jointbench.benchmarks.nightly import load_config
from jointbench.benchmarks.nightly import run_nightly
from jointbench.core.errors import ConfigError
from tests.harness_studies import REPO, tiny_study


def nightly_config(folder: Path, **edit) -> Path:
    """configs/nightly.yaml with the tiny study instead of the paper studies."""
    data = yaml.safe_load((CONFIGS / "nightly.yaml").read_text())
    data["studies"] = [str(tiny_study(folder / "configs", seeds=3))]
    data.update(edit)
    p = folder / "nightly.yaml"
    p.write_text(yaml.safe_dump(data, sort_keys=False))
    return p


def test_nightly_flags_exactly_the_perturbed_metrics_and_exits_nonzero(tmp_path, capsys):
    from jointbench.cli import main

    cfg, out = nightly_config(tmp_path), tmp_path / "results"
    args = ["nightly", "--config", str(cfg), "--out", str(out), "--serial", "--quiet"]
    assert main(args) == 0 and "nightly 1: baseline" in capsys.readouterr().out
    assert main(args) == 0 and "nightly 2: ok" in capsys.readouterr().out
    with sqlite3.connect(out / "history.sqlite") as db:
        run = db.execute("SELECT MAX(id) FROM runs").fetchone()[0]
        perturb = {"B": "value * (1 + 1e-3)",                  # beyond rel 1e-6 ('*')
                   "K_err_pct": "value + 0.5",                 # beyond abs 0.01 ('*_pct')
                   "K": "value * (1 + 1e-8)",                  # below rel 1e-6: not a drift
                   "vaf_torque": "value + 0.005"}              # below abs 0.01 ('vaf*'): not a drift
        for metric, expr in perturb.items():
            n = db.execute(f"UPDATE results SET value = {expr} WHERE run_id = ? AND metric = ?", (run, metric)).rowcount
            assert n == 3
    res = run_nightly(load_config(cfg), out, serial=True, progress=False)
    assert res.verdict == "regression"
    drift = res.outcomes[0].diff.drift
    assert sorted(drift["metric"]) == ["B", "K_err_pct"] and list(drift["n_drifted"]) == [3, 3]
    assert res.outcomes[0].diff.flipped.empty
    assert res.regressions == ["tiny: 2 metric(s) drifted beyond their threshold: fit/ibk_spectral:B, "
                               "fit/ibk_spectral:K_err_pct"]
    html = res.index.read_text()
    assert html.index("REGRESSION") < html.index("Metrics that drifted") < html.index("Checks against the published")
    # the study's section is its own report page (the same model as results/tiny/report.md and .html)
    run = res.outcomes[0].run
    assert run.report is not None and (run.folder / "report.html").is_file()
    assert 'href="../tiny/report.html"' in html
    for title in [s.title for s in run.report.body if hasattr(s, "title")]:
        assert f">{title}</h3>" in html, title
    summary = (out / "nightly" / "summary.md").read_text()
    assert "### Checks against the published values" in summary and "### Interpretation" in summary
    assert main(args) == 0            # the next night compares with nightly 3 (unperturbed): no regression
    assert "nightly 4: ok" in capsys.readouterr().out


def test_flipped_checks_show_their_evidence_grouped_and_every_kind_counts(tmp_path):
    """Checks of every kind of evidence that flip from pass to miss are regressions; the page groups
    the flipped checks by kind (reproduction, conditional, calibrated, sanity) and names the kind."""
    cfg = nightly_config(tmp_path)
    pub = tmp_path / "configs" / "tiny_published.yaml"
    data = yaml.safe_load(pub.read_text())
    impossible = {"part": "fit", "source": "-", "published": 1, "low": 0, "high": 1e-9,
                  "select": {"metric": "K", "estimator": "ibk_spectral"}, "tolerance_reason": "test band"}
    data["checks"] += [{**impossible, "id": "T-rep", "description": "never met", "evidence": "reproduction"},
                       {**impossible, "id": "T-cal", "description": "never met either", "evidence": "calibrated",
                        "free_parameter": "none"}]
    pub.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / "results"
    first = run_nightly(load_config(cfg), out, serial=True, progress=False)
    recorded = {}
    with sqlite3.connect(out / "history.sqlite") as db:       # the history records each check's evidence
        run = first.outcomes[0].run.run_id
        recorded = dict(db.execute("SELECT check_id, evidence FROM checks WHERE run_id = ?", (run,)).fetchall())
        db.execute("UPDATE checks SET status = 'pass' WHERE run_id = ? AND check_id IN ('T-rep', 'T-cal')", (run,))
        db.execute("UPDATE checks SET status = 'miss' WHERE run_id = ? AND check_id = 'T-K'", (run,))
    assert recorded == {"T-K": "sanity", "T-vaf": "sanity", "T-rep": "reproduction", "T-cal": "calibrated"}
    res = run_nightly(load_config(cfg), out, serial=True, progress=False)
    assert res.verdict == "regression"
    assert res.regressions == [
        "tiny: 2 check(s) flipped from pass to miss (reproduction 1: T-rep; calibrated 1: T-cal)"]
    flipped = res.outcomes[0].diff.flipped.set_index("check")
    assert dict(flipped["evidence"]) == {"T-rep": "reproduction", "T-cal": "calibrated", "T-K": "sanity"}
    assert dict(flipped["change"]) == {"T-rep": "regressed", "T-cal": "regressed", "T-K": "improved"}
    html = res.index.read_text()
    heads = ["Checks that flipped: reproduction (1 regressed)", "Checks that flipped: calibrated (1 regressed)",
             "Checks that flipped: sanity (1 improved)"]
    assert html.index(heads[0]) < html.index(heads[1]) < html.index(heads[2])
    table = html[html.index(heads[0]):html.index(heads[1])]
    assert "<th>evidence</th>" in table and "<td>reproduction</td>" in table and "T-rep" in table


@pytest.mark.parametrize("edit, message", [
    ({"colour": "red"}, "unknown key 'colour'"),
    ({"thresholds": [{"metric": "vaf*", "abs": 0.1}]}, "the last rule must be metric '*'"),
    ({"thresholds": [{"metric": "*", "abs": -1}]}, "thresholds[0]: key 'abs': must be >= 0"),
    ({"thresholds": [{"metric": "*"}]}, "give 'abs', 'rel' or both"),
    ({"timing": {"grow_factor": 0.5}}, "timing: key 'grow_factor': must be >= 1"),
    ({"use_cache": "maybe"}, "key 'use_cache': expected true or false"),
])
def test_nightly_config_is_strict(tmp_path, edit, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        load_config(nightly_config(tmp_path, **edit))


def test_shipped_nightly_config_runs_every_paper_study():
    cfg = load_config()
    shipped = set(study_ids())
    assert set(cfg.studies) == shipped - {"matrix"} and "matrix" in shipped   # the comparison grid is left out
    # every study `make reproduce` runs (the paper studies) is in the nightly
    makefile = (REPO / "Makefile").read_text()
    papers = set(re.search(r"^REPRODUCE_STUDIES\s*:=(.*)$", makefile, re.M)[1].split())   # study ids
    assert papers == {"westwick2012", "xu1998", "vanderuit2018_table1", "vanderuit2018_table2"}
    assert papers <= set(cfg.studies)
    assert cfg.rules.threshold("vaf_output").metric == "vaf*" and cfg.rules.threshold("K").metric == "*"


# ----------------------------------------------------------------------------- the page in a browser
@pytest.fixture(scope="session")
def chromium() -> str:
    """Headless Chromium, installed from Debian's packages by the project's set-up step (make chromium)."""
    if os.environ.get("JOINTBENCH_NO_BROWSER"):
        pytest.skip("JOINTBENCH_NO_BROWSER is set")
    if shutil.which("make") is None:
        pytest.skip("make not found: cannot run the set-up step `make chromium`")
    r = subprocess.run(["make", "-s", "chromium"], cwd=REPO, capture_output=True, text=True, timeout=1200)
    if r.returncode != 0:
        pytest.skip(f"headless Chromium could not be installed: {(r.stderr or r.stdout).strip()}")
    return r.stdout.strip().splitlines()[-1]


def _browser(chromium: str, profile: Path, *args: str) -> subprocess.CompletedProcess:
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             "--disable-extensions", f"--user-data-dir={profile}"]
    return subprocess.run([chromium, *flags, *args], capture_output=True, text=True, timeout=180)


def test_make_nightly_page_renders_tables_and_images_in_chromium(tmp_path, chromium):
    cfg, out = nightly_config(tmp_path), tmp_path / "results"
    nightly_args = f"--config {cfg} --out {out} --quiet"
    if Path(sys.prefix).resolve() == (REPO / ".venv").resolve() and shutil.which("make"):
        r = subprocess.run(["make", "-s", "nightly", f"NIGHTLY_ARGS={nightly_args}"], cwd=REPO,
                           capture_output=True, text=True, timeout=600)
    else:                             # a test run outside the project's venv: the same command directly
        r = subprocess.run([sys.executable, "-m", "jointbench", "nightly", *nightly_args.split()], cwd=REPO,
                           capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    index = out / "nightly" / "index.html"
    html = index.read_text()
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", html), "the page must not load anything"
    # The page as it is, after the browser has laid it out:
    dom = _browser(chromium, tmp_path / "profile1", "--dump-dom", index.as_uri())
    assert dom.returncode == 0, dom.stderr
    assert "JointBench nightly report" in dom.stdout and "Checks against the published values" in dom.stdout
    assert dom.stdout.count("<table") >= 2 and dom.stdout.count('src="data:image/png;base64,') >= 1
    # Did the images decode and the tables get rows? A copy of the page with a probe that writes the
    # answer into the title (the report itself has no script).
    probe = tmp_path / "probe.html"
    probe.write_text(html.replace("</body>", """<script>
      window.addEventListener('load', () => {
        const imgs = [...document.images];
        const ok = imgs.filter(i => i.complete && i.naturalWidth > 0).length;
        const rows = document.querySelectorAll('table tbody tr').length;
        document.title = `probe imgs ${ok}/${imgs.length} rows ${rows}`;
      });</script></body>"""))
    dom = _browser(chromium, tmp_path / "profile2", "--virtual-time-budget=10000", "--dump-dom", probe.as_uri())
    m = re.search(r"<title>probe imgs (\d+)/(\d+) rows (\d+)</title>", dom.stdout)
    assert m, dom.stdout[:500]
    n_ok, n_img, n_rows = map(int, m.groups())
    assert n_img >= 1 and n_ok == n_img and n_rows >= 3
    # And a screenshot: not blank, with the colours of the plots and the pass/miss cells in it.
    shot = tmp_path / "index.png"
    r = _browser(chromium, tmp_path / "profile3", "--window-size=1280,4000", f"--screenshot={shot}", index.as_uri())
    assert shot.is_file(), r.stderr
    import matplotlib.image as mpimg

    px = mpimg.imread(shot)[..., :3]
    colourful = (px.max(axis=2) - px.min(axis=2)) > 0.15
    assert px.std() > 0.05 and colourful.mean() > 0.001
    hist = out / "nightly" / "history.html"
    dom = _browser(chromium, tmp_path / "profile4", "--dump-dom", hist.as_uri())
    assert "JointBench nightly history" in dom.stdout and 'src="data:image/png;base64,' in dom.stdout
