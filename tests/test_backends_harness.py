"""The simulation backend in the harness: the part's ``backend`` key, ``--backend``, the output folders,
"Checks by backend" in the reports, every paper study on MuJoCo (smoke size) and the apparatus study."""
from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest

from jointbench import cli
from jointbench.benchmarks import backends
from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.harness.cache import case_key
from jointbench.benchmarks.runner import expand
from jointbench.benchmarks.study import run_study
from jointbench.core.errors import ConfigError
from tests.golden import check_golden
from tests.test_harness import write_study
from tests.harness_studies import study_copy

pytest.importorskip("mujoco")


# ------------------------------------------------------------------------------------- config and CLI
def test_part_backend_key_reaches_the_cases(tmp_path):
    p = write_study(tmp_path, lambda d: d["parts"]["fig6"].update(backend="mujoco", seeds=1))
    cases = expand(load_study(p), ["fig6", "table1"])
    assert {c.part: c.backend for c in cases} == {"fig6": "mujoco", "table1": "analytic"}
    assert {c.backend for c in expand(load_study(p), ["fig6", "table1"], backend="mujoco")} == {"mujoco"}
    assert case_key(cases[0]) != case_key(expand(load_study(p), ["fig6"], backend="analytic")[0])


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["parts"]["fig6"].update(backend="bullet"),
     r"parts\.fig6: key 'backend': unknown simulation backend 'bullet'; known: analytic, lti, ltv, mujoco, stepping$"),
    (lambda d: d["parts"]["fig6"]["experiment"].update(gravity={"mass": 1.5, "com_distance": 0.2}),
     r"parts\.fig6: experiment: backend 'analytic' cannot simulate this experiment: gravity .* use backend 'mujoco'$"),
    (lambda d: d["parts"]["fig6"].update(backend="mujoco") or d["parts"]["fig6"]["experiment"].update(
        apparatus={"kind": "position_servo", "stiffness": 1e9}),
     r"parts\.fig6: experiment: backend 'mujoco': the step 1/fs_sim = 0\.0002 s is unstable .* largest stable step"),
])
def test_bad_backend_or_model_is_one_line_naming_the_part(tmp_path, edit, message):
    p = write_study(tmp_path, edit)
    with pytest.raises(ConfigError, match=message) as exc:
        expand(load_study(p), ["fig6"])       # the part alone: a whole study's run names every bad part at once
    assert "\n" not in str(exc.value) and str(p) in str(exc.value)


