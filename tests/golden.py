"""Pinned smoke-run outcomes: each study's smoke run must give, check by check, the statuses in
``tests/golden/<name>_smoke.csv``. A check that flips fails the suite; a deliberate change is written by
re-running the test with ``JOINTBENCH_GOLDEN_REASON='<why>'``, which rewrites the file and logs the flips
with the reason in ``tests/golden/CHANGES.md``.
"""
from __future__ import annotations

import datetime as _dt
import os
from pathlib import Path

import pandas as pd

GOLDEN = Path(__file__).resolve().parent / "golden"
COLUMNS = ["check", "evidence", "status"]


def _diff(pinned: pd.DataFrame, now: pd.DataFrame) -> list[str]:
    a = pinned.set_index("check")
    b = now.set_index("check")
    out = [f"{c}: pinned, not in the run" for c in a.index.difference(b.index)]
    out += [f"{c}: new check, not pinned" for c in b.index.difference(a.index)]
    for c in a.index.intersection(b.index):
        for col in ("evidence", "status"):
            if a.loc[c, col] != b.loc[c, col]:
                out.append(f"{c}: {col} {a.loc[c, col]} -> {b.loc[c, col]}")
    return out


def check_golden(name: str, comparison: pd.DataFrame) -> None:
    """Assert (or, with JOINTBENCH_GOLDEN_REASON set, rewrite) the pinned outcome of smoke run ``name``."""
    path = GOLDEN / f"{name}_smoke.csv"
    now = comparison[COLUMNS].astype(str).reset_index(drop=True)
    reason = os.environ.get("JOINTBENCH_GOLDEN_REASON", "").strip()
    pinned = pd.read_csv(path, dtype=str) if path.is_file() else pd.DataFrame(columns=COLUMNS)
    changes = _diff(pinned, now)
    if reason:
        if changes or not path.is_file():
            if not path.is_file():
                counts = now["status"].value_counts()
                changes = [f"first pin: {len(now)} checks, {counts.get('pass', 0)} pass, {counts.get('miss', 0)} miss"]
            GOLDEN.mkdir(exist_ok=True)
            now.to_csv(path, index=False)
            with open(GOLDEN / "CHANGES.md", "a") as log:
                log.write(f"\n## {_dt.date.today().isoformat()} {name}: {reason}\n\n"
                          + "".join(f"- {c}\n" for c in changes))
        return
    assert path.is_file(), (f"no pinned outcome {path}: create it deliberately with "
                            f"JOINTBENCH_GOLDEN_REASON='<why>' pytest {name} tests")
    assert not changes, (f"the smoke run of {name} changed outcome (pinned in {path}):\n  " + "\n  ".join(changes)
                         + "\nIf this is deliberate, re-run with JOINTBENCH_GOLDEN_REASON='<why>' to update the "
                         "file (the flips and the reason go to tests/golden/CHANGES.md).")
