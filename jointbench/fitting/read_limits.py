"""Limits of a recording, checked before anything is loaded (each refusal one line naming the file).

- a regular file: not a device such as ``/dev/zero``, a FIFO or a socket (reading one may never end);
- at most :data:`MAX_SAMPLES` samples per channel and :data:`MAX_VALUES` values per variable: a CSV's
  lines are counted first, an NPZ member's header and a .mat v7.3 dataset's shape are read before their
  data (a zip bomb's members of 2 GiB of zeros are refused from their headers);
- a CSV in UTF-8 (latin-1 or UTF-16 is one line, not a decoding error of pandas).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from jointbench.core.errors import InputError
from jointbench.core.files import decode_text, file_problem

#: most samples per channel a record may have: 5 million is 33 minutes at 2.5 kHz, far beyond the records
#: the estimators are built for (the papers' longest is 60 s); longer recordings are fitted in windows
MAX_SAMPLES = 5_000_000
#: most values per variable (an ensemble holds realizations x samples): 400 MB of float64
MAX_VALUES = 50_000_000


def check_file(path: Path) -> None:
    """A regular file (never opened otherwise: a FIFO would block, /dev/zero never ends)."""
    problem = file_problem(path)
    if problem is not None:
        raise InputError(f"{path}: {problem}" if problem != "file not found" else f"{path}: no such file")


def check_shape(where: str, what: str, shape) -> None:
    """An array of ``shape`` within the limits (before it is loaded)."""
    shape = tuple(int(n) for n in shape)
    if int(np.prod(shape, dtype=object)) > MAX_VALUES or (shape and max(shape) > MAX_SAMPLES):
        raise InputError(f"{where}: {what} is {'x'.join(map(str, shape))}, more than the {MAX_SAMPLES} samples "
                         f"per channel ({MAX_VALUES} values) a record may have; read it in windows or resample it")


def check_csv(path: Path) -> None:
    """A regular file of at most :data:`MAX_SAMPLES` lines, whose start decodes as UTF-8."""
    check_file(path)
    n = 0
    with open(path, "rb") as f:
        head = f.read(1 << 16)
        f.seek(0)
        for block in iter(lambda: f.read(1 << 22), b""):
            n += block.count(b"\n")
            if n > MAX_SAMPLES + 1000:
                raise InputError(f"{path}: more than {MAX_SAMPLES} lines, more than the {MAX_SAMPLES} samples a "
                                 f"record may have; read it in windows or resample it")
    cut = head.rfind(b"\n") + 1 if len(head) == 1 << 16 else len(head)
    decode_text(head[:cut] or head, str(path), InputError)
