"""Outside methods end to end: the worked example (examples/plugin_estimator) pip-installed into a folder
of its own, found by its entry point, benchmarked beside two built-in estimators on the process pool and
on a local Dask cluster (identical rows), and recomputed (only its cases) when its source is edited."""
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from jointbench.core import plugins
from jointbench.core.errors import ConfigError
from tests.harness_studies import cli_env

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "plugin_estimator"
TIMINGS = ("wall_time_s", "sim_time_s")


def _pip_install(src: Path, target: Path) -> None:
    """``pip install`` the plugin into ``target`` (no dependencies: the test venv has them; no build
    isolation: its setuptools builds it, nothing is downloaded)."""
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                    "--no-index", "--upgrade", "--target", str(target), str(src)], check=True, timeout=600,
                   capture_output=True)


@pytest.fixture(scope="module")
def plugin(tmp_path_factory):
    """(source copy, install folder, env with the install folder on PYTHONPATH)."""
    root = tmp_path_factory.mktemp("plugin")
    src = root / "src"
    shutil.copytree(EXAMPLE, src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    target = root / "site"
    _pip_install(src, target)
    env = cli_env()
    env["PYTHONPATH"] = str(target)
    return src, target, env


def _jb(env, *args, cwd, timeout=600):
    r = subprocess.run([sys.executable, "-m", "jointbench", *map(str, args)], cwd=cwd, env=env,
                       capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, r.stdout + r.stderr
    return r


def _numbers(path: Path) -> pd.DataFrame:
    """The rows but their timings and the column naming the plugin's code (installed or not, edited or not)."""
    rows = pd.read_csv(path)
    rows = rows.drop(columns=[c for c in (*TIMINGS, "plugin") if c in rows.columns])
    rows = rows[rows["metric"] != "fit_time_s"]
    return rows.sort_values(["case_id", "estimator", "metric"], kind="stable").reset_index(drop=True)


def _cases(out: Path) -> pd.DataFrame:
    from jointbench import api

    history = api.History(out)
    runs = history.runs().sort_values("id")
    cases = history.cases(int(runs["id"].iloc[-1]))
    cases["estimator"] = cases["case_id"].str.extract(r"estimator=([a-z0-9_]+)")[0]
    return cases.set_index("estimator")


def test_the_plugin_runs_everywhere_and_an_edit_recomputes_its_cases(plugin, tmp_path):
    src, target, env = plugin
    listed = _jb(env, "estimate", "--list", cwd=tmp_path).stdout          # found by its entry point
    assert "sliding_ibk" in listed and "a plugin example" in listed
    study, out = src / "comparison.yaml", tmp_path / "results"
    pool = _jb(env, "run", study, "--out", out, "--workers", "2", "--quiet", cwd=tmp_path)
    assert "6 cases (0 from cache, 6 computed), 0 failed" in pool.stdout    # sliding_ibk, fsewls tuned too; identify
    first = _numbers(out / "plugin_comparison" / "cases.csv")
    assert set(first["estimator"]) == {"sliding_ibk", "fsewls", "irf2_ls", "(scenario)"}   # identify: on by default
    assert (first["status"] == "ok").sum() == len(first) - 1                # irf2_ls tuned: "nothing to tune"
    assert first[first["status"] != "ok"]["reason"].str.startswith("nothing to tune: irf2_ls").all()
    before = _cases(out)
    # not installed: the study's plugins: finds the package folder beside it, and the workers of a local Dask
    # cluster import it from that folder (jointbench.core.plugins.ensure): every row identical to the pool's
    bare = {k: v for k, v in env.items() if k != "PYTHONPATH"}
    beside = tmp_path / "beside"
    _jb(bare, "run", study, "--out", beside, "--executor", "dask", "--workers", "2", "--quiet", cwd=tmp_path)
    pd.testing.assert_frame_equal(_numbers(beside / "plugin_comparison" / "cases.csv"), first)
    # edit the plugin's code (a statement that changes no number: its source hash changes; a comment would not,
    # tests/test_tuning_declared.py), install it again: its cases recompute, only they, here on a local Dask
    # cluster whose workers import the installed plugin (PYTHONPATH), with the pool's numbers. This run and the
    # one beside are the Dask runs of the plugin installed and not installed; a third, of the whole grid with the
    # plugin installed, checked nothing more (and took 7 CPU-s, a third of the test).
    init = src / "sliding_ibk" / "__init__.py"
    init.write_text(init.read_text() + "\n_EDITED = True\n")
    _pip_install(src, target)
    again = _jb(env, "run", study, "--out", out, "--executor", "dask", "--workers", "2", "--quiet", cwd=tmp_path)
    assert "6 cases (4 from cache, 2 computed), 0 failed" in again.stdout
    cases = _cases(out)
    def of(frame, est, column="cache_key"):
        return list(frame.loc[frame.index == est, column])

    assert of(cases, "sliding_ibk", "cached") == [0, 0] and of(cases, "fsewls", "cached") == [1, 1]
    assert not set(of(cases, "sliding_ibk")) & set(of(before, "sliding_ibk"))
    assert of(cases, "irf2_ls") == of(before, "irf2_ls")
    pd.testing.assert_frame_equal(_numbers(out / "plugin_comparison" / "cases.csv"), first)   # no number changed


def test_a_plugin_by_path_and_its_errors(tmp_path):
    p = tmp_path / "my_method.py"
    p.write_text("raise RuntimeError('broken on purpose')\n")
    with pytest.raises(ConfigError, match=r"^--plugin: plugin .*my_method.py' failed to import: RuntimeError: broken"):
        plugins.load(str(p))
    with pytest.raises(ConfigError, match="no module named 'no_such_plugin_xyz'"):
        plugins.load("no_such_plugin_xyz")
    from jointbench import estimators

    loaded = plugins.load(str(EXAMPLE / "sliding_ibk"))
    try:
        assert loaded.module == "sliding_ibk" and "sliding_ibk" in estimators.REGISTRY.names()
        from jointbench.benchmarks.harness.fingerprint import plugin_hash

        text = plugin_hash(["sliding_ibk", "fsewls"])
        assert list(text) == ["sliding_ibk"] and text["sliding_ibk"].startswith("sliding_ibk==0.1.0 ")  # __version__
    finally:
        estimators.REGISTRY._items.pop("sliding_ibk", None)
        estimators.REGISTRY._tags.pop("sliding_ibk", None)
