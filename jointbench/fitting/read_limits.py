"""Limits of a recording, checked before anything is loaded (each refusal one line naming the file).

- a regular file: not a device such as ``/dev/zero``, a FIFO or a socket (reading one may never end);
- what loading it costs in memory, not a count of rows: a CSV's lines and columns are counted first (about
  :data:`CSV_BYTES_PER_VALUE` each while pandas reads it), an NPZ member's header and a .mat v7.3 dataset's
  shape are read before their data (a zip bomb's members of 2 GiB of zeros are refused from their headers
  when they would not fit); each must fit in half the memory available (:func:`available_memory`). Whether
  the fit fits is the method's own estimate (``memory_bytes``, :func:`jointbench.fitting.checks.check_memory`):
  a record of 10^7 rows is read, and fitted by a method that can;
- a CSV in UTF-8 (latin-1 or UTF-16 is one line, not a decoding error of pandas).
"""
from __future__ import annotations

from pathlib import Path

from jointbench.core.errors import InputError
from jointbench.core.files import decode_text, file_problem

#: bytes one value of a CSV costs at the peak of reading it (its text held as Python strings, then the float64
#: array): the peak resident memory grew by 110 bytes per value reading a 3-column CSV of 10^6 rows
CSV_BYTES_PER_VALUE = 120
#: the share of the available memory one recording may take to load
LOAD_FRACTION = 0.5


def available_memory() -> int:
    """Bytes of memory available (``MemAvailable`` on Linux; 8 GiB when unknown)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 8 << 30


def size_text(nbytes: int) -> str:
    """``nbytes`` in the largest binary unit it reaches (``1.5 GiB``)."""
    for unit, k in (("GiB", 30), ("MiB", 20), ("KiB", 10)):
        if nbytes >= 1 << k:
            return f"{nbytes / (1 << k):.3g} {unit}"
    return f"{nbytes} bytes"


def check_file(path: Path) -> None:
    """A regular file (never opened otherwise: a FIFO would block, /dev/zero never ends)."""
    problem = file_problem(path)
    if problem is not None:
        raise InputError(f"{path}: {problem}" if problem != "file not found" else f"{path}: no such file")


def check_csv(path: Path) -> None:
    """A regular file whose start decodes as UTF-8, and whose values (lines times the columns of its first
    line) can be read in :data:`LOAD_FRACTION` of the memory available."""
    check_file(path)
    with open(path, "rb") as f:
        head = f.read(1 << 16)
    cut = head.rfind(b"\n") + 1 if len(head) == 1 << 16 else len(head)
    decode_text(head[:cut] or head, str(path), InputError)
    first = head.split(b"\n", 1)[0]
    columns = 1 + max(first.count(sep) for sep in (b",", b";", b"\t"))
    budget = int(LOAD_FRACTION * available_memory())
    lines = 0
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 22), b""):
            lines += block.count(b"\n")
            need = lines * columns * CSV_BYTES_PER_VALUE
            if need > budget:
                raise InputError(f"{path}: reading it needs more than {size_text(need)} ({lines} lines so far, "
                                 f"{columns} columns), more than half the memory available "
                                 f"({size_text(available_memory())}); read it in windows or resample it")
