"""Estimators from outside the package: plugins.

A method developer keeps an estimator in a package of their own and registers it with
``@jointbench.estimators.register("name")``. JointBench finds it three ways:

- an **entry point** of group ``jointbench.estimators`` in the plugin's ``pyproject.toml``::

      [project.entry-points."jointbench.estimators"]
      my_method = "my_package.my_module"        # the module that registers it (or module:Class)

  installed plugins are imported when the estimator registry is first asked for a name
  (``jointbench estimate --list`` shows them);
- ``--plugin MODULE`` on the command line (a module name, or the path of a ``.py`` file or a package folder);
- a study's ``plugins:`` key (the same, paths relative to the study file).

:func:`load` imports one and records it; the harness hands every worker what it must import
(:func:`requirement`, :func:`ensure`) so that a plugin estimator runs on every executor (the process pool,
serially, on Dask), and the hash of what the plugin's code means (:func:`source_files`, hashed by
:func:`jointbench.benchmarks.harness.fingerprint.plugin_source_hash` like jointbench's own modules: comments
and docstrings count for nothing) enters the case cache key (an edited plugin recomputes its cases:
:func:`jointbench.benchmarks.harness.fingerprint.plugin_hash`).
"""
from __future__ import annotations

import dataclasses
import functools
import importlib
import importlib.metadata
import sys
from pathlib import Path

from jointbench.core.errors import ConfigError, JointBenchError

#: the entry-point group of outside estimators
ESTIMATORS_GROUP = "jointbench.estimators"


@dataclasses.dataclass(frozen=True)
class Plugin:
    """A loaded plugin module: ``spec`` is how to load it again (in a worker)."""

    spec: str              # module name, or the absolute path of its .py file / package folder
    module: str            # the imported module's name
    distribution: str      # the installed distribution it comes from ('' when none: a file or folder)
    version: str


_LOADED: dict[str, Plugin] = {}


def _from_path(ref: str, where: str) -> tuple[str, str]:
    """(module name, folder to put on sys.path) of a .py file or a package folder."""
    path = Path(ref).expanduser().resolve()
    if path.is_file() and path.suffix == ".py":
        return path.stem, str(path.parent)
    if path.is_dir() and (path / "__init__.py").is_file():
        return path.name, str(path.parent)
    raise ConfigError(f"{where}: plugin {ref!r}: not a .py file or a package folder (one with __init__.py)")


