"""Writing files so that an interrupted program never leaves half a file or a stray temporary.

One mechanism for every output of the project (study results, reports, cache entries, the outputs of
``jointbench estimate``): :func:`atomic_write` writes through a temporary file beside the target and
moves it into place. Temporary names are unique per process (``.NAME.PID.RANDOM.tmp``), so concurrent
writers never collide; the temporary is removed on any exception, KeyboardInterrupt and SIGTERM
included (the CLI turns SIGTERM into an exception). A process killed with SIGKILL cannot clean up:
:func:`sweep_stale_temps` removes the temporaries of processes that no longer exist, and the harness
calls it before it writes into a folder.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable

from jointbench.errors import OutputError

TMP_SUFFIX = ".tmp"


def _tmp_prefix(path: Path) -> str:
    return f".{path.name}.{os.getpid()}."


def atomic_write(path: str | os.PathLike, write: Callable[[str], object], mode: int = 0o644) -> None:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then move it into place.

    Parameters
    ----------
    path : path-like
        The file to (re)write; its folder is created when missing.
    write : callable
        Writes the content into the file name it is given (a ``str``).
    mode : int
        Permission bits of the result (``mkstemp`` would leave 0600).

    Raises
    ------
    OutputError
        The folder or file cannot be written (one line naming the path and the reason).
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=_tmp_prefix(path), suffix=TMP_SUFFIX, dir=path.parent)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write: {exc.strerror or exc}") from None
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write: {exc.strerror or exc}") from None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_text(path: str | os.PathLike, text: str) -> None:
    """:func:`atomic_write` of a UTF-8 text."""
    atomic_write(path, lambda p: Path(p).write_text(text, encoding="utf-8"))


def pid_alive(pid: int) -> bool:
    """Whether a process with this id exists (a zombie counts as gone)."""
    if pid <= 0:
        return False
    if os.name == "nt":          # os.kill(pid, 0) would send Ctrl-C there: assume alive
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()[0] != b"Z"
    except OSError:
        return True


def sweep_stale_temps(folder: str | os.PathLike, recursive: bool = False) -> list[Path]:
    """Remove the temporaries of :func:`atomic_write` left in ``folder`` by processes that no longer
    exist (killed with SIGKILL during a write); those of live processes are kept. Returns the paths
    removed."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    removed = []
    for p in (folder.rglob if recursive else folder.glob)(f".*{TMP_SUFFIX}"):
        fields = p.name.split(".")
        if len(fields) < 5 or not fields[-3].isdigit():
            continue                      # not one of ours
        if pid_alive(int(fields[-3])):
            continue
        try:
            p.unlink()
            removed.append(p)
        except OSError:
            pass
    return removed
