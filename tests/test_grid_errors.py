"""A config error inside a comparison grid is an error before anything runs (exit 2), an impossible
combination a skip; repeated values, oversized grids and ``--budget nan`` are refused (issue 20)."""
from __future__ import annotations

import time

import numpy as np
import pytest

from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.runner import expand_study
from jointbench.core.errors import ConfigError
from tests.harness_studies import cli_here as cli, tiny_grid_part, tiny_study


def _grid(tmp_path, edit=None, **axes):
    part = tiny_grid_part(["ibk_spectral"], **axes)
    if edit is not None:
        edit(part, tmp_path)
    return tiny_study(tmp_path / "cfg", extra_parts={"grid": part})


def _exp(part):
    return part["scenarios"]["elbow"]["experiment"]


def _profile(tmp_path, low=40.0, t_end=10.0):
    p = tmp_path / "k.csv"
    t = np.linspace(0, t_end, 11)
    p.write_text("time,value\n" + "".join(f"{a:g},{low if i % 2 else 60:g}\n" for i, a in enumerate(t)))
    return p


def _variation(**kw):
    def edit(part, tmp_path):
        part["variations"]["square"] = {"shape": "file", **{k: (v(tmp_path) if callable(v) else v)
                                                              for k, v in kw.items()}}
    return edit


def _unstable(part, tmp_path):
    _exp(part)["joint"]["K"] = 2.0e7
    part["scenarios"]["elbow"]["stiffness"] = {"mean": 2.0e7, "amplitude": 1.0e6, "period": "4 s"}
    part["grid"]["backend"] = ["mujoco"]


CONFIG_ERRORS = {
    "typo'd key duraton": (lambda p, t: _exp(p).update(duraton=_exp(p).pop("duration")), "unknown key 'duraton'"),
    "typo'd key Kk": (lambda p, t: _exp(p)["joint"].update(Kk=_exp(p)["joint"].pop("K")), "'Kk'"),
    "negative duration": (lambda p, t: _exp(p).update(duration="-8 s"), "duration"),
    "zero inertia": (lambda p, t: _exp(p)["joint"].update(I=0), "'I'"),
    "unknown variation shape": (lambda p, t: p["variations"].update(square={"shape": "sqare"}), "sqare"),
    "fs above fs_sim": (lambda p, t: p["grid"].update(fs=["5 kHz"]), "is above fs_sim"),
    "negative cutoff": (lambda p, t: _exp(p)["perturbation"].update(cutoff="-20 Hz"), "cutoff"),
    "missing profile file": (_variation(path=lambda t: str(t / "nope.csv")), "nope.csv: not found"),
    "wrong sha256 profile": (_variation(path=lambda t: str(_profile(t)), sha256="0" * 64), "SHA-256"),
    "profile making K negative": (_variation(path=lambda t: str(_profile(t, low=-5.0))), "the profile reaches -5"),
    "unstable MuJoCo step": (_unstable, "unstable"),
}


@pytest.mark.parametrize("name", list(CONFIG_ERRORS))
def test_a_config_error_inside_a_grid_is_an_error_naming_the_combination(tmp_path, name):
    edit, words = CONFIG_ERRORS[name]
    with pytest.raises(ConfigError) as exc:      # when the study is loaded (a variation's keys) or expanded
        expand_study(load_study(_grid(tmp_path, edit)), ["grid"])
    msg = str(exc.value)
    assert words in msg and "parts.grid" in msg and "\n" not in msg, msg
    assert "the combination scenario=elbow" in msg or "grid" in msg


def test_a_config_error_inside_a_grid_exits_2_before_anything_runs(tmp_path):
    path = _grid(tmp_path, CONFIG_ERRORS["typo'd key duraton"][0])
    r = cli("run", path, "--parts", "grid", "--out", tmp_path / "out", "--quiet")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "duraton" in r.stderr, r.stderr
    assert "(a misspelt 'duration', which is missing?)" in r.stderr       # one error, not two
    assert "the combination scenario=elbow, variation=square, noise=0" in r.stderr
    assert not (tmp_path / "out" / "history.sqlite").exists() and not (tmp_path / "out" / "cache").exists()


