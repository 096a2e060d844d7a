"""What a number depends on besides its case: the code that computes it, the libraries, the machine.

The code hash follows **meaning**: a module counts by its parsed code (its syntax tree without
docstrings; comments and layout are never in it, :func:`module_hash`), so editing a comment, a
docstring or a blank line changes no key. It covers the **import closure** (:func:`closure`) of what
computes a case, found statically: follow every import of a project module (``import a.b``, ``from a
import b``, relative imports, and imports inside functions); a package whose ``__init__`` calls
``import_submodules`` at module level (the registries of joint models, perturbations, backends) brings
in all its modules. Protocols and estimators are registered lazily (a module is imported when its name
is first used), so each case's key (:func:`case_code_hash`) covers the shared closure of
:mod:`jointbench.benchmarks.harness.case` (the core, ``sims/``, the protocol and estimator base
modules) plus the closures of *its* protocol's and estimators' modules
(:meth:`~jointbench.benchmarks.harness.case.Case.code_modules`): a change of one estimator recomputes
only the cases that use it. Never in a key: the config loader, tables, figures, reports, CLI or this
harness, so editing a caption or a report recomputes nothing. Tests check that every project module a
case actually loads is in its closure, and that a comment edit keeps every key.

Modules are hashed by their installed names (``jointbench.estimators.kbr``), not their paths, so a
checkout and an installed wheel of the same code give the same hash.

Library versions that can change a number: Python, numpy, scipy (and mujoco when installed), with the
processor architecture. The git state (commit, dirty flag) is recorded with each run but is not part of
the cache key (the code hash is the precise form of it).
"""
from __future__ import annotations

import ast
import functools
import hashlib
import importlib.metadata
import importlib.util
import json
import os
import platform
import socket
import subprocess
import sys
from pathlib import Path

#: the repository's code folders and the installed packages they are (pyproject.toml's package-dir)
PACKAGE_DIRS = {"jointbench": "jointbench", "jointbench.sims": "sims", "jointbench.estimators": "estimators",
                "jointbench.benchmarks": "benchmarks"}
PACKAGES = tuple(PACKAGE_DIRS.values())


@functools.lru_cache(maxsize=None)
def package_root(package: str) -> Path | None:
    """The folder package ``package`` (a key of :data:`PACKAGE_DIRS`) is imported from: the checkout's
    folder (``sims/``) in a checkout or an editable install, ``site-packages/jointbench/sims`` from a wheel."""
    spec = importlib.util.find_spec(package)
    locations = list(spec.submodule_search_locations or []) if spec is not None else []
    return Path(locations[0]).resolve() if locations else None


def source_checkout() -> Path | None:
    """The git checkout the running code comes from (a checkout, or an editable install of one); None when
    it runs from an installed wheel. Found from where the code is, and used only to read (the git state):
    results go to ``./results`` or ``--out``."""
    root = package_root("jointbench")
    repo = root.parent if root is not None else None
    if repo is not None and (repo / "pyproject.toml").is_file() and all((repo / f).is_dir() for f in PACKAGES):
        return repo
    return None


#: the checkout of the running code (None: installed from a wheel)
REPO = source_checkout()
CASE_ENTRY = "jointbench.benchmarks.harness.case"
#: libraries whose version is part of every cache key (their numerics are in every result; numba and llvmlite
#: compile the loops of jointbench.core.compiled's users: another compiler may round otherwise)
KEY_LIBRARIES = ("numpy", "scipy", "numba", "llvmlite", "mujoco")
#: libraries recorded with each run (history), besides the key libraries
RECORDED_LIBRARIES = ("pandas", "matplotlib", "pyyaml", "jinja2", "threadpoolctl", "dm-control", "tqdm")
#: the tracked paths whose uncommitted changes can change a result; generated outputs (results/, the
#: README's status block) cannot: `make reproduce` rewrites them between studies
RESULT_INPUTS = PACKAGES + ("configs", "pyproject.toml")


