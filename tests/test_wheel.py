"""The issue's acceptance, as a new user: a wheel built from the checkout, installed into a fresh venv
outside it, used from an empty folder: ``jointbench list`` lists every study, ``jointbench run westwick2012
--parts fig2`` writes ./results/westwick2012/report.md, ``jointbench estimate`` runs on a CSV, a study file
of one's own runs beside its own model; site-packages holds ``jointbench`` and no ``sims``, ``estimators``
or ``benchmarks``.

Fast and offline: the wheel is built without build isolation (the test venv's setuptools) and installed
with ``--no-deps``; the new venv reaches the core's libraries (numpy, scipy, pandas, ...) through a ``.pth``
line to a folder of links into the test venv's site-packages, so nothing is downloaded. The folder leaves
out jointbench itself (the venv's is the wheel's) and every extra (mujoco, dm_control, dask, h5py): the
venv is the light core, and asking for an extra's feature is one line naming the extra.
"""
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

import jointbench

REPO = Path(__file__).resolve().parents[1]
SOURCES = ("pyproject.toml", "README.md", "LICENSE", "jointbench", "sims", "estimators", "benchmarks", "configs")
#: what the light core's venv does not see of the test venv: jointbench's editable install and the extras
EXTRAS = ("jointbench", "__editable__", "mujoco", "dm_control", "dm_env", "labmaze", "dask", "distributed", "h5py",
          "matio", "mat_io")


@pytest.fixture(scope="module")
def venv(tmp_path_factory):
    """(python, jointbench script, site-packages) of a fresh venv with the wheel of this checkout."""
    root = tmp_path_factory.mktemp("wheel")
    src = root / "src"                      # a copy: building in place would leave build/ in the checkout
    src.mkdir()
    for name in SOURCES:
        (shutil.copytree if (REPO / name).is_dir() else shutil.copy2)(
            REPO / name, src / name, **({"ignore": shutil.ignore_patterns("__pycache__", "*.egg-info")}
                                        if (REPO / name).is_dir() else {}))
    dist = root / "dist"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation",
                    "--no-index", "-w", str(dist), str(src)], check=True, capture_output=True, timeout=900)
    (wheel,) = dist.glob("jointbench-*.whl")
    env = root / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(env)], check=True, timeout=300)
    purelib = "import sysconfig; print(sysconfig.get_paths()['purelib'])"
    site = Path(subprocess.run([str(env / "bin" / "python"), "-c", purelib], check=True, capture_output=True,
                               text=True).stdout.strip())
    libs = root / "core-libraries"                 # the test venv's libraries, without jointbench and the extras
    libs.mkdir()
    for entry in Path(sysconfig.get_paths()["purelib"]).iterdir():
        if not entry.name.lower().startswith(EXTRAS) and not entry.name.endswith(".pth"):
            (libs / entry.name).symlink_to(entry)
    (site / "_test_venv_libraries.pth").write_text(f"{libs}\n")
    subprocess.run([str(env / "bin" / "python"), "-m", "pip", "install", "--quiet", "--no-deps", "--no-index",
                    "--ignore-installed", str(wheel)], check=True, capture_output=True, timeout=900)
    return env / "bin" / "python", env / "bin" / "jointbench", site