def test_an_impossible_combination_is_still_a_skip(tmp_path):
    """skirt needs a multisine: on PRBS it is skipped with the reason, and the run goes on."""
    def prbs(part, tmp_path):
        part["grid"]["estimator"] = ["ibk_spectral", "skirt"]
        part["grid"]["perturbation"] = ["prbs"]
        part["perturbations"] = {"prbs": {"kind": "prbs", "amplitude": 0.02, "clock": "20 ms"}}
    cases, skipped = expand_study(load_study(_grid(tmp_path, prbs)), ["grid"])
    assert {c.sweep["estimator"] for c in cases} == {"ibk_spectral"}
    assert {s["estimator"] for s in skipped} == {"skirt"} and all("multisine" in s["reason"] for s in skipped)


@pytest.mark.parametrize("order", [["analytic", "lti"], ["lti", "analytic"]])
def test_each_backend_builds_its_own_experiment_and_skip_verdict(tmp_path, order):
    """The lti backend cannot simulate a time-varying joint: its combinations are skipped with that reason,
    the analytic ones run, whichever comes first on the axis (an experiment built once for both backends
    would give both the verdict of the first)."""
    cases, skipped = expand_study(load_study(_grid(tmp_path, backend=order)), ["grid"])
    assert {c.backend for c in cases} == {"analytic"} and len(cases) == 2
    assert {s["backend"] for s in skipped} == {"lti"} and len(skipped) == 2
    assert all("backend 'lti' cannot simulate" in s["reason"] for s in skipped)


@pytest.mark.parametrize("axes, words", [
    ({"noise": [1, 1.0]}, "grid.noise[1]: 1.0 is the same value as grid.noise[0] 1"),
    ({"noise": [0.05, 5.0e-2]}, "grid.noise: a value is listed twice"),
    ({"fs": ["100 Hz", "0.1 kHz"]}, "grid.fs[1]: '0.1 kHz' is the same value as grid.fs[0] '100 Hz' (100 Hz)"),
])
def test_values_that_mean_the_same_are_refused_before_the_run(tmp_path, axes, words):
    with pytest.raises(ConfigError, match=__import__("re").escape(words)):
        load_study(_grid(tmp_path, **axes))


def test_the_same_values_through_set_are_refused_too(tmp_path):
    r = cli("run", _grid(tmp_path), "--parts", "grid", "--out", tmp_path / "out", "--quiet",
            "--set", "grid.grid.fs=[100 Hz, 0.1 kHz]")
    assert r.returncode == 2 and "is the same value as grid.fs[0]" in r.stderr and r.stderr.count("\n") == 1


def test_a_grid_of_a_million_combinations_is_refused_at_once(tmp_path):
    def huge(part, tmp_path):
        part["grid"]["noise"] = [round(i * 1e-4, 6) for i in range(1000)]
        part["grid"]["fs"] = [f"{i} Hz" for i in range(1, 1001)]
    path = _grid(tmp_path, huge)
    t0 = time.process_time()
    with pytest.raises(ConfigError, match=r"grid: 1 scenario x 1 variation x 1000 noise x 1000 fs x 1 estimator = "
                                          r"1000000 combinations, more than the 20000 a grid may have"):
        load_study(path)
    assert time.process_time() - t0 < 60          # it never expands them (a guard, not a timing target)


@pytest.mark.parametrize("budget", ["nan", "0", "-5", "abc"])
def test_budget_must_be_minutes_above_zero(tmp_path, budget):
    r = cli("run", _grid(tmp_path), "--out", tmp_path / "out", "--quiet", "--budget", budget)
    assert r.returncode == 2 and "--budget: expected minutes > 0" in r.stderr and r.stderr.count("\n") == 1, r.stderr


def test_nan_budget_cannot_bypass_the_check_from_python(tmp_path):
    from jointbench.benchmarks.study import run_study

    with pytest.raises(ConfigError, match="^budget: expected minutes > 0"):
        run_study(_grid(tmp_path), parts=["grid"], out_root=tmp_path / "out", serial=True, progress=False,
                  budget_minutes=float("nan"))


def test_two_cases_under_one_name_are_refused_before_the_run(tmp_path):
    import yaml

    path = tiny_study(tmp_path / "cfg")
    data = yaml.safe_load(path.read_text())
    data["parts"]["fit"]["seeds"] = 1
    data["parts"]["fit"]["sweep"] = {"near_unity": [0.9, "0.9"]}
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    with pytest.raises(ConfigError, match=r"two cases are named .fit-near_unity=0.9-seed0."):
        expand_study(load_study(path))
