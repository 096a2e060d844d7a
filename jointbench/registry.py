"""Name -> object registries filled by decorators (folder-as-registry, as in benchopt/dm_control)."""
from __future__ import annotations

import importlib
import pkgutil
from typing import Callable, Generic, Iterable, TypeVar

from jointbench.errors import ConfigError

T = TypeVar("T")


class Registry(Generic[T]):
    """A tagged registry of named objects.

    Parameters
    ----------
    kind : str
        What the registry holds ("estimator", "joint model", ...), used in error messages.
    """

    def __init__(self, kind: str):
        self.kind = kind
        self._items: dict[str, T] = {}
        self._tags: dict[str, frozenset[str]] = {}

    def register(self, name: str, *, tags: Iterable[str] = ()) -> Callable[[T], T]:
        """Decorator registering ``obj`` under ``name`` (names are unique)."""

        def deco(obj: T) -> T:
            if name in self._items and self._items[name] is not obj:
                raise RuntimeError(f"{self.kind} {name!r} registered twice")
            self._items[name] = obj
            self._tags[name] = frozenset(tags)
            return obj

        return deco

    def get(self, name: str) -> T:
        """Return the object registered as ``name`` or raise a :class:`ConfigError` listing the names."""
        try:
            return self._items[name]
        except KeyError:
            known = ", ".join(sorted(self._items)) or "(none)"
            raise ConfigError(f"unknown {self.kind} {name!r}; known: {known}") from None

    def names(self, tag: str | None = None) -> list[str]:
        """Sorted registered names, optionally only those carrying ``tag``."""
        return sorted(n for n in self._items if tag is None or tag in self._tags[n])

    def tags(self, name: str) -> frozenset[str]:
        self.get(name)
        return self._tags[name]

    def __contains__(self, name: object) -> bool:
        return name in self._items


def import_submodules(package_name: str, package_path: Iterable[str]) -> None:
    """Import every non-private module of a package so that its decorators run."""
    for info in pkgutil.iter_modules(list(package_path)):
        if not info.name.startswith("_"):
            importlib.import_module(f"{package_name}.{info.name}")
