"""What a study author meets (issue 36): a run with --set and no --out writes where the docs say, a study file's
errors come all at once, an unranked scenario says why, and the light install (no MuJoCo extra) runs the analytic
rows of every shipped study and says which rows need the extra."""
from __future__ import annotations

import sys

import pytest

from tests.harness_studies import cli_here, tiny_study


# ------------------------------------------------------------------------------------ --set without --out
def test_jointbench_run_with_set_and_no_out_writes_set_runs_not_the_study_folder(tmp_path, monkeypatch):
    """docs/harness.md and docs/comparison_rows.md: a run with --set and no --out writes
    results/set-runs/<study>-set-<hash8>/ and says so on stderr; the study's own results stay as they were (the
    command line passed its default results folder as if --out had been given, and wrote over them)."""
    path = tiny_study(tmp_path / "c", seeds=1)
    monkeypatch.chdir(tmp_path)
    own = tmp_path / "results" / "tiny"
    own.mkdir(parents=True)
    (own / "checks.csv").write_text("committed\n")
    got = cli_here("run", path, "--serial", "--quiet", "--set", "fit.seeds=2")
    assert got.returncode == 0, got.stderr
    assert sorted(p.name for p in own.iterdir()) == ["checks.csv"] and (own / "checks.csv").read_text() == "committed\n"
    written = list((tmp_path / "results" / "set-runs").glob("tiny-set-*/report.md"))
    assert len(written) == 1, got.stdout
    assert f"outputs in {written[0].parent}" in got.stderr and str(written[0].parent) in got.stdout
    # --out names the folder: the study's own folder when asked for
    again = cli_here("run", path, "--serial", "--quiet", "--set", "fit.seeds=2", "--out", tmp_path / "results")
    assert again.returncode == 0, again.stderr
    assert (own / "report.md").is_file() and (own / "checks.csv").read_text() != "committed\n"
    assert "set-runs" not in again.stderr



# ---------------------------------------------------------------------------------- every error at once
def test_a_study_files_errors_come_all_at_once(tmp_path):
    """A study with a misspelt key in one part and two variations missing profile keys: one run names them all
    (the variations' keys came one combination, so one run, at a time: ramp 'duration', then smooth_random's)."""
    from tests.harness_studies import tiny_grid_part

    part = tiny_grid_part(["sds"], realizations=2, noise=[0.05], variation=["ramp", "random"])
    part["variations"] = {"ramp": {"shape": "ramp"}, "random": {"shape": "smooth_random"}}
    path = tiny_study(tmp_path / "c", extra_parts={"grid": part})
    text = path.read_text().replace("protocol: parametric_fit", "protocol: parametric_fit\n    sedes: 2", 1)
    path.write_text(text)
    got = cli_here("run", path, "--out", tmp_path / "out")
    assert got.returncode == 2
    lines = got.stderr.removeprefix("jointbench: error: ").strip().splitlines()
    assert lines == [f"{path}: parts.fit: unknown key 'sedes'; allowed: " + lines[0].split("allowed: ")[1],
                     f"{path}: parts.grid: variations.ramp (ramp): missing required key 'duration'",
                     f"{path}: parts.grid: variations.random (smooth_random): missing required key 'bandwidth'",
                     f"{path}: parts.grid: variations.random (smooth_random): missing required key 'seed'"], lines


@pytest.mark.parametrize("joint, errors", [
    ({"model": "time_varying"}, ["missing required key 'I'", "missing required key 'K'"]),
    ({"model": "time_varying", "I": 0.1, "K": {"shape": "ramp", "initial": 40, "final": 60}},
     ["key 'K' (ramp): missing required key 'duration'", "give exactly one of 'B' (number or profile) and "
                                                         "'damping_ratio'"]),
    ({"model": "wrist_contact", "I": 0.003, "b": 0.035, "k": {"shape": "smooth_random", "mean": 5, "amplitude": 1}},
     ["key 'k' (smooth_random): missing required key 'bandwidth'", "key 'k' (smooth_random): missing required "
                                                                    "key 'seed'"]),
])
def test_a_joint_models_errors_come_at_once(joint, errors):
    """A joint model's missing keys and its profiles' come together (K was checked after the other keys, and a
    profile's keys after the damping)."""
    from jointbench import sims
    from jointbench.core.errors import ConfigError

    exp = {"joint": joint, "perturbation": {"kind": "filtered_noise", "cutoff": "20 Hz"}, "fs_sim": "1 kHz",
           "duration": "2 s"}
    with pytest.raises(ConfigError) as exc:
        sims.Experiment.from_mapping(exp, "experiment")
    lines = str(exc.value).splitlines()
    assert len(lines) == len(errors) and all(e in line for e, line in zip(errors, lines)), lines


