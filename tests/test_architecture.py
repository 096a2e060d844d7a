"""Dependencies flow one way: jointbench <- {sims, estimators} <- benchmarks <- api <- CLI.

The repository's folders ``jointbench/``, ``sims/``, ``estimators/`` and ``benchmarks/`` are one installed
namespace: ``jointbench``, ``jointbench.sims``, ``jointbench.estimators``, ``jointbench.benchmarks``
(pyproject.toml's package-dir). Here each folder is a *room*: ``core`` (jointbench/), ``sims``,
``estimators`` and ``benchmarks``; and two rooms on top: ``api`` (jointbench/api.py, the Python API, which
may use everything below it) and ``cli`` (the command-line modules, which wrap the API and the harness).
"""
import ast
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: room -> installed package
PACKAGE_OF = {"core": "jointbench", "sims": "jointbench.sims", "estimators": "jointbench.estimators",
              "benchmarks": "jointbench.benchmarks"}
FOLDER_OF = {"core": "jointbench", "sims": "sims", "estimators": "estimators", "benchmarks": "benchmarks"}
FORBIDDEN = {
    "core": {"sims", "estimators", "benchmarks", "api", "cli"},
    "sims": {"estimators", "benchmarks", "api", "cli"},
    "estimators": {"sims", "benchmarks", "api", "cli"},
    "benchmarks": {"api", "cli"},          # the harness: the API and the CLI sit on it, never the reverse
    "api": {"cli"},
}
#: the API room (a module of the jointbench folder) and the command-line modules (in the benchmarks folder)
API_MODULES = {"jointbench.api"}
CLI_MODULES = {"jointbench.benchmarks.cli", "jointbench.benchmarks.cli_history", "jointbench.benchmarks.__main__",
               "jointbench.benchmarks.recordings.cli"}
CODE = sorted(FOLDER_OF.values()) + ["tests", "docs", "examples", "configs"]


def room_of(module: str) -> str | None:
    """The room a module name belongs to (None: not the project's)."""
    parts = module.split(".")
    if parts[0] != "jointbench":
        return None
    if module in API_MODULES:
        return "api"
    if module in CLI_MODULES:
        return "cli"
    if len(parts) > 1 and parts[1] in ("sims", "estimators", "benchmarks"):
        return parts[1]
    return "core"


def _package_of_file(path: Path) -> str:
    """The installed package a file under one of the code folders belongs to."""
    rel = path.relative_to(REPO).with_suffix("").parts
    room = next((r for r, f in FOLDER_OF.items() if f == rel[0]), None)
    if room is None:
        return ".".join(rel[:-1])
    return ".".join([PACKAGE_OF[room], *rel[1:-1]])


def imported_modules(path: Path) -> set[str]:
    """Every module ``path`` imports, in full (``from a.b import c`` gives ``a.b`` and ``a.b.c``: c may be
    a module); relative imports resolved against the file's package."""
    tree = ast.parse(path.read_text(), str(path))
    package = _package_of_file(path)
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{parent}.{base}" if base else parent
            out.add(base)
            out |= {f"{base}.{a.name}" for a in node.names}
    return out


def imported_rooms(path: Path) -> set[str]:
    return {r for m in imported_modules(path) if m and (r := room_of(m)) is not None}


def files_of(room: str) -> list[Path]:
    """The source files of a room."""
    every = [f for folder in FOLDER_OF.values() for f in sorted((REPO / folder).rglob("*.py"))]
    return [f for f in every if room_of(_module_of_file(f)) == room]


def _module_of_file(path: Path) -> str:
    package = _package_of_file(path)
    return package if path.name == "__init__.py" else f"{package}.{path.stem}"


@pytest.mark.parametrize("room", sorted(FORBIDDEN))
def test_layering(room):
    bad = []
    assert files_of(room), room
    for f in files_of(room):
        hit = imported_rooms(f) & FORBIDDEN[room]
        if hit:
            bad.append(f"{f.relative_to(REPO)} imports {sorted(hit)}")
    assert not bad, "\n".join(bad)


def test_recordings_need_only_the_core():
    """benchmarks/recordings (``jointbench estimate``) imports jointbench and estimators, nothing else of the
    project: not the rest of benchmarks (harness, protocols, figures, config), not sims; its command-line
    module also uses the API (``jointbench.api.fit``), the library modules do not."""
    room = REPO / "benchmarks" / "recordings"
    files = sorted(room.rglob("*.py"))
    assert files, room
    inside = ("jointbench.benchmarks", "jointbench.benchmarks.recordings")  # the package itself and this room

    def outside(m: str, cli: bool) -> bool:
        room = room_of(m)
        return (room == "sims" or (room == "api" and not cli)
                or (room == "benchmarks" and m not in inside and not m.startswith(inside[1] + ".")))

    bad = []
    for f in files:
        cli = room_of(_module_of_file(f)) == "cli"   # recordings/cli.py wraps jointbench.api.fit
        hit = sorted(m for m in imported_modules(f) if outside(m, cli))
        if hit:
            bad.append(f"{f.relative_to(REPO)} imports {hit}")
    assert not bad, "\n".join(bad)


def test_runtime_never_reads_shared():
    """../shared exists only beside developers' checkouts: code outside tests must not refer to it."""
    for pkg in FOLDER_OF.values():
        for f in (REPO / pkg).rglob("*.py"):
            assert "shared/data" not in f.read_text(), f"{f} refers to ../shared"


