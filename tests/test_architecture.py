"""The floors of the house: every module imports only the floors beneath its own (and its own room).

One installed namespace, ``jointbench``; the repository's folders ``sims/``, ``estimators/`` and ``benchmarks/``
are its sub-packages ``jointbench.sims``, ``jointbench.estimators`` and ``jointbench.benchmarks``
(pyproject.toml's package-dir). From the ground up (:data:`FLOORS`):

1. ``core``: ``jointbench/core/`` (and the package's face, ``jointbench/__init__.py``, and the shipped configs);
2. ``sims`` and ``estimators``, side by side: neither imports the other (an estimator never knows how its
   data were made);
3. ``fitting``: ``jointbench/fitting/``, the user's fitting path (it needs no simulator: :data:`ALSO_FORBIDDEN`);
4. ``benchmarks``: the harness; and beside it ``testing``: ``jointbench/testing/``, the conformance kit (it
   simulates and fits, never imports the harness);
5. ``api``: ``jointbench/api.py``;
6. ``cli``: ``jointbench/cli/`` and ``jointbench/__main__.py``.

Every import counts, at the top of a module or inside a function, under ``TYPE_CHECKING`` or not: a
function-local import that climbs a floor is a climb all the same.
"""
import ast
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: the repository's code folders and the installed packages they are (pyproject.toml's package-dir)
PACKAGE_DIRS = {"jointbench": "jointbench", "sims": "jointbench.sims", "estimators": "jointbench.estimators",
                "benchmarks": "jointbench.benchmarks", "configs": "jointbench.configs"}
#: room -> (floor, the module names that make it: a name, or a package and everything under it)
ROOMS = {
    "core": (1, ("jointbench", "jointbench.core", "jointbench.configs")),
    "sims": (2, ("jointbench.sims",)),
    "estimators": (2, ("jointbench.estimators",)),
    "fitting": (3, ("jointbench.fitting",)),
    "benchmarks": (4, ("jointbench.benchmarks",)),
    "testing": (4, ("jointbench.testing",)),
    "api": (5, ("jointbench.api",)),
    "cli": (6, ("jointbench.cli", "jointbench.__main__")),
}
FLOORS = {room: floor for room, (floor, _) in ROOMS.items()}
#: rooms a room must not import although they lie beneath it
ALSO_FORBIDDEN = {"fitting": {"sims"}}
CODE = sorted(PACKAGE_DIRS) + ["tests", "docs", "examples", "tools"]


def room_of(module: str) -> str | None:
    """The room of a module name (the longest prefix that names one; ``jointbench`` alone is the core's face);
    None: not the project's."""
    best, length = None, -1
    for room, (_, names) in ROOMS.items():
        for n in names:
            exact_only = n == "jointbench"
            hit = module == n or (not exact_only and module.startswith(n + "."))
            if hit and len(n) > length:
                best, length = room, len(n)
    return best


def module_of_file(path: Path) -> str:
    """The installed module name of a file under one of the code folders."""
    rel = path.relative_to(REPO).with_suffix("").parts
    parts = PACKAGE_DIRS[rel[0]].split(".") + list(rel[1:])
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def import_statements(source: str, module: str, is_package: bool = False) -> list[tuple[str, list[str]]]:
    """Every import of ``source`` (the text of ``module``), anywhere in it: ``(module, [])`` for ``import a.b``,
    ``("a.b", ["c", "d"])`` for ``from a.b import c, d``; relative imports resolved against the module's
    package."""
    tree = ast.parse(source)
    package = module if is_package else module.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{parent}.{base}" if base else parent
            out.append((base, [a.name for a in node.names]))
    return out


def imported_modules(source: str, module: str, is_package: bool = False) -> set[str]:
    """Every module ``source`` (the text of ``module``) imports anywhere, in full (``from a.b import c`` gives
    ``a.b`` and ``a.b.c``: c may be a module); relative imports resolved against the module's package."""
    out = set()
    for base, names in import_statements(source, module, is_package):
        out.add(base)
        out |= {f"{base}.{n}" for n in names}
    return out