def test_cli_rejects_an_unknown_backend(capsys):
    assert cli.main(["run", "westwick2012", "--backend", "bullet", "--parts", "fig2"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("jointbench: error: --backend: unknown simulation backend 'bullet'; known: "
                   "analytic, lti, ltv, mujoco, stepping")


def test_run_folders():
    base = Path("/r/xu1998")
    assert backends.run_folder(base, None) == base
    assert backends.run_folder(base, "mujoco") == base / "backend-mujoco"


# ------------------------------------------------------------- every paper study on MuJoCo, smoke size
def _westwick(d):
    for part in d["parts"].values():
        if "seeds" in part:
            part["seeds"] = 1
        if "experiment" in part:
            part["experiment"] = {**part["experiment"], "duration": "12 s"}


def _xu(d):
    for part in d["parts"].values():
        if "experiment" not in part:          # the arithmetic part (X9): nothing simulated
            continue
        part["seeds"] = 1
        part["experiment"] = {**part["experiment"], "duration": "14 s"}
    d["parts"]["fig2"]["sweep"] = {"condition": ["posture", "movement"], "f_v": [0.5]}
    d["parts"]["fig3"]["sweep"] = {"nsr": [0.2]}
    d["parts"]["fig3_angle_noise"]["sweep"] = {"nsr": [0.2]}
    d["parts"]["traces"]["sweep"] = {"shape": ["square"], "condition": ["posture"]}
    d["parts"]["readings"]["sweep"] = {"variant": ["chosen"], "condition": ["movement"], "f_v": [0.5]}


def _vdr(d):
    for part in ("table1", "table1_skirt_np7"):      # the second shares the first's simulated responses
        d["parts"][part]["seeds"] = 1
        d["parts"][part]["sweep"] = {"variation": ["square10"], "snr_db": [10, math.inf]}
    del d["parts"]["table1_snr_standard"], d["parts"]["table1_kbr_refined"]


@pytest.fixture(scope="module")
def mujoco_runs(tmp_path_factory):
    """Each paper study, reduced, run with --backend mujoco; westwick2012 also on its own backend. In this
    process (serial): what is checked is the backend in the studies and their reports; MuJoCo in the pool's
    worker processes is the apparatus smoke run's (test_apparatus_study_smoke), and a pool for these few cases
    cost 2 CPU-s more than it saved."""
    tmp = tmp_path_factory.mktemp("backends")
    out = tmp / "results"
    runs = {}
    for study, edit in (("westwick2012", _westwick), ("xu1998", _xu), ("vanderuit2018_table1", _vdr)):
        path = study_copy(tmp, study, edit)
        runs[study] = run_study(path, out_root=out, serial=True, progress=False, backend="mujoco")
    path = study_copy(tmp, "westwick2012", _westwick)
    runs["westwick2012/analytic"] = run_study(path, out_root=out, serial=True, progress=False)
    # again on MuJoCo, now that the study's own run exists (every case from the cache)
    runs["westwick2012/again"] = run_study(path, out_root=out, serial=True, progress=False, backend="mujoco")
    return runs


@pytest.mark.parametrize("study", ["westwick2012", "xu1998", "vanderuit2018_table1"])
def test_every_paper_study_runs_on_mujoco(mujoco_runs, study):
    run = mujoco_runs[study]
    assert not run.failed, [r.error for r in run.failed]
    assert run.folder.name == "backend-mujoco" and run.folder.parent.name == run.study.id
    for name in ("checks.csv", "cases.csv", "report.md"):
        assert (run.folder / name).is_file(), name
    rows = pd.read_csv(run.folder / "cases.csv")
    simulated = rows[rows["n_trials"] > 0]
    assert len(simulated) and set(simulated["backend"]) == {"mujoco"}
    assert (simulated["sim_time_s"] > 0).all()
    assert len(run.checks) and run.checks["reproduced"].notna().any()
    assert "## Simulation backends" in (run.folder / "report.md").read_text()


def test_the_study_report_shows_mujoco_beside_every_check(mujoco_runs):
    run = mujoco_runs["westwick2012/analytic"]
    text = (run.folder / "report.md").read_text()
    assert "### Checks by backend" in text
    section = text.split("### Checks by backend")[1].split("\n## ")[0]
    header = next(line for line in section.splitlines() if line.startswith("| check"))
    assert "| analytic (study) |" in header and "| mujoco |" in header and "| mujoco within |" in header
    mj = pd.read_csv(run.folder / "backend-mujoco" / "checks.csv")
    for check in run.checks["check"]:
        assert f"| {check} |" in section
    assert len(mj) == len(run.checks)
    # the simulation time per trial of each backend
    table = text.split("## Simulation backends")[1].split("###")[0]
    assert "`westwick2012/backend-mujoco`" in table and "this report" in table
    # and the MuJoCo report, rendered again after the study's own run, shows it beside its own
    again = mujoco_runs["westwick2012/again"]
    assert not again.failed and all(r.wall_time_s >= 0 for r in again.results)
    mtext = (again.folder / "report.md").read_text()
    assert "### Checks by backend" in mtext and "analytic (study)" in mtext


def test_cli_backend_option_writes_the_backend_folder(tmp_path, monkeypatch, capsys):
    import jointbench.benchmarks.study as study_mod

    seen = {}

    def fake_run_study(ref, **kw):
        seen.update(kw)
        raise ConfigError("stop here")

    monkeypatch.setattr(study_mod, "run_study", fake_run_study)
    assert cli.main(["run", "xu1998", "--backend", "mujoco", "--parts", "fig2"]) == 2
    assert seen["backend"] == "mujoco"


# ---------------------------------------------------------------------------------- apparatus study
def test_apparatus_study_smoke(tmp_path):
    def edit(d):
        d["parts"]["servo"]["seeds"] = 1
        d["parts"]["servo"]["sweep"] = {"servo_stiffness": [30000, 1000], "voluntary": ["present"]}
        d["parts"]["servo"]["experiment"]["duration"] = "12 s"
        d["parts"]["gravity"]["seeds"] = 1
        d["parts"]["gravity"]["sweep"] = {"posture_deg": [0, 180]}
        d["parts"]["gravity"]["experiment"]["duration"] = "14 s"
        d["parts"]["gravity"]["params"]["discard"] = "4.5 s"
    run = run_study(study_copy(tmp_path, "apparatus", edit), out_root=tmp_path / "out", workers=2, progress=False)
    assert not run.failed, [r.error for r in run.failed]
    for name in ("apparatus_servo.png", "apparatus_gravity.png", "report.md"):
        assert (run.folder / name).is_file(), name
    comp = run.checks.set_index("check")
    assert comp.loc["G1-offset", "status"] == "pass" and comp["reproduced"].notna().all()
    rows = run.rows
    off = rows[rows["metric"] == "gravity_offset"].set_index("posture_deg")["value"]
    assert off[0] > 2.5 and off[180] < -2.5      # m g l = 2.75 N·m/rad
    text = (run.folder / "report.md").read_text()
    assert "| this report | mujoco | gravity, servo |" in text
    check_golden("apparatus", run.checks)      # every check's status in this smoke run is pinned


def test_simulation_timing_counts_computed_responses_per_backend():
    """Trials served a shared response are counted as trials, not as computed responses (hand-checkable)."""
    from jointbench.benchmarks.backends import timing

    cases = pd.DataFrame({"case_id": ["a", "a", "b", "c", "d"],
                          "backend": ["analytic", "analytic", "analytic", "mujoco", "x"],
                          "part": ["p", "p", "q", "p", "p"], "sim_time_s": [0.3, 0.3, 0.1, 2.0, 0.0],
                          "n_trials": [4, 4, 2, 5, 0], "n_responses": [1, 1, 2, 4, 0], "git_commit": ["abc"] * 5})
    t = timing(cases)
    assert t["backends"] == {"analytic": ["p", "q"], "mujoco": ["p"]}          # "d" simulated nothing
    rows = {r["backend"]: r for r in t["rows"]}
    assert rows["analytic"]["trials"] == 6 and rows["analytic"]["responses"] == 3
    assert rows["analytic"]["per_response_s"] == pytest.approx(0.4 / 3)
    assert rows["mujoco"]["per_response_s"] == pytest.approx(0.5) and t["commit"] == "abc"