@functools.lru_cache(maxsize=None)
def _module_file(name: str) -> Path | None:
    parts = name.split(".")
    for n in range(min(2, len(parts)), 0, -1):   # jointbench.sims.x lives in sims/, jointbench.x in jointbench/
        folder = PACKAGE_DIRS.get(".".join(parts[:n]))
        if folder is not None:
            break
    else:
        return None
    root = package_root(".".join(parts[:n]))
    if root is None:
        return None
    base = root.joinpath(*parts[n:])
    if (base / "__init__.py").is_file():
        return base / "__init__.py"
    if base.with_suffix(".py").is_file():
        return base.with_suffix(".py")
    return None


#: Version of what :func:`_facts` computes (bump it when the meaning hash or the import facts change):
#: part of the memo's file name, so an older memo is never read.
FACTS_FORMAT = 1


def _memo_file() -> Path:
    """Where the facts of module sources are remembered between processes (a user cache, like
    matplotlib's): ``$XDG_CACHE_HOME/jointbench`` or ``~/.cache/jointbench``, one file per Python version
    (syntax trees differ between versions)."""
    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return root / "jointbench" / f"code-facts-{FACTS_FORMAT}-py{sys.version_info[0]}{sys.version_info[1]}.json"


_MEMO: dict = {}
_MEMO_STATE = {"loaded": False, "dirty": False}


def _memo() -> dict:
    if not _MEMO_STATE["loaded"]:
        _MEMO_STATE["loaded"] = True
        try:
            data = json.loads(_memo_file().read_text())
            if isinstance(data, dict):
                _MEMO.update(data)
        except (OSError, ValueError):
            pass                       # absent or unreadable: computed again, written anew
    return _MEMO


def _save_memo(keep: int = 4000) -> None:
    """Write the memo when it learnt something (the newest ``keep`` entries); never fails a run."""
    if not _MEMO_STATE["dirty"]:
        return
    _MEMO_STATE["dirty"] = False
    items = list(_MEMO.items())[-keep:]
    try:
        from jointbench.core.files import atomic_write

        text = json.dumps(dict(items), separators=(",", ":"))
        atomic_write(_memo_file(), lambda t: Path(t).write_text(text))
    except OSError:
        pass                           # a read-only home: hashing still works, it is only slower


