"""Recorded data sets fetched on demand (``jointbench data fetch NAME``, :func:`jointbench.api.fetch_data`): a pinned
address and SHA-256 per data set, stored in the user's data folder, never in the package.

A data set is a :class:`DataSet`: the file's address at a pinned commit of its public repository, its SHA-256, its
licence. :func:`fetch` downloads it, refuses it in one line when its SHA-256 is not the pinned one (nothing is
stored then), and keeps it in :func:`data_folder`: ``$JOINTBENCH_DATA`` when set, else
``$XDG_CACHE_HOME/jointbench`` (``~/.cache/jointbench``). :func:`located` gives the stored file, or None. The
REKLAB ankle recordings are GPL-2 like the toolbox they come with: they are fetched by the user who asks for them,
never shipped in the wheel.

References
----------
Kearney, R. E. et al. REKLAB NLID toolbox (reklab/reklab_public, GPL-2): ``stiffnessID/experimental_data.mat``,
five stationary ankle trials (``z_pf``, ``z_pf2``, ``z_df``, ``z_df2``, ``z_df3``) as ``nldat`` objects, 1 kHz.
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import tempfile
from pathlib import Path
from typing import Callable

from jointbench.core.errors import ConfigError, InputError, OutputError, argument

#: the environment variable naming the folder where fetched data sets are kept
DATA_ENV = "JOINTBENCH_DATA"


@dataclasses.dataclass(frozen=True)
class DataSet:
    """One fetchable file: where it is (a pinned commit), its SHA-256, its name on disk and its licence."""

    name: str
    url: str
    sha256: str
    filename: str
    licence: str
    description: str


#: the REKLAB toolbox's commit the ankle recordings are pinned to (reklab/reklab_public)
REKLAB_COMMIT = "4f070cb70f5d9f778a608ff8799bbfc01daf8d83"

DATASETS = {
    "reklab": DataSet(
        name="reklab",
        url=f"https://raw.githubusercontent.com/reklab/reklab_public/{REKLAB_COMMIT}/stiffnessID/experimental_data.mat",
        sha256="c8f08330ae256b8984052c0a8f907c7e077e6062547c21d154999a0fb130114d",
        filename="reklab_experimental_data.mat",
        licence="GPL-2 (the REKLAB toolbox's licence)",
        description="five stationary ankle trials (z_pf, z_pf2, z_df, z_df2, z_df3) as REKLAB nldat objects, 1 kHz"),
}


def dataset(name: str) -> DataSet:
    """The data set ``name``; one line naming the known ones otherwise."""
    if name not in DATASETS:
        raise ConfigError(f"{argument('name')}: unknown data set {name!r}; known: {', '.join(sorted(DATASETS))}")
    return DATASETS[name]


def data_folder() -> Path:
    """Where fetched data sets are kept: ``$JOINTBENCH_DATA``, else ``$XDG_CACHE_HOME/jointbench``, else
    ``~/.cache/jointbench`` (never inside the package)."""
    if os.environ.get(DATA_ENV):
        return Path(os.environ[DATA_ENV]).expanduser()
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache).expanduser() / "jointbench"


def located(name: str) -> Path | None:
    """The stored file of data set ``name`` (:func:`fetch`), or None when it has not been fetched."""
    path = data_folder() / dataset(name).filename
    return path if path.is_file() else None


def sha256_of(path: Path) -> str:
    """The SHA-256 of a file, hex."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _urlopen(url: str):
    import urllib.request

    return urllib.request.urlopen(url, timeout=60)


def fetch(name: str, *, url: str | None = None, folder: str | Path | None = None,
          opener: Callable[[str], object] = _urlopen) -> Path:
    """Download data set ``name``, check its SHA-256 and store it.

    Parameters
    ----------
    name : str
        A key of :data:`DATASETS` (``"reklab"``).
    url : str or None
        Another address of the same file (a mirror, a ``file://`` copy); the pinned one by default. The SHA-256
        checked is the pinned one whatever the address.
    folder : str, Path or None
        Where to store it; default :func:`data_folder`.
    opener : callable
        ``opener(url)`` returning a readable binary stream (``urllib.request.urlopen``; tests pass their own).

    Returns
    -------
    Path
        The stored file (already there with the right SHA-256: not downloaded again).

    Raises
    ------
    InputError
        The download failed, or the file's SHA-256 is not the pinned one (nothing is stored).
    OutputError
        The folder cannot be written.
    """
    ds = dataset(name)
    root = Path(folder).expanduser() if folder is not None else data_folder()
    target = root / ds.filename
    if target.is_file() and sha256_of(target) == ds.sha256:
        return target
    source = url or ds.url
    try:
        root.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{ds.filename}.", dir=root)
    except OSError as exc:
        raise OutputError(f"{root}: cannot store the data set {name} there ({exc.strerror or exc}); set "
                          f"{DATA_ENV} to a writable folder") from None
    h = hashlib.sha256()
    try:
        try:
            with os.fdopen(fd, "wb") as out, opener(source) as stream:
                for block in iter(lambda: stream.read(1 << 20), b""):
                    h.update(block)
                    out.write(block)
        except OSError as exc:           # urllib's URLError and HTTPError are OSErrors
            raise InputError(f"{name}: cannot download {source}: {getattr(exc, 'reason', None) or exc}") from None
        if h.hexdigest() != ds.sha256:
            raise InputError(f"{name}: {source} has SHA-256 {h.hexdigest()}, not the pinned {ds.sha256}: "
                             f"refused, nothing stored")
        os.replace(tmp, target)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return target
