"""Name -> object registries filled by decorators (folder-as-registry, as in benchopt/dm_control)."""
from __future__ import annotations

import ast
import dataclasses
import importlib
import pkgutil
import re
import textwrap
from pathlib import Path
from typing import Callable, Generic, Iterable, TypeVar

from jointbench.core.errors import ConfigError

T = TypeVar("T")

#: a registered name: letters, digits and ``_``, not starting with a digit, in parts joined by ``.`` or ``-``
#: (``irf2_ls``, ``xu1998.track``); what a config file, ``-e`` or ``--list`` can name unambiguously
NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:[.-][A-Za-z0-9_]+)*")


def check_name(kind: str, name: object, module: str | None = None) -> str:
    """``name`` if it is a valid registered name (:data:`NAME`), else a one-line :class:`ConfigError` naming
    the ``kind`` and the ``module`` that registers it."""
    if isinstance(name, str) and NAME.fullmatch(name):
        return name
    by = f" (registered by {module})" if module else ""
    raise ConfigError(f"{kind} name {name!r}{by} is not a name: use letters, digits and '_' (not starting with a "
                      f"digit), parts joined by '.' or '-', e.g. 'my_method'")


class Registry(Generic[T]):
    """A tagged registry of named objects.

    Parameters
    ----------
    kind : str
        What the registry holds ("estimator", "joint model", ...), used in error messages.
    entry_points : str, optional
        An entry-point group whose installed plugins are imported before a name is first looked up or
        listed (:func:`jointbench.core.plugins.load_entry_points`).
    """

    def __init__(self, kind: str, entry_points: str | None = None):
        self.kind = kind
        self._items: dict[str, T] = {}
        self._tags: dict[str, frozenset[str]] = {}
        self._deferred: dict[str, Registration] = {}
        self._modules: dict[str, str] = {}
        self._entry_points = entry_points   # plugins' entry-point group, imported on the first look-up

    def _plugins(self) -> None:
        if self._entry_points is not None:
            from jointbench.core.plugins import load_entry_points

            load_entry_points(self._entry_points)

    def defer(self, registrations: Iterable["Registration"]) -> None:
        """Know these names before their modules are imported; :meth:`get` imports a module on first use.

        :meth:`names`, :meth:`tags` and :meth:`summary` answer from the registrations without importing
        anything (e.g. ``jointbench estimate --list``); the decorator still does the registering. A deferred
        name is owned by its module (the built-ins): no other module may register it (:meth:`register`).
        """
        for r in registrations:
            check_name(self.kind, r.name, r.module)
            other = self._deferred.get(r.name)
            if other is not None and other.module != r.module:
                raise ConfigError(f"{self.kind} {r.name!r} is registered by both {other.module} and {r.module}; "
                                  f"rename one")
            self._deferred.setdefault(r.name, r)

    def _load(self, name: str) -> None:
        r = self._deferred.get(name)
        if r is not None and name not in self._items:
            importlib.import_module(r.module)
            if name not in self._items:
                raise RuntimeError(f"{self.kind} {name!r}: module {r.module} did not register it")

    def register(self, name: str, *, tags: Iterable[str] = (), module: str | None = None) -> Callable[[T], T]:
        """Decorator registering ``obj`` under ``name``; ``module``: the module that defines it (default
        ``obj.__module__``).

        Names are owned: a name is registered by one module only, whatever the order of imports. A built-in's
        name (known to :meth:`defer` before any plugin is imported) cannot be taken by another module, and two
        modules (two plugins) registering one name is an error: a one-line :class:`ConfigError` naming both
        modules. The owner registering again (its module re-imported) replaces its own entry. ``name`` must be
        a :data:`NAME`.
        """

        def deco(obj: T) -> T:
            owner = module or getattr(obj, "__module__", None)
            check_name(self.kind, name, owner)
            self._check_owner(name, owner)
            self._items[name] = obj
            self._tags[name] = frozenset(tags)
            self._modules[name] = owner
            return obj

        return deco

    def _check_owner(self, name: str, module: str | None) -> None:
        """Refuse ``module`` registering ``name`` when another module owns it (the built-in or an earlier one)."""
        deferred = self._deferred.get(name)
        if deferred is not None and deferred.module != module:
            raise ConfigError(f"{self.kind} {name!r} of {module} clashes with the built-in {self.kind} {name!r} "
                              f"({deferred.module}); a plugin cannot replace a built-in: rename the plugin's")
        held = self._modules.get(name)
        if name in self._items and held != module:
            if str(held).startswith("jointbench."):
                raise ConfigError(f"{self.kind} {name!r} of {module} clashes with the built-in {self.kind} {name!r} "
                                  f"({held}); a plugin cannot replace a built-in: rename the plugin's")
            raise ConfigError(f"{self.kind} {name!r} is registered by both {held} and {module}; rename one of them")

    def get(self, name: str) -> T:
        """Return the object registered as ``name`` or raise a :class:`ConfigError` listing the names."""
        if name not in self._items and name not in self._deferred:
            self._plugins()
        self._load(name)
        try:
            return self._items[name]
        except KeyError:
            known = ", ".join(self.names()) or "(none)"
            raise ConfigError(f"unknown {self.kind} {name!r}; known: {known}") from None

    def names(self, tag: str | None = None) -> list[str]:
        """Sorted registered names, optionally only those carrying ``tag``."""
        self._plugins()
        every = set(self._items) | set(self._deferred)
        return sorted(n for n in every if tag is None or tag in self.tags(n))

    def tags(self, name: str) -> frozenset[str]:
        if name in self._items:
            return self._tags[name]
        if name in self._deferred:
            return self._deferred[name].tags
        self.get(name)
        return self._tags[name]

    def summary(self, name: str) -> str:
        """First line of the docstring of ``name`` (without importing it when deferred)."""
        if name in self._items:
            doc = (getattr(self._items[name], "__doc__", None) or "").strip().splitlines()
            return doc[0] if doc else ""
        if name in self._deferred:
            return self._deferred[name].summary
        self.get(name)
        return self.summary(name)

    def module_of(self, name: str) -> str | None:
        """The module that registers ``name`` (without importing it when deferred), or None if unknown."""
        if name in self._deferred:
            return self._deferred[name].module
        return self._modules.get(name)

    def __contains__(self, name: object) -> bool:
        if name not in self._items and name not in self._deferred:
            self._plugins()
        return name in self._items or name in self._deferred


