"""Where a study's files are: the shipped studies and configs (package data), and what a study file names.

A shipped study is a folder, ``benchmarks/studies/<id>/`` (package ``jointbench.benchmarks.studies.<id>``):
its ``study.yaml``, its ``published.yaml`` and the code that is its own (``protocol.py``, ``figures.py``).
The joint models several studies share and the nightly config are package data too, ``jointbench.configs``
(the checkout's ``configs/``). Both are installed inside the wheel, so a study runs the same from an
installed wheel in any folder as from the checkout. A study of one's own (``jointbench run
path/to/my_study.yaml``, or a folder holding a ``study.yaml``) finds the joint models, published values and
plugins it names beside it first (and in the config folder it is part of), then in the package. Nothing
here is ever written: results go to ``./results`` or ``--out`` (:func:`benchmarks.study.results_root`).
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from jointbench.core.errors import ConfigError


def _package_folder(package: str) -> Path:
    """The folder of package ``package`` (in a checkout, its folder: ``configs/``, ``benchmarks/studies/``)."""
    from importlib.resources import files

    return Path(str(files(package)))


#: the shipped configs shared by the studies: joint models (``models/``) and ``nightly.yaml`` (read-only)
CONFIGS = _package_folder("jointbench.configs")
#: the shipped studies, one folder each (read-only)
STUDIES = _package_folder("jointbench.benchmarks.studies")
#: the file that makes a folder a study
STUDY_FILE = "study.yaml"


def study_ids(studies_dir: Path = STUDIES) -> list[str]:
    """The shipped studies (``jointbench list``): the folders holding a ``study.yaml``."""
    return sorted(p.parent.name for p in Path(studies_dir).glob(f"*/{STUDY_FILE}"))


def study_path(ref: str | Path, studies_dir: Path = STUDIES) -> Path:
    """The file of study ``ref``: a path to a YAML file, a folder holding a ``study.yaml``, or the id of a
    shipped study."""
    path = Path(ref)
    if path.is_dir() and (path / STUDY_FILE).is_file():
        return path / STUDY_FILE
    if path.is_dir():
        raise ConfigError(f"{path}: is a folder, not a file, and holds no {STUDY_FILE}; give a study file (e.g. "
                          f"my_study.yaml) or a folder holding a {STUDY_FILE}")
    if path.suffix:
        return path
    shipped = Path(studies_dir) / str(path) / STUDY_FILE
    if not shipped.is_file() and not path.is_file():
        raise ConfigError(f"unknown study {str(ref)!r}; shipped studies: {', '.join(study_ids(studies_dir))} "
                          f"(or give the path of a study file, e.g. my_study.yaml, or of a folder holding a "
                          f"{STUDY_FILE})")
    return shipped if shipped.is_file() else path


def search_roots(study_file: Path | None, configs_dir: Path = CONFIGS) -> list[Path]:
    """Where the names and relative paths of a study file are looked up, in order: the study's folder, the
    config folder it is part of (the parent of a ``studies/`` folder), then the package's configs (joint
    models: ``models/``) and their parent (so that ``configs/models/x.yaml``, written relative to a checkout,
    resolves from a wheel too)."""
    roots = []
    if study_file is not None:
        here = Path(study_file).resolve().parent
        roots += [here] + ([here.parent] if here.name == "studies" else [])
    roots += [Path(configs_dir), Path(configs_dir).parent]
    return list(dict.fromkeys(roots))


def model_dirs(roots: Sequence[Path]) -> list[Path]:
    """The folders a joint model named in a study is looked up in: the study's own folder, then
    ``<root>/models`` for each root (:func:`search_roots`) that has one."""
    out = [r / "models" for r in roots if (r / "models").is_dir()]
    if roots:
        out.insert(0, roots[0])
    return list(dict.fromkeys(out))


def find_model(name: str, dirs: Sequence[Path], where: str) -> Path:
    """The file ``<name>.yaml`` of a joint model named in a config, from the first of ``dirs`` holding it."""
    for d in dirs:
        if (Path(d) / f"{name}.yaml").is_file():
            return Path(d) / f"{name}.yaml"
    known = ", ".join(sorted({p.stem for d in dirs if Path(d).name == "models" for p in Path(d).glob("*.yaml")}))
    raise ConfigError(f"{where}: key 'joint': no model file {name}.yaml in {', '.join(str(d) for d in dirs)}; "
                      f"known: {known or '(none)'}")


def find_file(ref: str | Path, roots: Sequence[Path], where: str, key: str) -> Path:
    """A path named in a study file: absolute, or the first ``root / ref`` that exists."""
    ref = Path(ref)
    found = [ref] if ref.is_absolute() else [root / ref for root in roots]
    for cand in found:
        if cand.is_file():
            return cand
    for cand in found:
        if cand.is_dir():
            raise ConfigError(f"{where}: key {key!r}: {cand}: is a folder; the key names a file (a .yaml)")
    if ref.is_absolute():
        raise ConfigError(f"{where}: key {key!r}: {ref}: file not found")
    raise ConfigError(f"{where}: key {key!r}: {ref} not found beside the study or in the package's configs "
                      f"(looked in {', '.join(str(r) for r in roots)})")


def load_plugins(refs: Sequence[str], where: str, roots: Sequence[Path]) -> tuple[str, ...]:
    """Import a study's ``plugins`` (module names, or ``.py`` files and package folders beside the study, as
    parsed by :class:`benchmarks.config.StudyFile`) so that their estimators are registered; returns their
    specs (:func:`jointbench.core.plugins.load`). A bare name is an installed module when one is importable,
    else a package folder or ``<name>.py`` beside the study."""
    import importlib.util

    from jointbench.core import plugins

    out = []
    for ref in refs:
        if ref.endswith(".py") or "/" in ref:
            ref = str(next((r / ref for r in roots if (r / ref).exists()), Path(ref)))
        elif importlib.util.find_spec(ref.split(".")[0]) is None:     # not installed: a folder or file beside
            here = roots[0] if roots else Path.cwd()
            for cand in (here / ref, here / f"{ref}.py"):
                if (cand / "__init__.py").is_file() or cand.is_file():
                    ref = str(cand)
                    break
        out.append(plugins.load(ref, f"{where}: key 'plugins'").spec)
    return tuple(out)
