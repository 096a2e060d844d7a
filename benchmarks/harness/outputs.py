"""Where a study writes: ``<results>/<study>/``, checked before any case runs, locked while written.

- The study id names a folder: it must be a plain name, and the folder must lie inside the results
  folder (a config saying ``study: ../../x`` is refused, naming the file and key); the harness's own
  names there (``cache``, ``nightly``, ``history.sqlite``) are refused too.
- The folders must be writable: a read-only ``results/`` is one line (exit 2), before hours of work.
- Two runs of one study may run at once (cases and cache entries are written atomically under unique
  names); each writes its outputs under an exclusive lock of the study folder, so every set of
  ``cases.csv``, ``checks.csv``, report and figures comes from one run. The second waits for the
  first to finish writing (a few seconds) and says so, naming it; a holder that has not finished after
  :data:`LOCK_WAIT_S` (stuck) ends the wait with one line naming it.
"""
from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
import time
from pathlib import Path

from jointbench.core.errors import ConfigError, OutputError

STUDY_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,99}")
#: names in the results folder that belong to the harness (the case cache, the nightly pages, the run
#: history and its SQLite companions), compared without case (macOS and Windows fold it)
RESERVED = ("cache", "nightly", "set-runs", "history.sqlite", "history.sqlite-wal", "history.sqlite-shm",
            "history.sqlite-journal")


def study_folder(root: Path, study_id: str, config: Path | str) -> Path:
    """``root / study_id``, refusing an id that is not a plain name or leaves ``root``."""
    if not STUDY_ID.fullmatch(study_id) or ".." in study_id:
        raise ConfigError(f"{config}: key 'study': {study_id!r} is not a plain name (letters, digits, '_', "
                          f"'-', '.'; no '..'): it names the results folder <results>/<study>")
    if study_id.lower() in RESERVED:
        raise ConfigError(f"{config}: key 'study': {study_id!r} is a reserved name of the results folder (it "
                          f"holds the harness's own {study_id.lower()}); reserved: {', '.join(RESERVED[:3])}; "
                          f"choose another id")
    try:
        root = Path(root).resolve()
        folder = (root / study_id).resolve()
    except (OSError, RuntimeError) as exc:        # a symlink loop
        raise OutputError(f"{root}: cannot use it as the results folder ({exc})") from None
    if folder.parent != root:
        raise ConfigError(f"{config}: key 'study': {study_id!r} would write outside {root}")
    return folder


def ensure_writable(*folders: Path) -> None:
    """Create the folders and prove each writable now (one clear error instead of a traceback later)."""
    for folder in folders:
        try:
            folder.mkdir(parents=True, exist_ok=True)
            fd, probe = tempfile.mkstemp(prefix=f".probe.{os.getpid()}.", suffix=".tmp", dir=folder)
            os.close(fd)
            os.unlink(probe)
        except OSError as exc:
            raise OutputError(f"{folder}: cannot write results here ({exc.strerror or exc}); make it "
                              f"writable or choose another results folder with --out DIR") from None


#: seconds a run waits for another run of the same study to finish writing its outputs (a few seconds when
#: all is well); then it stops with one line naming the holder
LOCK_WAIT_S = 300.0
#: seconds between two tries of a held lock
LOCK_POLL_S = 0.2


def lock_holder(text: bytes) -> str:
    """What a lock file says of its holder (``run 12 (pid 345)``), as printable text of at most 100
    characters: the file is anyone's to write, and its bytes must not reach a terminal raw."""
    shown = "".join(c if c.isprintable() else "?" for c in text.decode("utf-8", errors="replace")).strip()
    return (shown[:100] + "...") if len(shown) > 100 else (shown or "another run")


