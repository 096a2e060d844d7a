"""Modules imported on first use, so that importing the core and ``jointbench.sims`` stays light.

``scipy.signal`` costs about 0.6 CPU-s to import (it loads ``scipy.stats``), ``scipy.linalg`` 0.2; the
simulators use them only inside functions, so a process that only reads configs, lists registries or serves
cases from the cache (the parent of a parallel or fully cached run, ``jointbench list``) never pays for it.
"""
from __future__ import annotations

import importlib
from types import ModuleType


class LazyModule:
    """Stands for module ``name``; imports it on the first attribute access.

    Examples
    --------
    >>> sps = LazyModule("scipy.signal")      # nothing imported yet
    >>> sps.butter(2, 0.1, output="sos").shape
    (1, 6)
    """

    def __init__(self, name: str):
        self._name = name
        self._module: ModuleType | None = None

    def __getattr__(self, attr: str):
        if self._module is None:
            self._module = importlib.import_module(self._name)
        return getattr(self._module, attr)

    def __repr__(self) -> str:
        return f"<lazy module {self._name!r}{'' if self._module is None else ' (imported)'}>"


#: ``scipy.signal`` (``from jointbench.core.lazy import scipy_signal as sps``) and ``scipy.linalg``
scipy_signal = LazyModule("scipy.signal")
scipy_linalg = LazyModule("scipy.linalg")