@dataclasses.dataclass(frozen=True)
class Registration:
    """A ``@decorator("name", tags=...)`` class or function found in a module's source by
    :func:`scan_registrations`."""

    name: str
    module: str
    tags: frozenset[str]
    summary: str


def scan_registrations(package_name: str, package_path: Iterable[str],
                       decorator: str = "register") -> list[Registration]:
    """Registrations in the non-private modules of a package, read from their source (nothing imported):
    :func:`scan_modules` of the package's modules."""
    return scan_modules(package_modules(package_name, package_path), decorator)


def package_modules(package_name: str, package_path: Iterable[str]) -> list[tuple[str, Path]]:
    """``(module name, source file)`` of the non-private modules of a package (nothing imported)."""
    modules = []
    for info in pkgutil.iter_modules(list(package_path)):
        path = Path(info.module_finder.path) / f"{info.name}.py"
        if not info.name.startswith("_") and path.exists():
            modules.append((f"{package_name}.{info.name}", path))
    return modules


def scan_modules(modules: Iterable[tuple[str, Path]], decorator: str = "register") -> list[Registration]:
    """Registrations in the modules ``(module name, source file)``, read from their source (nothing imported).

    Finds classes and functions decorated ``@decorator("name", ...)`` or ``@decorator("name", ...,
    tags=(...))`` (name and tags literal strings; other arguments ignored), with the first line of their
    docstring. ``tests/test_architecture.py`` checks that it finds exactly what importing every module
    registers, for the estimators, protocols and figure makers.
    """
    out = []
    for module, path in modules:
        text = Path(path).read_text(encoding="utf-8")
        for node in _decorated_nodes(text, decorator, str(path)):
            for dec in node.decorator_list:
                if not (isinstance(dec, ast.Call) and getattr(dec.func, "id", getattr(dec.func, "attr", None))
                        == decorator and dec.args and isinstance(dec.args[0], ast.Constant)
                        and isinstance(dec.args[0].value, str)):
                    continue
                tags: frozenset[str] = frozenset()
                for kw in dec.keywords:
                    if kw.arg == "tags" and isinstance(kw.value, (ast.Tuple, ast.List)):
                        tags = frozenset(e.value for e in kw.value.elts if isinstance(e, ast.Constant))
                doc = (ast.get_docstring(node) or "").strip().splitlines()
                out.append(Registration(dec.args[0].value, module, tags, doc[0] if doc else ""))
    return out


def _decorated_nodes(text: str, decorator: str, where: str) -> list:
    """The class and function nodes of ``text`` that may carry ``@decorator(...)``: each decorated definition is
    parsed alone (its decorators, header and docstring, the body replaced by ``pass``), about 20 times faster
    than parsing the module (a CLI pays this at every start); the whole module is parsed when a snippet is not
    valid Python on its own."""
    lines = text.splitlines()
    starts = [i for i, line in enumerate(lines) if re.match(rf"\s*@(?:[\w.]+\.)?{re.escape(decorator)}\(", line)]
    nodes = []
    for i in starts:
        j = i
        while j < len(lines) and not re.match(r"\s*(?:async\s+)?(?:class|def)\s", lines[j]):
            j += 1
        k = j
        while k < len(lines) and not re.search(r":\s*(#.*)?$", lines[k]):
            k += 1
        body: list[str] = []                         # the docstring's lines, if any
        m = k + 1
        while m < len(lines) and not lines[m].strip():
            m += 1
        quote = lines[m].strip()[:3] if m < len(lines) else ""
        if quote in ('"""', "'''"):
            end = m
            if lines[m].strip().count(quote) < 2 or lines[m].strip() == quote:
                end = m + 1
                while end < len(lines) and quote not in lines[end]:
                    end += 1
            body = lines[m:end + 1]
        indent = re.match(r"\s*", lines[j] if j < len(lines) else "").group(0) + "    "
        snippet = textwrap.dedent("\n".join(lines[i:k + 1] + body + [indent + "pass"]))
        try:
            tree = ast.parse(snippet)
        except SyntaxError:
            tree = None
        if tree is None or not tree.body or not isinstance(tree.body[0], (ast.ClassDef, ast.FunctionDef)):
            tree = ast.parse(text, where)          # the slow path, exact
            return [n for n in ast.walk(tree) if isinstance(n, (ast.ClassDef, ast.FunctionDef))]
        nodes.append(tree.body[0])
    return nodes


def import_submodules(package_name: str, package_path: Iterable[str]) -> None:
    """Import every non-private module of a package so that its decorators run."""
    for info in pkgutil.iter_modules(list(package_path)):
        if not info.name.startswith("_"):
            importlib.import_module(f"{package_name}.{info.name}")