@contextlib.contextmanager
def study_lock(folder: Path, owner: str, wait_message: bool = True):
    """Hold an exclusive lock on ``folder/.lock`` while the outputs are written. Another run holding it is
    waited for, saying so (with its holder, :func:`lock_holder`), at most :data:`LOCK_WAIT_S`; then
    :class:`OutputError` names the holder and the lock file."""
    path = folder / ".lock"
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise OutputError(f"{path}: cannot create the lock file ({exc.strerror or exc})") from None
    try:
        try:
            import fcntl
        except ImportError:            # not POSIX: no lock (atomic writes still keep each file whole)
            fcntl = None
        if fcntl is not None:
            _acquire(fcntl, fd, path, wait_message)
        os.ftruncate(fd, 0)
        os.pwrite(fd, owner.encode(), 0)
        yield
    finally:
        os.close(fd)                   # closing releases the lock


def _acquire(fcntl, fd: int, path: Path, wait_message: bool) -> None:
    """Take the lock of ``fd``, waiting at most :data:`LOCK_WAIT_S` (see :func:`study_lock`)."""
    t0 = time.monotonic()
    holder = None
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            break
        except BlockingIOError:
            if holder is None:
                holder = lock_holder(os.pread(fd, 400, 0))
                if wait_message:
                    print(f"jointbench: {path.parent.name}: {holder} is writing the results; waiting up to "
                          f"{LOCK_WAIT_S:g} s for it to finish", file=sys.stderr, flush=True)
            if time.monotonic() - t0 > LOCK_WAIT_S:
                raise OutputError(f"{path}: {holder} has held the results' lock for more than {LOCK_WAIT_S:g} s; "
                                  f"if it is stuck, end it (the lock goes with its process) and run again") \
                    from None
            time.sleep(LOCK_POLL_S)
    if holder is not None and wait_message:
        print(f"jointbench: {path.parent.name}: lock acquired after {time.monotonic() - t0:.1f} s", file=sys.stderr)


#: where runs with ``--set`` and no ``--out`` write (``<results>/set-runs/<study>-set-<hash8>/``): beside, not
#: among, the studies' own folders (``results/*/checks.csv`` are the studies' status)
SET_RUNS = "set-runs"


def set_folder_name(study_id: str, overrides) -> str:
    """The results folder of a run with ``--set`` and no ``--out``: ``<study>-set-<hash8>`` (the hash of the
    overrides in order), so that such a run never replaces the study's own (committed) results."""
    import hashlib
    import json

    digest = hashlib.sha256(json.dumps(list(overrides)).encode()).hexdigest()[:8]
    return f"{study_id}-set-{digest}"


#: count and index columns written as (nullable) integers
INT_COLUMNS = ("seed", "realization", "n", "n_steps", "n_trials", "n_responses")


def parquet_frame(rows):
    """The tidy rows typed for Parquet: a column holding one kind of value keeps it (numbers, booleans,
    strings; the :data:`INT_COLUMNS` as nullable integers); a column mixing kinds (a grid axis with ``native``
    and rates) is written as strings."""
    import pandas as pd

    out = rows.copy()
    for col in INT_COLUMNS:
        if col in out.columns and pd.api.types.is_numeric_dtype(out[col]):
            x = out[col]
            if bool((x.dropna() == x.dropna().round()).all()):
                out[col] = x.astype("Int64")
    for col in out.columns:
        if out[col].dtype != object and not pd.api.types.is_string_dtype(out[col]):
            continue
        values = out[col].dropna()
        kinds = {bool if isinstance(v, bool) else (float if isinstance(v, (int, float)) else type(v)) for v in values}
        if kinds == {bool}:
            out[col] = out[col].astype("boolean")
        elif kinds == {float}:
            out[col] = pd.to_numeric(out[col])
        else:
            out[col] = out[col].map(lambda v: None if v is None or (isinstance(v, float) and v != v) else str(v))
    return out


def write_parquet(rows, path: Path) -> None:
    """``rows`` as Parquet (pyarrow) at ``path``."""
    parquet_frame(rows).to_parquet(path, index=False, engine="pyarrow")