def test_modules_stay_small():
    big = [f"{f.relative_to(REPO)}: {n}" for pkg in FOLDER_OF.values()
           for f in (REPO / pkg).rglob("*.py") if (n := len(f.read_text().splitlines())) > 500]
    assert not big, big


def test_estimator_index_matches_the_registry():
    """The registry knows the estimators from their source (``jointbench estimate --list`` imports none
    of them); importing every module must register exactly those names, tags and summaries."""
    from jointbench import estimators

    known = {n: (estimators.REGISTRY.tags(n), estimators.REGISTRY.summary(n)) for n in estimators.REGISTRY.names()}
    estimators.import_all()
    loaded = {n: (estimators.REGISTRY._tags[n], (estimators.REGISTRY._items[n].__doc__ or "").strip().splitlines()[0])
              for n in estimators.REGISTRY._items}
    assert known == loaded


def _first_line(obj) -> str:
    doc = (getattr(obj, "__doc__", None) or "").strip().splitlines()
    return doc[0] if doc else ""


def test_protocol_and_figure_indexes_match_the_registries():
    """Protocols and figure makers are registered lazily too (the study module imports none of them):
    the names, tags and summaries read from their source are exactly what importing every module
    registers."""
    from jointbench.benchmarks import figures, protocols

    for package, doc_of in ((protocols, lambda p: p.fn), (figures, lambda f: f)):
        reg = package.REGISTRY
        known = {n: (reg.tags(n), reg.summary(n) if n not in reg._items else _first_line(doc_of(reg._items[n])))
                 for n in reg.names()}
        package.import_all()
        loaded = {n: (reg._tags[n], _first_line(doc_of(reg._items[n]))) for n in reg._items}
        assert known == loaded and len(known) > 5, package.__name__


def test_importing_the_study_module_loads_no_protocol_or_figure():
    """Lazy registration: ``jointbench list`` and a study's start pay for no protocol, figure or
    scipy.stats import (each was 0.5-0.7 CPU-s of every CLI process)."""
    code = ("import sys, jointbench.benchmarks.study, jointbench.benchmarks.cli as c; c.main(['list']); "
            "print(sorted(m for m in sys.modules if m.startswith(('jointbench.benchmarks.protocols.', "
            "'jointbench.benchmarks.figures.', 'scipy.stats'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"


BARE = re.compile(r"^\s*(?:import|from)\s+(sims|estimators|benchmarks)\b", re.M)


def test_the_api_room_is_above_the_harness_and_below_the_cli():
    """jointbench/api.py is its own room: the core files are the other modules of jointbench/, the harness
    never imports the API, the API never imports a command-line module, and the CLI wraps the API."""
    assert [f.name for f in files_of("api")] == ["api.py"]
    assert (REPO / "jointbench" / "api.py") not in files_of("core")
    assert "api" in imported_rooms(REPO / "benchmarks" / "recordings" / "cli.py")
    assert room_of("jointbench.benchmarks.study") == "benchmarks" and room_of("jointbench.benchmarks.cli") == "cli"


def test_importing_the_api_and_the_cli_sets_no_blas_threads():
    """Importing jointbench.api or the CLI module leaves the caller's environment and BLAS pools alone."""
    import subprocess
    import sys

    code = ("import os, json; before = dict(os.environ); import numpy; from threadpoolctl import threadpool_info; "
            "n0 = [p['num_threads'] for p in threadpool_info()]; "
            "import jointbench.api, jointbench.benchmarks.cli, jointbench.benchmarks.recordings.cli; "
            "n1 = [p['num_threads'] for p in threadpool_info()]; "
            "print(json.dumps([sorted(set(os.environ.items()) ^ set(before.items())), n0 == n1]))")
    env = {k: v for k, v in __import__("os").environ.items() if not k.endswith("_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env).stdout
    assert out.strip() == "[[], true]", out


def test_no_bare_top_level_imports():
    """One installed namespace: ``import sims`` (or estimators, benchmarks) works only from the checkout's
    own folder and would load a second copy of every module beside ``jointbench.sims``; every import
    names ``jointbench.``."""
    bad = []
    for folder in CODE:
        for f in sorted((REPO / folder).rglob("*.py")):
            bad += [f"{f.relative_to(REPO)}: {m.group(0).strip()}" for m in BARE.finditer(f.read_text())]
    assert not bad, "\n".join(bad)


def test_a_bare_import_is_caught():
    """The check above is not vacuous: it flags the import forms the move rewrote."""
    for line in ("import sims", "from estimators import make", "    import benchmarks.study as s",
                 "from sims.profile import X"):
        assert BARE.search(line), line
    for line in ("from jointbench import sims", "import jointbench.sims as sims", "x = 'benchmarks'"):
        assert not BARE.search(line), line


def test_the_wheel_installs_one_top_level_package():
    """pyproject.toml installs every package under ``jointbench`` and maps each code folder into it."""
    cfg = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert all(p == "jointbench" or p.startswith("jointbench.") for p in cfg["packages"]), cfg["packages"]
    dirs = cfg["package-dir"]
    for room, folder in FOLDER_OF.items():
        assert dirs[PACKAGE_OF[room]] == folder
    # every sub-package of a code folder is listed (a new folder would otherwise be left out of the wheel)
    for room, folder in FOLDER_OF.items():
        for init in (REPO / folder).rglob("__init__.py"):
            sub = ".".join([PACKAGE_OF[room], *init.parent.relative_to(REPO / folder).parts])
            assert sub in cfg["packages"], f"{init.parent} is not installed: add {sub!r} to pyproject's packages"
