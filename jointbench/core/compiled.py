"""How the compiled loops of the package are compiled: numba in nopython mode, cached on disk.

One mechanism for every compiled kernel: the integrator loops of :mod:`jointbench.sims._ltv_kernels`,
FSEWLS's EWLS loops of :mod:`jointbench.estimators._ewls_loops` and the ensemble estimators' eigensolver
(:mod:`jointbench.estimators._small_eigh`), the three that pay for themselves (issue 34 weighed each against
the time a user waits, results/benchmarks.md).
Each kernel module imports this (and numba) on its first use, so that ``import jointbench``, the
registries and the command line's start stay light.

The kernels use IEEE arithmetic as written (no ``fastmath``: no reassociation, no fused multiply-add), so
a compiled loop gives the numbers of the same operations done by numpy, bit for bit, whatever the
vector width (tests/test_sims_tv.py, tests/test_fsewls.py). ``error_model="numpy"``: a division by zero
gives inf or nan as in numpy instead of raising, so the lane loops run as vector instructions.

The compiled code is cached on disk (``cache=True``): beside the kernel's source in ``__pycache__``, or,
when that folder is not writable (as in some installed wheels), in numba's per-user cache folder;
``NUMBA_CACHE_DIR`` overrides both. When numba finds neither, the kernels are compiled anew in each
process, with one warning.
"""
from __future__ import annotations

import warnings

from numba import njit

_WARNED: list[bool] = []          # the warning below is given once per process


def jit(fn):
    """``fn`` compiled in nopython mode with numpy's division semantics, cached on disk (module docstring);
    when numba finds no writable cache folder, compiled anew in each process instead, with one warning."""
    try:
        return njit(cache=True, error_model="numpy")(fn)
    except RuntimeError as exc:                   # numba: "cannot cache function ...: no locator available"
        if not _WARNED:
            _WARNED.append(True)
            warnings.warn(f"jointbench: the compiled kernels are not cached ({exc}); each process compiles them "
                          f"again (a few seconds): set NUMBA_CACHE_DIR to a writable folder", RuntimeWarning,
                          stacklevel=2)
        return njit(error_model="numpy")(fn)


def jit_inline(fn):
    """``fn`` compiled as :func:`jit` compiles, and inlined into each caller in numba's own representation
    (``inline="always"``): no compiled function of its own, so its callees' code is not optimised and
    generated once more for it (a fifth of the eigensolver's compile time when it was a compiled helper,
    issue 22)."""
    return njit(cache=True, error_model="numpy", inline="always")(fn)