def code_files() -> list[Path]:
    return [f for folder in PACKAGE_DIRS for f in sorted((REPO / folder).rglob("*.py"))]


def climbs(module: str, imports: set[str]) -> list[str]:
    """The imports of ``module`` that break the floors: a floor above its own, another room of its own floor,
    or a room :data:`ALSO_FORBIDDEN` to it."""
    own = room_of(module)
    bad = []
    for m in sorted(imports):
        room = room_of(m)
        if room is None or room == own:
            continue
        if FLOORS[room] > FLOORS[own]:
            bad.append(f"{m} (floor {FLOORS[room]} {room}, above floor {FLOORS[own]} {own})")
        elif FLOORS[room] == FLOORS[own]:
            bad.append(f"{m} ({room}, beside {own} on floor {FLOORS[own]})")
        elif room in ALSO_FORBIDDEN.get(own, ()):
            bad.append(f"{m} ({room}: never imported by {own})")
    return bad


def test_every_module_has_a_floor():
    homeless = [str(f.relative_to(REPO)) for f in code_files() if room_of(module_of_file(f)) is None]
    assert not homeless, homeless


def test_the_floors_hold():
    """No module imports a floor above its own or a room beside it, function-local imports included."""
    bad = []
    for f in code_files():
        module = module_of_file(f)
        hits = climbs(module, imported_modules(f.read_text(), module, f.name == "__init__.py"))
        bad += [f"{f.relative_to(REPO)} imports {h}" for h in hits]
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("module, source", [
    ("jointbench.core.types", "def f():\n    from jointbench.benchmarks import study\n"),
    ("jointbench.estimators.kbr", "import jointbench.sims.experiment"),
    ("jointbench.fitting.read", "from jointbench.sims import simulate"),
    ("jointbench.benchmarks.study", "if TYPE_CHECKING:\n    from jointbench.api import Fit\n"),
    ("jointbench.api", "from jointbench.cli import main"),
    ("jointbench.sims.experiment", "from ..estimators import make"),
])
def test_a_climb_is_caught(module, source):
    """The floor test is not vacuous: each of these imports breaks a floor and is named."""
    assert climbs(module, imported_modules(source, module))


def test_the_floors_in_order():
    assert [r for r, _ in sorted(FLOORS.items(), key=lambda kv: kv[1])] == \
        ["core", "sims", "estimators", "fitting", "benchmarks", "testing", "api", "cli"]
    assert room_of("jointbench") == "core" and room_of("jointbench.api") == "api"
    assert room_of("jointbench.apis") is None and room_of("jointbench.benchmarks.study") == "benchmarks"
    assert room_of("jointbench.cli.estimate") == "cli" and room_of("numpy") is None


def test_runtime_never_reads_shared():
    """../shared exists only beside developers' checkouts: code outside tests must not refer to it."""
    for f in code_files():
        assert "shared/data" not in f.read_text(), f"{f} refers to ../shared"