@functools.lru_cache(maxsize=None)
def _facts(path: Path) -> dict:
    """What the source at ``path`` means and imports: ``hash`` (:func:`module_hash`), ``imports`` (each
    import statement as ``[level, module, names]``) and ``eager`` (an ``import_submodules`` call at
    module level). Keyed by the SHA-256 of the file's bytes, remembered between processes
    (:func:`_memo_file`): parsing every module of the closure cost 0.2-0.4 CPU-s a process."""
    raw = Path(path).read_bytes()
    key = hashlib.sha256(raw).hexdigest()
    memo = _memo()
    hit = memo.pop(key, None)
    if not (isinstance(hit, dict) and {"hash", "imports", "eager"} <= set(hit)):
        tree = ast.parse(raw.decode("utf-8"), str(path))
        imports = []
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                imports += [[0, a.name, None] for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                imports.append([node.level, node.module or "", [a.name for a in node.names]])
        eager = any(isinstance(st, ast.Expr) and isinstance(st.value, ast.Call)
                    and getattr(st.value.func, "id", None) == "import_submodules" for st in tree.body)
        _strip_docstrings(tree.body)
        hit = {"hash": hashlib.sha256(ast.dump(tree).encode()).hexdigest(), "imports": imports, "eager": eager}
        _MEMO_STATE["dirty"] = True
    memo[key] = hit                    # the newest last (what :func:`_save_memo` keeps)
    return hit


@functools.lru_cache(maxsize=None)
def _imports(name: str, path: Path) -> frozenset[str]:
    """Project modules that module ``name`` (file ``path``) may import."""
    facts = _facts(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: set[str] = set()

    def add(mod: str) -> None:
        bits = mod.split(".")
        for i in range(1, len(bits) + 1):        # importing a.b.c runs a, a.b and a.b.c
            out.add(".".join(bits[:i]))

    for level, module, names in facts["imports"]:
        if names is None:                        # import a.b
            add(module)
            continue
        if level:
            base = package.split(".")
            base = base[: len(base) - level + 1]
            module = ".".join(base + ([module] if module else []))
        add(module)
        for a in names:                          # "from pkg import submodule"
            out.add(f"{module}.{a}")
    if path.name == "__init__.py" and facts["eager"]:   # import_submodules(...) run on import
        for sub in sorted(path.parent.glob("*.py")):
            if sub.name != "__init__.py":
                out.add(f"{name}.{sub.stem}")
        for sub in sorted(path.parent.glob("*/__init__.py")):
            out.add(f"{name}.{sub.parent.name}")
    return frozenset(m for m in out if _module_file(m) is not None)


def _strip_docstrings(stmts: list) -> None:
    """Drop, in place, every statement that is a bare string (docstrings of modules, classes and
    functions, and string "comments"): such a statement computes nothing. Only statements hold bodies,
    so only they are visited."""
    stmts[:] = [st for st in stmts if not (isinstance(st, ast.Expr) and isinstance(st.value, ast.Constant)
                                           and isinstance(st.value.value, str))]
    for st in stmts:
        for field in ("body", "orelse", "finalbody", "handlers", "cases"):
            sub = getattr(st, field, None)
            if isinstance(sub, list) and sub:
                if isinstance(sub[0], ast.stmt):
                    _strip_docstrings(sub)
                else:                              # except handlers, match cases: their bodies
                    for h in sub:
                        _strip_docstrings(h.body)


def module_hash(path: Path) -> str:
    """SHA-256 of what the module at ``path`` means: the dump of its syntax tree without docstrings
    (comments, blank lines and line numbers are not in a tree), so only an edit of code changes it."""
    return _facts(Path(path))["hash"]


@functools.lru_cache(maxsize=None)
def _closure_of(entry: str) -> tuple[tuple[str, Path], ...]:
    seen: dict[str, Path] = {}
    bits = entry.split(".")
    todo = [".".join(bits[:i]) for i in range(1, len(bits) + 1)]   # its packages run first
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        path = _module_file(name)
        if path is None:
            continue
        seen[name] = path
        for module in _imports(name, path):      # an imported module, and the packages it runs first
            bits = module.split(".")
            todo.extend(p for p in (".".join(bits[:i]) for i in range(1, len(bits) + 1)) if p not in seen)
    return tuple(sorted(seen.items()))


def closure(entry_modules) -> dict[str, Path]:
    """Project modules (name -> file) that importing every module of ``entry_modules`` can run."""
    out: dict[str, Path] = {}
    for entry in entry_modules:
        out.update(_closure_of(entry))
    return dict(sorted(out.items()))


def hash_modules(modules: dict[str, Path]) -> str:
    """One hash of named modules (:func:`module_hash` of each, by installed name)."""
    h = hashlib.sha256()
    for name, path in sorted(modules.items()):
        h.update(f"{name}\0{module_hash(path)}\0".encode())
    _save_memo()
    return h.hexdigest()[:20]


def case_modules(*entries: str) -> tuple[Path, ...]:
    """Files of the closure of the case module and ``entries`` (a case's protocol and estimator modules,
    :meth:`~jointbench.benchmarks.harness.case.Case.code_modules`), sorted."""
    return tuple(sorted(set(closure((CASE_ENTRY, *entries)).values())))


@functools.lru_cache(maxsize=None)
def case_code_hash(entries: tuple[str, ...] = ()) -> str:
    """The code part of a case's key: :func:`hash_modules` of the closure of the case module and
    ``entries`` (its protocol's and estimators' modules)."""
    return hash_modules(closure((CASE_ENTRY, *entries)))


def _registered_modules() -> tuple[str, ...]:
    from jointbench import estimators
    from jointbench.benchmarks import protocols

    return tuple(sorted({m for reg in (estimators.REGISTRY, protocols.REGISTRY) for n in reg.names()
                         if (m := reg.module_of(n))}))


@functools.lru_cache(maxsize=None)
def code_hash() -> str:
    """Hash of all the code any case can run (the case module and every registered protocol and
    estimator): recorded with each run and checked on workers."""
    return case_code_hash(_registered_modules())


def forget() -> None:
    """Forget every cached hash and closure (after the files were edited in this process, e.g. a test)."""
    for f in (_module_file, _facts, _imports, _closure_of, case_code_hash, code_hash):
        f.cache_clear()


def repo_path(path: Path) -> str:
    """A source file's path in the repository layout (``sims/backend.py``), wherever it is installed: the
    checkout and a wheel of the same source hash alike."""
    path = Path(path).resolve()
    best = None
    for pkg, folder in PACKAGE_DIRS.items():
        root = package_root(pkg)
        if root is not None and root in path.parents and (best is None or len(root.parts) > len(best[0].parts)):
            best = (root, folder)
    if best is None:
        return path.name
    return f"{best[1]}/{path.relative_to(best[0]).as_posix()}"


# --- outside estimators (plugins): their source enters the key of the cases that use them ---------------
def plugin_hash(estimator_names) -> dict[str, str]:
    """``{estimator: "<distribution>==<version> <source hash>"}`` for the estimators of ``estimator_names``
    whose code lives outside jointbench (plugins, :mod:`jointbench.core.plugins`; :func:`plugin_text`): in
    the key of their cases (an edit of their code recomputes them, and only them), in every tidy row of
    those cases (column ``plugin``), the report and the run history (``jointbench diff`` names a plugin
    that changed). Built-in estimators are covered by :func:`code_hash` and give nothing here."""
    from jointbench import estimators

    out = {}
    for name in sorted(estimator_names):
        module = estimators.REGISTRY.get(name).__module__
        if module.split(".")[0] != "jointbench":
            out[name] = plugin_text(module)
    return out


@functools.lru_cache(maxsize=None)
def plugin_text(module: str) -> str:
    """``"<distribution>==<version> <source hash>"`` of the plugin that module ``module`` belongs to: the
    installed distribution and its version, or (a plugin imported from a file or folder) the top-level
    module's name and its ``__version__`` ('-' when it has none), and :func:`plugin_source_hash`."""
    from jointbench.core import plugins

    dist, version = plugins.distribution_of(module)
    top = module.split(".")[0]
    if not version:
        version = str(getattr(sys.modules.get(top), "__version__", "") or "")
    try:
        source = plugin_source_hash(module)
    except ImportError:              # loaded once, its module since gone (removed, or its folder off sys.path)
        source = "(source not found)"
    return f"{dist or top}=={version or '-'} {source}"


def plugin_source_hash(module: str) -> str:
    """Hash (20 hex digits) of what the plugin's code means: every source file of the top-level package of
    ``module`` (:func:`jointbench.core.plugins.source_files`, subpackages included) by its name relative to
    the package and its :func:`module_hash` (syntax tree without docstrings), as for jointbench's own
    modules: editing a comment, a docstring or a blank line of a plugin changes no key (docs/harness.md). A
    file that does not parse (never imported) counts by its bytes."""
    from jointbench.core import plugins

    base, files = plugins.source_files(module)
    h = hashlib.sha256()
    for p in files:
        try:
            meaning = module_hash(p)
        except (SyntaxError, ValueError):             # ValueError: not UTF-8 text, or a NUL byte
            meaning = "bytes " + hashlib.sha256(p.read_bytes()).hexdigest()
        h.update(f"{p.relative_to(base).as_posix()}\0{meaning}\0".encode())
    _save_memo()
    return h.hexdigest()[:20]


def plugin_requirements(estimator_names) -> dict[str, str]:
    """What a worker must import to run these estimators: ``{top-level module: folder}`` of the plugins."""
    from jointbench import estimators
    from jointbench.core import plugins

    mods = {estimators.REGISTRY.get(n).__module__ for n in estimator_names}
    return dict(plugins.requirement(m) for m in sorted(mods) if m.split(".")[0] != "jointbench")


def _version(dist: str) -> str | None:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


@functools.lru_cache(maxsize=None)
def key_environment() -> dict:
    """Python and library versions and the processor architecture: part of every cache key."""
    env = {"python": platform.python_version(), "machine": platform.machine()}
    for lib in KEY_LIBRARIES:
        v = _version(lib)
        if v is not None:
            env[lib] = v
    return env


def environment() -> dict:
    """Everything recorded about where a run ran (history)."""
    env = dict(key_environment())
    env.update({"implementation": platform.python_implementation(), "system": platform.system(),
                "release": platform.release(), "host": socket.gethostname(), "cpus": os.cpu_count(),
                "executable": sys.executable})
    env["packages"] = {lib: v for lib in KEY_LIBRARIES + RECORDED_LIBRARIES if (v := _version(lib))}
    from jointbench.core import plugins

    loaded = plugins.loaded()
    if loaded:          # outside estimators in this process (a run records those its cases use: history)
        env["plugins"] = {p.module: plugin_text(p.module) for p in loaded}
    return env


def canonical(obj) -> str:
    """A stable JSON text of ``obj`` (sorted keys; non-JSON values by ``str``).

    The same text for ``obj`` and for ``obj`` read back from its JSON: the object goes through JSON once
    before the keys are sorted, so a mapping with number keys (``{5: .., 10: ..}``, sorted 5 < 10) and its
    stored copy (``{"5": .., "10": ..}``, sorted "10" < "5") give one text. Without it a cache entry's
    material never hashed to its key again and such cases were always recomputed."""
    return canonical_json(json.loads(json.dumps(obj, default=str, allow_nan=True)))


def canonical_json(plain) -> str:
    """:func:`canonical` of an object already read from JSON (string keys, JSON values only)."""
    return json.dumps(plain, sort_keys=True, separators=(",", ":"), allow_nan=True)


def sha(obj, n: int = 32) -> str:
    return sha_text(canonical(obj), n)


def sha_text(text: str, n: int = 32) -> str:
    """The first ``n`` hex digits of the SHA-256 of ``text`` (:func:`sha` of what ``text`` is canonical of)."""
    return hashlib.sha256(text.encode()).hexdigest()[:n]


def _git(*args: str, cwd: Path | None = None) -> str | None:
    if cwd is None and REPO is None:
        return None
    try:
        out = subprocess.run(["git", *args], cwd=REPO if cwd is None else cwd, capture_output=True,
                             text=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() if out.returncode == 0 else None


def git_state(repo: Path | None = None) -> tuple[str, bool]:
    """(short commit, dirty). Dirty means uncommitted changes to tracked files that can change a result
    (:data:`RESULT_INPUTS`; regenerated reports and the README's status block do not count) or untracked
    files in the code packages or configs."""
    repo = REPO if repo is None else repo
    if repo is None:                      # installed from a wheel: no git, the package's version instead
        return installed_version(), False
    commit = _git("rev-parse", "--short", "HEAD", cwd=repo)
    if commit is None:
        return "unknown", False
    tracked = _git("status", "--porcelain", "--untracked-files=no", "--", *RESULT_INPUTS, cwd=repo) or ""
    untracked = _git("status", "--porcelain", "--untracked-files=all", "--", *PACKAGES, "configs",
                     cwd=repo) or ""
    dirty = bool(tracked) or any(line.startswith("??") for line in untracked.splitlines())
    return commit, dirty


def installed_version() -> str:
    """``v<version>`` of the installed jointbench: the stamp of results computed from a wheel."""
    return f"v{_version('jointbench') or 'unknown'}"


def git_commit(repo: Path | None = None) -> str:
    """``<commit>`` or ``<commit>-dirty`` (the stamp of reports and tidy rows); 'unknown' in a checkout
    without git, ``v<version>`` from an installed wheel."""
    commit, dirty = git_state(repo)
    return commit + ("-dirty" if dirty else "")
