"""Writing files so that an interrupted program never leaves half a file or a stray temporary.

One mechanism for every output of the project (study results, reports, cache entries, the outputs of
``jointbench estimate``): :func:`atomic_write` writes through a temporary file beside the target and
moves it into place. Temporary names are unique per process (``.NAME.PID.RANDOM.tmp``), so concurrent
writers never collide; the temporary is removed on any exception, KeyboardInterrupt and SIGTERM
included (the CLI turns SIGTERM into an exception). A process killed with SIGKILL cannot clean up:
:func:`sweep_stale_temps` removes the temporaries of processes that no longer exist, and the harness
calls it before it writes into a folder. A set of files that belong together (a study's tables, report
and figures) is written into a staging folder and moved into place as a set (:func:`replace_as_set`).
"""
from __future__ import annotations

import os
import shutil
import stat
import tempfile
from pathlib import Path
from typing import Callable

from jointbench.core.errors import OutputError

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


def atomic_write_set(items: list[tuple[str | os.PathLike, Callable[[str], object]]], mode: int = 0o644) -> None:
    """:func:`atomic_write` of several files as one set: every temporary is written first, and only when all
    are complete are they moved into place. A failure (a full disk) removes the temporaries and leaves every
    old file as it was: never half of the new set beside half of the old one."""
    temps: list[tuple[str, Path]] = []
    try:
        for path, write in items:
            path = Path(path)
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                fd, tmp = tempfile.mkstemp(prefix=_tmp_prefix(path), suffix=TMP_SUFFIX, dir=path.parent)
                os.close(fd)
                temps.append((tmp, path))
                write(tmp)
                os.chmod(tmp, mode)
            except OSError as exc:
                raise OutputError(f"{path}: cannot write: {exc.strerror or exc}; no output was replaced") from None
        for tmp, path in temps:
            os.replace(tmp, path)
    finally:
        for tmp, _ in temps:
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


def staging_folder(folder: str | os.PathLike, name: str = "outputs") -> Path:
    """A new empty folder inside ``folder`` to write a set of outputs into before :func:`replace_as_set`
    (named like a temporary, so that :func:`sweep_stale_temps` removes it if its process dies)."""
    Path(folder).mkdir(parents=True, exist_ok=True)
    return Path(tempfile.mkdtemp(prefix=f".{name}.{os.getpid()}.", suffix=TMP_SUFFIX, dir=folder))


def sweep_stale_temps(folder: str | os.PathLike, recursive: bool = False) -> list[Path]:
    """Remove the temporaries of :func:`atomic_write` (and the staging folders of :func:`staging_folder`)
    left in ``folder`` by processes that no longer exist (killed with SIGKILL during a write); those of
    live processes are kept. Returns the paths removed."""
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
            if p.is_dir() and not p.is_symlink():
                shutil.rmtree(p)          # a staged set of outputs (replace_as_set) never moved into place
            else:
                p.unlink()
            removed.append(p)
        except OSError:
            pass
    return removed


def file_problem(path: str | os.PathLike, max_bytes: int | None = None) -> str | None:
    """What makes ``path`` unfit to read as an input file, or None: missing, a folder, not a regular file
    (a device such as ``/dev/zero``, a FIFO or a socket: reading one may never end), or larger than
    ``max_bytes``. Symlinks are followed; nothing is opened (a FIFO would block)."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return "file not found"
    except OSError as exc:
        return f"cannot be read ({exc.strerror or exc})"
    mode = st.st_mode
    if stat.S_ISDIR(mode):
        return "is a folder, not a file"
    if not stat.S_ISREG(mode):
        kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode)
                else "a device")
        return f"is {kind}, not a regular file"
    if max_bytes is not None and st.st_size > max_bytes:
        return f"is {size_text(st.st_size)}, more than the {size_text(max_bytes)} allowed"
    return None


def size_text(nbytes: int) -> str:
    """``12.3 MB``-style size (decimal units, as file managers show them)."""
    for unit, k in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if nbytes >= k:
            return f"{nbytes / k:.3g} {unit}"
    return f"{nbytes} bytes"


def decode_text(data: bytes, where: str, error=ValueError) -> str:
    """UTF-8 text (a UTF-8 byte-order mark is dropped); anything else is one line naming ``where``, the
    encoding it looks like and the place of the first bad byte."""
    for bom, name in ((b"\xff\xfe\x00\x00", "UTF-32"), (b"\x00\x00\xfe\xff", "UTF-32"),
                      (b"\xff\xfe", "UTF-16"), (b"\xfe\xff", "UTF-16")):
        if data.startswith(bom):
            raise error(f"{where}: the file is {name} text (it starts with a {name} byte-order mark); "
                        f"save it as UTF-8")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        col = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        head = data[:400]
        hint = " (it looks like UTF-16)" if head.count(b"\x00") >= 0.3 * len(head) else ""   # every other byte NUL
        raise error(f"{where}: not UTF-8 text{hint}: byte 0x{data[exc.start]:02x} at line {line}, column {col}; "
                    f"save the file as UTF-8") from None


def _check_targets(folder: Path, names: list[Path]) -> None:
    """Refuse, before anything moves, a target of :func:`replace_as_set` that a file cannot replace: a
    folder (or anything but a file or a link) where a file goes, or a file where a folder goes."""
    from jointbench.core.errors import OutputError

    for name in names:
        dest = folder / name
        for parent in list(reversed(dest.relative_to(folder).parents))[1:]:
            above = folder / parent
            if above.exists() and not above.is_dir():
                raise OutputError(f"{above}: is a file where the outputs need a folder; move it away and run again")
        if dest.is_symlink() or not dest.exists():
            continue
        if not dest.is_file():
            what = "a folder" if dest.is_dir() else "not a regular file"
            raise OutputError(f"{dest}: is {what} where the outputs write a file; move it away and run again")


def replace_as_set(folder: str | os.PathLike, staged: str | os.PathLike) -> list[Path]:
    """Move every file of ``staged`` (a folder written beside ``folder``'s files) into ``folder``, replacing
    files of the same names, then remove ``staged``. Each move is a rename within one file system, which
    needs no space and cannot fail half-way through a file: a set written completely in ``staged`` goes
    into place as a whole (or, if the renames are interrupted, every file is still a whole file of one
    run). Returns the files moved."""
    folder, staged = Path(folder), Path(staged)
    sources = sorted(p for p in staged.rglob("*") if p.is_file())
    _check_targets(folder, [src.relative_to(staged) for src in sources])
    moved = []
    for src in sources:
        dest = folder / src.relative_to(staged)
        dest.parent.mkdir(parents=True, exist_ok=True)
        os.replace(src, dest)
        moved.append(dest)
    shutil.rmtree(staged, ignore_errors=True)
    return moved