def load(ref: str, where: str = "--plugin") -> Plugin:
    """Import plugin ``ref`` (a module name, or the path of a ``.py`` file or package folder) once.

    Raises
    ------
    ConfigError
        No such module or file, or its import failed (the message names ``where``, the plugin and the
        error).
    """
    ref = str(ref).strip()
    is_path = ref.endswith(".py") or "/" in ref or Path(ref).is_dir()
    spec = str(Path(ref).expanduser().resolve()) if is_path else ref
    if spec in _LOADED:
        return _LOADED[spec]
    name, folder = _from_path(ref, where) if is_path else (ref, None)
    if folder is not None:
        old = sys.modules.get(name)
        if old is not None and Path(getattr(old, "__file__", "") or "").resolve().parent not in (
                Path(folder), Path(folder) / name):
            raise ConfigError(f"{where}: plugin {ref!r}: a module named {name!r} is already imported from "
                              f"{getattr(old, '__file__', '?')}; rename the plugin")
        if folder not in sys.path:
            sys.path.append(folder)     # appended: a yaml.py beside the plugin must not replace PyYAML
    try:
        module = importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name != name.split(".")[0] and exc.name != name:
            raise ConfigError(f"{where}: plugin {ref!r} failed to import: ModuleNotFoundError: {exc}") from None
        raise ConfigError(f"{where}: plugin {ref!r}: no module named {name!r}; install it (pip install ...) or "
                          f"give the path of its .py file") from None
    except JointBenchError as exc:       # e.g. a name taken from a built-in (jointbench.core.registry)
        raise ConfigError(f"{where}: plugin {ref!r}: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - any error of outside code becomes one line naming it
        raise ConfigError(f"{where}: plugin {ref!r} failed to import: {type(exc).__name__}: {exc}") from None
    if folder is not None:
        _check_origin(module, Path(folder), ref, where)
    dist = distribution_of(module.__name__)
    plugin = Plugin(spec, module.__name__, dist[0], dist[1])
    _LOADED[spec] = plugin
    return plugin


def _check_origin(module, folder: Path, ref: str, where: str) -> None:
    """Refuse a plugin path whose name an installed module answers to (the plugin folder is searched after
    every installed one, so ``numpy.py`` would import numpy, not the plugin)."""
    here = Path(getattr(module, "__file__", "") or "").resolve()
    if here.parent not in (folder, folder / module.__name__.split(".")[0]):
        raise ConfigError(f"{where}: plugin {ref!r}: the name {module.__name__!r} is taken by the installed "
                          f"module at {here}; rename the plugin")


def loaded() -> list[Plugin]:
    """The plugins loaded in this process (by :func:`load` and from entry points)."""
    return list(_LOADED.values())


@functools.lru_cache(maxsize=None)
def _distributions() -> dict[str, list[str]]:
    return dict(importlib.metadata.packages_distributions())


@functools.lru_cache(maxsize=None)
def distribution_of(module: str) -> tuple[str, str]:
    """(distribution, version) that installs top-level module ``module`` ('', '' when none does)."""
    top = module.split(".")[0]
    for dist in _distributions().get(top, []):
        try:
            return dist, importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            continue
    return "", ""


def _top(module: str):
    top = module.split(".")[0]
    return sys.modules.get(top) or importlib.import_module(top)


def source_files(module: str) -> tuple[Path, tuple[Path, ...]]:
    """(base folder, source files) of the top-level package (or module) of ``module``: every ``.py`` file
    under the package's folder, or the module's file."""
    top = _top(module)
    locations = list(getattr(top, "__path__", []) or [])
    if locations:
        base = Path(locations[0])
        return base, tuple(sorted(p for p in base.rglob("*.py") if "__pycache__" not in p.parts))
    file = Path(getattr(top, "__file__", "") or "")
    return file.parent, ((file,) if file.is_file() else ())


def requirement(module: str) -> tuple[str, str]:
    """(top-level module, folder it is imported from): what a worker needs to import ``module``'s code."""
    mod = _top(module)
    locations = list(getattr(mod, "__path__", []) or [])
    where = Path(locations[0]).parent if locations else Path(getattr(mod, "__file__", "") or ".").parent
    return mod.__name__, str(where)


def ensure(requirements: dict[str, str]) -> None:
    """In a worker: import each top-level module of ``requirements`` (name -> folder), the folder put on
    ``sys.path`` when the module is not importable otherwise."""
    for name, folder in requirements.items():
        if name in sys.modules:
            continue
        try:
            importlib.import_module(name)
        except ModuleNotFoundError:
            if folder not in sys.path:
                sys.path.append(folder)
            importlib.import_module(name)


_EP_DONE: set[str] = set()


def load_entry_points(group: str = ESTIMATORS_GROUP, warn=None) -> None:
    """Import the installed plugins of entry-point ``group`` (once per process). A plugin that fails to
    import is reported on stderr (naming it and its distribution) and skipped: one broken plugin must
    not take the others, or the built-in estimators, with it."""
    if group in _EP_DONE:
        return
    _EP_DONE.add(group)
    for ep in importlib.metadata.entry_points(group=group):
        dist = getattr(ep, "dist", None)
        label = f"{dist.name} {dist.version}" if dist is not None else "?"
        try:
            obj = ep.load()
        except Exception as exc:  # noqa: BLE001 - outside code: report, skip, go on
            (warn or _warn)(f"plugin {ep.name!r} ({label}, entry point {ep.value}) failed to import: "
                            f"{type(exc).__name__}: {exc}; its estimators are not available")
            continue
        module = obj.__name__ if isinstance(obj, type(sys)) else getattr(obj, "__module__", ep.module)
        _LOADED.setdefault(ep.module, Plugin(ep.module, module, dist.name if dist else "",
                                             dist.version if dist else ""))


def _warn(msg: str) -> None:
    print(f"jointbench: {msg}", file=sys.stderr)