def _run(cmd, cwd, timeout=900):
    r = subprocess.run([str(c) for c in cmd], cwd=cwd, capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout


def test_site_packages_holds_jointbench_alone(venv):
    python, _, site = venv
    top = {p.name for p in site.iterdir() if not p.name.endswith((".dist-info", ".pth")) and p.name != "__pycache__"}
    assert top == {"jointbench"}, top
    assert (site / "jointbench" / "benchmarks" / "studies" / "westwick2012" / "study.yaml").is_file()
    assert (site / "jointbench" / "benchmarks" / "studies" / "westwick2012" / "published.yaml").is_file()
    assert (site / "jointbench" / "configs" / "models" / "elbow_xu1998.yaml").is_file()
    assert (site / "jointbench" / "benchmarks" / "harness" / "templates").is_dir()
    where = _run([python, "-c", "import jointbench.sims, jointbench.benchmarks.locate as l; "
                  "print(jointbench.sims.__file__); print(l.CONFIGS)"], cwd=site.parent)
    assert all(line.startswith(str(site)) for line in where.split()), where


def test_an_empty_folder_lists_runs_and_estimates(venv, tmp_path):
    python, jb, _ = venv
    listed = _run([jb, "list"], cwd=tmp_path)
    studies = sorted(p.stem for p in (REPO / "configs" / "studies").glob("*.yaml"))
    assert f"studies:   {', '.join(studies)}" in listed
    _run([jb, "run", "westwick2012", "--parts", "fig2", "--quiet"], cwd=tmp_path)
    report = tmp_path / "results" / "westwick2012" / "report.md"
    assert report.is_file() and "fig2" in report.read_text()
    comparison = pd.read_csv(tmp_path / "results" / "westwick2012" / "checks.csv")
    assert set(comparison["commit"]) == {f"v{jointbench.__version__}"}       # no git: the package's version
    assert (comparison["status"] == "pass").all()
    # a code hash of the same source, wherever it is installed
    from jointbench.benchmarks.harness.fingerprint import code_hash

    assert _run([python, "-c", "from jointbench.benchmarks.harness.fingerprint import code_hash; print(code_hash())"],
                cwd=tmp_path).strip() == code_hash()
    rng = np.random.default_rng(0)
    u = np.convolve(rng.standard_normal(3000), np.ones(5) / 5, "same")
    pd.DataFrame({"time": np.arange(3000) / 200.0, "angle": u, "torque": 50 * u + 0.01 * rng.standard_normal(3000)}
                 ).to_csv(tmp_path / "rec.csv", index=False)
    out = _run([jb, "estimate", "-e", "irf2_ls", "-i", "rec.csv", "-o", "est.csv", "--set", "lag_before=20ms",
                "--set", "lag_after=20ms"], cwd=tmp_path)
    assert "VAF" in out and (tmp_path / "est_irf.csv").is_file()
    assert pd.read_csv(tmp_path / "est.csv")["stiffness"].mean() == pytest.approx(50, rel=0.02)


def test_a_study_file_of_ones_own_from_the_wheel(venv, tmp_path):
    _, jb, _ = venv
    folder = tmp_path / "my"
    (folder / "models").mkdir(parents=True)
    (folder / "models" / "stiff_ankle.yaml").write_text(yaml.safe_dump({"model": "second_order", "I": 0.015,
                                                                        "B": 0.8, "K": 200}))
    (folder / "values.yaml").write_text(yaml.safe_dump({"study": "mine", "source": "me", "checks": [
        {"id": "K", "part": "fit", "description": "K", "source": "-", "published": 200, "low": 190, "high": 210,
         "select": {"metric": "K", "estimator": "ibk_spectral"}, "evidence": "sanity",
         "tolerance_reason": "a noiseless fit"}]}))
    (folder / "mine.yaml").write_text(yaml.safe_dump({
        "study": "mine", "title": "my ankle", "paper": "none", "published": "values.yaml", "not_reproduced": [],
        "parts": {"fit": {"protocol": "parametric_fit", "description": "fit", "seeds": 1,
                          "experiment": {"joint": "stiff_ankle",
                                         "perturbation": {"kind": "filtered_noise", "cutoff": "20 Hz", "order": 2,
                                                          "rms": "0.02 rad"},
                                         "apparatus": {"kind": "position_servo", "stiffness": "30000 N.m/rad"},
                                         "fs_sim": "2 kHz", "duration": "4 s", "acquisition": {"fs": "500 Hz"}},
                          "estimators": {"ibk_spectral": {"fmin": "0 Hz", "fmax": "20 Hz", "segment": "2 s"}}}}}))
    out = _run([jb, "run", "my/mine.yaml", "--out", "elsewhere", "--serial", "--quiet"], cwd=tmp_path)
    assert "pass  sanity" in out
    assert (tmp_path / "elsewhere" / "mine" / "report.md").is_file() and not (tmp_path / "results").exists()


def test_the_light_core_names_the_extra_a_feature_needs(venv, tmp_path):
    python, jb, _ = venv
    assert _run([python, "-c", "import importlib.util as u; print([m for m in ('mujoco', 'dask', 'h5py') "
                 "if u.find_spec(m)])"], cwd=tmp_path).strip() == "[]"
    for args, extra in ((["run", "apparatus"], "jointbench[mujoco]"),
                        (["run", "westwick2012", "--backend", "mujoco"], "jointbench[mujoco]"),
                        (["run", "westwick2012", "--parts", "fig2", "--executor", "dask"], "jointbench[dask]")):
        r = subprocess.run([str(jb), *args], cwd=tmp_path, capture_output=True, text=True, timeout=600)
        assert r.returncode == 2, r.stdout + r.stderr
        lines = r.stderr.strip().splitlines()      # one line per part that needs the extra (apparatus: 2)
        assert 1 <= len(lines) <= 2 and all(extra in line for line in lines), r.stderr
    loaded = _run([python, "-c", "import sys, jointbench.api, jointbench.sims, jointbench.cli.studies; "
                   "print(sorted({m.split('.')[0] for m in sys.modules} & {'mujoco', 'dm_control', 'dask', 'h5py'}))"],
                  cwd=tmp_path)
    assert loaded.strip() == "[]", loaded
