"""REKLAB's ``PC_stiffnessID`` run in GNU Octave on the five stationary ankle trials: the reference numbers of
JointBench's parity table (docs/reklab_parity.md).

Usage::

    python -m tools.reklab.reference --toolbox /tmp/reklab_public [--commit SHA] \\
        [--data ../shared/data/reklab-ankle/ankle_stationary.npz] [--out tools/reklab]

``--toolbox``: a copy of the public toolbox (github.com/reklab/reklab_public, GPL-2), outside this repository;
``--commit``: its commit, read with git when the copy is a git work tree. Needs ``octave`` with its ``signal``
package on the PATH (Debian: ``apt-get install octave octave-signal``). Octave cannot read the toolbox's own
``stiffnessID/experimental_data.mat`` (MATLAB ``nldat`` objects stored as MCOS class data come back as opaque
structs), so the trials are written here as plain arrays from the developers' shared copy (the same recordings)
and rebuilt as ``nldat`` objects by ``pc_reference.m``.

Writes ``pc_stiffnessID_rect.csv`` (one row per trial: intrinsic K, reflex gain, VAFT, VAFi, VAFr, the CPU
seconds of the call; the toolbox commit, the Octave and signal-package versions) and ``pc_stiffnessID_rect_irfs.csv``
(the intrinsic and reflex IRFs as the toolbox stores them, per second) into ``--out``. Nothing of the toolbox is
copied into the repository: only these numbers and the scripts that made them.
"""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
TRIALS = ("z_pf", "z_pf2", "z_df", "z_df2", "z_df3")
SUMMARY, IRFS = "pc_stiffnessID_rect.csv", "pc_stiffnessID_rect_irfs.csv"


def toolbox_commit(toolbox: Path, given: str | None) -> str:
    """The toolbox's commit: ``given``, or git's of the work tree ``toolbox``."""
    if given:
        return given
    out = subprocess.run(["git", "-C", str(toolbox), "rev-parse", "HEAD"], capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"{toolbox} is not a git work tree: give the toolbox's commit with --commit")
    return out.stdout.strip()


def octave_versions() -> tuple[str, str]:
    """The versions of Octave and of its signal package."""
    out = subprocess.run(["octave", "--no-gui", "--eval",
                          "disp(version()); pkg load signal; p = pkg('list', 'signal'); disp(p{1}.version)"],
                         capture_output=True, text=True, check=True).stdout.split()
    return out[0], out[1]


def run(toolbox: Path, data: Path, out: Path, commit: str) -> None:
    """Write the trials as plain arrays, run ``pc_reference.m`` in Octave, add the provenance columns."""
    import pandas as pd
    import scipy.io

    d = np.load(data)
    if float(d["fs"]) != 1000.0:
        sys.exit(f"{data}: expected the 1 kHz recordings, got fs = {float(d['fs']):g} Hz")
    with tempfile.TemporaryDirectory() as tmp:
        mat, prefix = Path(tmp) / "trials.mat", Path(tmp) / "ref"
        scipy.io.savemat(mat, {k: np.asarray(d[k], float) for k in TRIALS})
        script = (f"toolbox = '{toolbox.resolve()}'; trials = '{mat}'; out = '{prefix}'; "
                  f"run('{HERE / 'pc_reference.m'}')")
        subprocess.run(["octave", "--no-gui", "--no-window-system", "--eval", script], check=True,
                       stdout=subprocess.DEVNULL)
        summary = pd.read_csv(f"{prefix}_summary.csv")
        irfs = pd.read_csv(f"{prefix}_irfs.csv")
    octave, signal = octave_versions()
    summary = summary.assign(toolbox="reklab/reklab_public", toolbox_commit=commit, octave=octave,
                             octave_signal=signal)
    out.mkdir(parents=True, exist_ok=True)
    summary.to_csv(out / SUMMARY, index=False)
    irfs.to_csv(out / IRFS, index=False)
    print(f"wrote {out / SUMMARY} and {out / IRFS} (toolbox {commit[:12]}, Octave {octave}, signal {signal})")


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--toolbox", type=Path, required=True, help="a copy of reklab/reklab_public")
    p.add_argument("--commit", help="the toolbox's commit (default: git's of --toolbox)")
    p.add_argument("--data", type=Path, default=HERE.parents[1].parent / "shared" / "data" / "reklab-ankle" /
                   "ankle_stationary.npz", help="the five trials as arrays (default: ../shared's copy)")
    p.add_argument("--out", type=Path, default=HERE, help="folder of the CSV files (default: tools/reklab)")
    a = p.parse_args(argv)
    commit = toolbox_commit(a.toolbox, a.commit)
    if not re.fullmatch(r"[0-9a-f]{40}", commit):
        sys.exit(f"--commit: expected 40 hex digits, got {commit!r}")
    run(a.toolbox, a.data, a.out, commit)


if __name__ == "__main__":
    main()
