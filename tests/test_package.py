"""The package travels: shipped configs as package data, a study of one's own run from its folder (its
models and published values beside it, then the package's), results in ./results or --out, one version
source, a light core whose optional parts fail in one line naming their extra."""
import tomllib
from pathlib import Path

import pytest
import yaml

import jointbench
from jointbench.benchmarks import locate
from jointbench.benchmarks.config import check_backend, load_study
from jointbench.core.errors import ConfigError
from tests.harness_studies import tiny_study

REPO = Path(__file__).resolve().parents[1]


def test_the_shipped_configs_are_package_data_found_by_the_import_system():
    assert locate.CONFIGS.samefile(REPO / "configs")         # editable install: the checkout's folder
    assert locate.STUDIES.samefile(REPO / "benchmarks" / "studies")
    assert locate.study_ids() == sorted(p.parent.name for p in (REPO / "benchmarks" / "studies").glob("*/study.yaml"))
    cfg = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert cfg["package-dir"]["jointbench.configs"] == "configs"
    for package, folder in (("jointbench.configs", REPO / "configs"),
                            ("jointbench.benchmarks.studies", REPO / "benchmarks" / "studies")):
        globs = cfg["package-data"][package]
        shipped = {p.relative_to(folder).as_posix() for p in folder.rglob("*.yaml")}
        covered = {s for s in shipped if any(Path(s).match(g) and s.count("/") == g.count("/") for g in globs)}
        assert shipped and covered == shipped, shipped - covered


def test_nothing_user_facing_derives_a_path_from_where_the_code_is():
    """Results, READMEs and reports: from the current folder or an argument, never from a module's own
    ``__file__`` (the only uses left read package data: the report templates beside pages.py; and the
    developers' script that rewrites the Table I checks beside it)."""
    import re

    own = re.compile(r"(?<![\"'.\w])__file__")
    bad = []
    for folder in ("jointbench", "sims", "estimators", "benchmarks"):
        for f in (REPO / folder).rglob("*.py"):
            for i, line in enumerate(f.read_text().splitlines(), 1):
                if own.search(line) and "templates" not in line and f.name != "generate_checks.py":
                    bad.append(f"{f.relative_to(REPO)}:{i}: {line.strip()}")
    assert not bad, bad


def test_a_study_of_ones_own_finds_its_model_and_values_beside_it(tmp_path, monkeypatch):
    path = tiny_study(tmp_path / "mine", seeds=1, duration="2 s")
    data = yaml.safe_load(path.read_text())
    (tmp_path / "mine" / "models").mkdir()
    (tmp_path / "mine" / "models" / "my_joint.yaml").write_text(yaml.safe_dump(
        {"model": "second_order", "I": 0.01, "B": 0.5, "K": 50}))
    data["parts"]["fit"]["experiment"]["joint"] = "my_joint"                # beside it, in models/
    data["published"] = Path(data["published"]).name                          # relative: beside it
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    study = load_study(path)
    assert study.parts["fit"].experiment["joint"]["K"] == 50 and len(study.checks) == 2
    data["parts"]["fit"]["experiment"]["joint"] = "ankle_westwick2012"        # not beside: the package's
    del data["published"]                                                     # optional: no checks
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    study = load_study(path)
    assert study.parts["fit"].experiment["joint"]["K"] == "140 N.m/rad" and study.checks == ()
    data["parts"]["fit"]["experiment"]["joint"] = "nobody"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    with pytest.raises(ConfigError, match=r"key 'joint': no model file nobody.yaml in .*mine.*known: .*my_joint"):
        load_study(path)
    with pytest.raises(ConfigError, match=r"unknown study 'westwik2012'; shipped studies: .*westwick2012"):
        load_study("westwik2012")


def test_results_go_to_the_current_folder_by_default(tmp_path, monkeypatch):
    from jointbench.benchmarks.study import results_root, run_study

    monkeypatch.chdir(tmp_path)
    assert results_root() == tmp_path / "results"
    path = tiny_study(tmp_path / "cfg", seeds=1, duration="2 s")
    run = run_study(path, serial=True, progress=False)
    assert run.folder == (tmp_path / "results" / "tiny").resolve()
    assert (tmp_path / "results" / "tiny" / "report.md").is_file()
    assert (tmp_path / "results" / "history.sqlite").is_file()


def test_one_version_source():
    import importlib.metadata

    meta = tomllib.loads((REPO / "pyproject.toml").read_text())
    assert "version" not in meta["project"] and meta["project"]["dynamic"] == ["version"]
    assert meta["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "jointbench.__version__"}
    assert importlib.metadata.version("jointbench") == jointbench.__version__
    cff = yaml.safe_load((REPO / "CITATION.cff").read_text())
    assert str(cff["version"]) == jointbench.__version__
    assert len(cff["references"]) == 3 and cff["license"] == "BSD-3-Clause"
    assert (REPO / "LICENSE").read_text().startswith("BSD 3-Clause License")
    assert f"## [{jointbench.__version__}]" in (REPO / "CHANGELOG.md").read_text()


def test_the_light_core_and_its_extras():
    meta = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    core = {d.split(">")[0].split("<")[0].split("[")[0].strip().lower() for d in meta["dependencies"]}
    assert not core & {"mujoco", "dm-control", "dask", "h5py"}, core
    extras = meta["optional-dependencies"]
    assert {"mujoco", "dask", "hdf5", "all", "test"} <= set(extras)
    assert extras["all"] == ["jointbench[mujoco,dask,hdf5,matlab]"]


def test_the_mujoco_backend_without_its_extra_is_one_line_naming_it(monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "mujoco" else real(name, *a))
    with pytest.raises(ConfigError) as exc:
        check_backend("mujoco", "option --backend")
    text = str(exc.value)
    assert "\n" not in text and "pip install 'jointbench[mujoco]'" in text and text.startswith("option --backend")
    with pytest.raises(ConfigError, match=r"jointbench\[mujoco\]"):
        load_study("apparatus")                              # its parts say backend: mujoco
    assert check_backend("analytic", "x") == "analytic"


def test_the_git_stamp_comes_from_the_checkout_and_a_wheel_gets_its_version(monkeypatch):
    from jointbench.benchmarks.harness import fingerprint

    assert fingerprint.REPO == REPO
    assert fingerprint.repo_path(REPO / "sims" / "backend.py") == "sims/backend.py"
    monkeypatch.setattr(fingerprint, "REPO", None)             # what an installed wheel sees
    assert fingerprint.git_commit() == f"v{jointbench.__version__}"
    assert fingerprint.git_state() == (f"v{jointbench.__version__}", False)