def test_errors_found_when_the_cases_are_made_come_all_at_once(tmp_path):
    """Errors that show only once the cases are made (a part's experiment, a grid's combinations): every part's
    and every combination's in one run, each distinct error once, naming a combination that has it."""
    from tests.harness_studies import tiny_grid_part

    part = tiny_grid_part(["sds"], realizations=2, noise=[0, 0.05], perturbation=["slow", "flat"])
    part["perturbations"] = {"slow": {"kind": "filtered_noise", "cutoff": "-2 Hz"},
                             "flat": {"kind": "prbs", "amplitude": 0}}
    path = tiny_study(tmp_path / "c", extra_parts={"grid": part})
    path.write_text(path.read_text().replace("fs_sim: 2 kHz", "fs_sim: -2 kHz", 1))      # the part 'fit'
    got = cli_here("run", path, "--out", tmp_path / "out")
    assert got.returncode == 2
    lines = got.stderr.removeprefix("jointbench: error: ").strip().splitlines()
    assert lines == [
        f"{path}: parts.fit: experiment: key 'fs_sim': must be > 0 Hz, got -2000.0 Hz",
        f"{path}: parts.grid: the combination scenario=elbow, variation=square, perturbation=slow, noise=0, "
        f"backend=analytic (and 1 more with this error): perturbation: key 'cutoff': must be > 0 Hz, got -2.0 Hz",
        f"{path}: parts.grid: the combination scenario=elbow, variation=square, perturbation=flat, noise=0, "
        f"backend=analytic (and 1 more with this error): perturbation: key 'amplitude': must be > 0, got 0.0"], lines


# ------------------------------------------------------------------------------- the light install (no MuJoCo)
def _without_mujoco(monkeypatch):
    """This process as the light install: ``import mujoco`` / ``dm_control`` fail and ``find_spec`` finds
    neither (a None entry in sys.modules is how Python marks a module that cannot be imported)."""
    for name in ("mujoco", "dm_control"):
        monkeypatch.setitem(sys.modules, name, None)
    from jointbench import sims

    assert sims.BACKENDS.get("mujoco").unavailable()          # the simulation of the missing extra holds


@pytest.fixture
def without_mujoco(monkeypatch):
    _without_mujoco(monkeypatch)


def _expanded(study_id: str):
    from jointbench.benchmarks.config import load_study
    from jointbench.benchmarks.runner import expand_study

    return expand_study(load_study(study_id))


def _labels(case_or_skip) -> tuple:
    d = case_or_skip.sweep if hasattr(case_or_skip, "sweep") else case_or_skip
    return tuple(sorted((k, str(v)) for k, v in d.items() if k not in ("reason", "part")))


def test_every_shipped_study_runs_its_analytic_rows_without_the_mujoco_extra(monkeypatch):
    """Without the extra every shipped study expands to the analytic cases it has with the extra, and the matrix
    skips exactly the MuJoCo combinations that would run with it, each with the reason naming the extra; a
    study with no analytic row (apparatus) is one line naming the extra."""
    from jointbench.benchmarks.locate import study_ids
    from jointbench.core.errors import ConfigError

    with_extra = {sid: _expanded(sid) for sid in study_ids() if sid != "apparatus"}
    mujoco_cases = {_labels(c) for c in with_extra["matrix"][0] if c.backend == "mujoco" and c.protocol == "compare"}
    assert mujoco_cases                       # the grid has MuJoCo rows when the extra is installed
    _without_mujoco(monkeypatch)
    for sid in study_ids():
        if sid == "apparatus":
            with pytest.raises(ConfigError, match=r"backend 'mujoco' needs .*pip install 'jointbench\[mujoco\]'"):
                _expanded(sid)
            continue
        cases, skipped = _expanded(sid)
        before = with_extra[sid][0]
        assert [c.case_id for c in cases] == [c.case_id for c in before if c.backend != "mujoco"], sid
        extra = {_labels(s) for s in skipped if "pip install 'jointbench[mujoco]'" in s["reason"]}
        assert extra == (mujoco_cases if sid == "matrix" else set()), sid


