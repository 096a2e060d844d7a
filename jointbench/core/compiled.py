"""How the compiled loops of the package are compiled: numba in nopython mode, cached on disk.

One mechanism for every compiled kernel (the eigensolver of :mod:`jointbench.estimators._small_eigh`, the
integrator loops of :mod:`jointbench.sims._ltv_kernels`). Each kernel module imports this (and numba) on
its first use, so that ``import jointbench``, the registries and the command line's start stay light.

The kernels use IEEE arithmetic as written (no ``fastmath``: no reassociation, no fused multiply-add), so
a compiled loop gives the numbers of the same operations done by numpy, bit for bit, whatever the
vector width (tests/test_sims_tv.py). ``error_model="numpy"``: a division by zero gives inf or nan as in
numpy instead of raising, so the lane loops run as vector instructions.

The compiled code is cached on disk (``cache=True``): beside the kernel's source in ``__pycache__``, or,
when that folder is not writable (as in some installed wheels), in numba's per-user cache folder;
``NUMBA_CACHE_DIR`` overrides both. When numba finds neither, the kernels are compiled anew in each
process, with one warning.
"""
from __future__ import annotations

import os
import warnings

from numba import njit

_UNCACHED: list[str] = []
#: the read end of a pipe whose other end a process compiling the kernels aside holds (see :func:`wait_aside`)
_ASIDE: list[int] = []


def jit(fn):
    """``fn`` compiled in nopython mode with numpy's division semantics, cached on disk (module docstring);
    when numba finds no writable cache folder, compiled anew in each process instead, with one warning."""
    try:
        return njit(cache=True, error_model="numpy")(fn)
    except RuntimeError as exc:                   # numba: "cannot cache function ...: no locator available"
        if not _UNCACHED:
            warnings.warn(f"jointbench: the compiled kernels are not cached ({exc}); each process compiles them "
                          f"again (a few seconds): set NUMBA_CACHE_DIR to a writable folder", RuntimeWarning,
                          stacklevel=2)
        _UNCACHED.append(fn.__name__)
        return njit(error_model="numpy")(fn)


def uncached() -> tuple[str, ...]:
    """The kernels compiled so far that numba could not cache (no writable cache folder): compiled anew in
    each process."""
    return tuple(_UNCACHED)


def compiling_aside(fd: int) -> None:
    """Say that another process is compiling the kernels into the disk cache and holds the write end of the
    pipe whose read end is ``fd`` (it closes it when done, by exiting): :func:`wait_aside` waits for that.
    Set by :func:`jointbench.benchmarks.harness.side_by_side.preload` before it forks the studies."""
    _ASIDE.append(fd)


def wait_aside() -> None:
    """Wait until the process compiling the kernels aside (:func:`compiling_aside`) is done, if there is one:
    a kernel module calls it when it is first imported, so that its first call loads the compiled code
    from the disk cache instead of compiling it a second time. Returns at once otherwise (and when that
    process has died: its end of the pipe is closed either way)."""
    while _ASIDE:
        fd = _ASIDE.pop()
        try:
            while os.read(fd, 4096):
                pass
        except OSError:
            pass
        finally:
            try:
                os.close(fd)
            except OSError:
                pass


def jit_inline(fn):
    """``fn`` compiled as :func:`jit` compiles, and inlined into each caller in numba's own representation
    (``inline="always"``): no compiled function of its own, so its callees' code is not optimised and
    generated once more for it (a fifth of the eigensolver's compile time when it was a compiled helper,
    issue 22)."""
    return njit(cache=True, error_model="numpy", inline="always")(fn)