def test_modules_stay_small():
    big = [f"{f.relative_to(REPO)}: {n}" for f in code_files() if (n := len(f.read_text().splitlines())) > 500]
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
    code = ("import sys, jointbench.benchmarks.study, jointbench.cli as c; c.main(['list']); "
            "print(sorted(m for m in sys.modules if m.startswith(('jointbench.benchmarks.protocols.', "
            "'jointbench.benchmarks.figures.', 'jointbench.benchmarks.compare.', 'scipy.stats')) "
            "or m.startswith('jointbench.benchmarks.studies.') and m.endswith(('.protocol', '.figures'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"


BARE = re.compile(r"^\s*(?:import|from)\s+(sims|estimators|benchmarks)\b", re.M)


def test_importing_the_api_and_the_cli_sets_no_blas_threads():
    """Importing jointbench.api or the CLI module leaves the caller's environment and BLAS pools alone."""
    import subprocess
    import sys

    code = ("import os, json; before = dict(os.environ); import numpy; from threadpoolctl import threadpool_info; "
            "n0 = [p['num_threads'] for p in threadpool_info()]; "
            "import jointbench.api, jointbench.cli; "
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
    for folder, package in PACKAGE_DIRS.items():
        assert dirs[package] == folder
    # every sub-package of a code folder is listed (a new folder would otherwise be left out of the wheel)
    for folder, package in PACKAGE_DIRS.items():
        for init in (REPO / folder).rglob("__init__.py"):
            sub = ".".join([package, *init.parent.relative_to(REPO / folder).parts])
            assert sub in cfg["packages"], f"{init.parent} is not installed: add {sub!r} to pyproject's packages"


def import_graph(sources: dict[str, tuple[str, bool]]) -> dict[str, set[str]]:
    """Module -> the modules among ``sources`` (``{module: (source, is_package)}``) it imports, anywhere in it
    (:func:`import_statements`): ``from P import x`` is an import of ``P.x`` when that is a module, else of
    ``P`` (x is a name ``P`` defines)."""
    graph = {}
    for module, (source, is_package) in sources.items():
        got = set()
        for base, names in import_statements(source, module, is_package):
            got |= {f"{base}.{n}" if f"{base}.{n}" in sources else base for n in names} if names else {base}
        graph[module] = {m for m in got if m in sources and m != module}
    return graph


def import_loops(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import loops of ``graph``: each set of modules that import one another, round (a strongly
    connected component of two modules or more, Tarjan's algorithm), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    loops = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            loop = []
            while not loop or loop[-1] != v:
                loop.append(stack.pop())
            if len(loop) > 1:
                loops.append(sorted(loop))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(loops)


def test_no_import_loops():
    """No two of the project's modules import each other, round about or directly, function-local imports
    included (a function-local import only hides a loop)."""
    sources = {module_of_file(f): (f.read_text(), f.name == "__init__.py") for f in code_files()}
    loops = import_loops(import_graph(sources))
    assert not loops, "\n".join(" <-> ".join(loop) for loop in loops)


def test_an_import_loop_is_caught():
    """The loop test is not vacuous: a loop through a function-local import is found (the one between the
    process pool and the Dask executor was such a loop); a package importing its own submodule by name,
    or a chain without a way back, is not a loop."""
    sources = {"p": ("", True),
               "p.pool": ("def make():\n    from p.dask import Dask\n", False),
               "p.dask": ("from p.pool import run_task\n", False),
               "p.cli": ("from p import dask, pool\n", False)}
    assert import_loops(import_graph(sources)) == [["p.dask", "p.pool"]]
    sources["p.dask"] = ("from p.workers import run_task\n", False)
    sources["p.workers"] = ("import os\n", False)
    assert import_loops(import_graph(sources)) == []


def private_imports(source: str, module: str, is_package: bool = False) -> list[str]:
    """``from M import _name`` in ``source`` where ``_name`` is not a module (a private helper of a package,
    ``from pkg import _mod``, is the package's own and allowed)."""
    return [f"{base}.{n}" for base, names in import_statements(source, module, is_package) for n in names
            if n.startswith("_") and not n.startswith("__") and f"{base}.{n}" not in MODULES]


MODULES = {module_of_file(f) for f in code_files()}


def test_no_private_name_is_imported_from_another_module():
    """A name that starts with ``_`` is its module's own: another module that needs it gets a public name in
    its home (private modules of a package, ``from pkg import _mod``, are the package's and allowed)."""
    bad = []
    for f in code_files():
        module = module_of_file(f)
        bad += [f"{f.relative_to(REPO)} imports {m}" for m in
                private_imports(f.read_text(), module, f.name == "__init__.py")]
    assert not bad, "\n".join(bad)


def test_a_private_import_is_caught():
    assert private_imports("from jointbench.core.schema import _number", "jointbench.sims.x") == \
        ["jointbench.core.schema._number"]
    assert private_imports("def f():\n    from .tables import _kind\n", "jointbench.benchmarks.checks") == \
        ["jointbench.benchmarks.tables._kind"]
    assert not private_imports("from jointbench.estimators import _reflex as rx", "jointbench.estimators.x")