def test_a_grid_with_mujoco_rows_runs_the_analytic_ones_and_says_which_need_the_extra(tmp_path, without_mujoco):
    from tests.harness_studies import tiny_grid_part

    part = tiny_grid_part(["sds"], realizations=2, noise=[0.05], backend=["analytic", "mujoco"])
    path = tiny_study(tmp_path / "c", extra_parts={"grid": part})
    got = cli_here("run", path, "--parts", "grid", "--serial", "--quiet", "--out", tmp_path / "out")
    assert got.returncode == 0, got.stderr
    line = [x for x in got.stderr.splitlines() if "on backend mujoco left out" in x]
    assert line == [f"jointbench: {path}: parts.grid: 1 combination on backend mujoco left out (the others run): "
                    f"simulation backend 'mujoco' needs mujoco and dm_control, not installed: pip install "
                    f"'jointbench[mujoco]' (or jointbench[all])"], got.stderr
    import pandas as pd

    rows = pd.read_csv(tmp_path / "out" / "tiny" / "cases.csv", low_memory=False)
    assert set(rows.loc[rows["metric"] != "skipped", "backend"]) == {"analytic"}
    skipped = rows[rows["metric"] == "skipped"]
    assert list(skipped["backend"]) == ["mujoco"] and "jointbench[mujoco]" in skipped["reason"].iloc[0]
    report = (tmp_path / "out" / "tiny" / "report.md").read_text()
    assert "jointbench[mujoco]" in report                         # the skipped rows, with the reason
    assert "backend analytic;" in report and "analytic and mujoco" not in report    # nothing ran on MuJoCo


def test_api_scenarios_says_what_it_leaves_out(without_mujoco):
    from jointbench import api

    with pytest.warns(UserWarning, match=r"leaves out .*study apparatus: .*jointbench\[mujoco\]"):
        frame = api.scenarios()
    assert set(frame.attrs["left_out"]) == {"apparatus"}
    assert "apparatus" not in set(frame["study"])
    assert {"matrix:xu1998_elbow", "matrix:framework_square"} <= set(frame["name"])   # the grid loads without it


# ------------------------------------------------------------------------- identify by default, and the hint
@pytest.mark.parametrize("identify", [None, False])
def test_an_unranked_scenario_says_why(tmp_path, identify):
    """A new grid without 'identify' gets the identifiability rows (on by default), and the report says why a
    scenario is not ranked with their figures; with 'identify: false' it says how to get them."""
    from jointbench.benchmarks.study import run_study
    from tests.harness_studies import tiny_grid_part

    part = tiny_grid_part(["ibk_spectral"], realizations=2, noise=[0.05])    # time-invariant: no VAF of k > 0
    part["params"].pop("identify")                    # a new study's grid, as written by its author
    if identify is not None:
        part["params"]["identify"] = identify
    run = run_study(tiny_study(tmp_path / "c", extra_parts={"grid": part}), parts=["grid"], serial=True,
                    progress=False, out_root=tmp_path / "out")
    rows = run.rows
    ident = rows[(rows["estimator"] == "(scenario)") & ~rows["metric"].astype(str).str.startswith("oracle")]
    assert len(ident) == (0 if identify is False else 4)
    best = rows[(rows["metric"] == "vaf_stiffness")]["value"].median()
    assert best <= 0
    text = (run.folder / "report.md").read_text()
    assert "**0 of 1 scenarios are ranked**" in text
    hint = next(line for line in text.splitlines() if "Not ranked, and why: " in line)
    hint = hint[hint.index("Not ranked, and why: "):]
    if identify is False:
        assert "no identifiability rows (the part's params.identify is false" in hint
    else:
        tv = float(ident.set_index("metric")["value"]["tv_share"])
        assert f"the time-varying stiffness torque is {tv:.3g} % of the measured torque's variance" in hint
