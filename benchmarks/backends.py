"""One study's results by simulation backend: where each backend's run goes, and what the report says.

``jointbench run STUDY`` simulates every part on the part's own backend (``backend:`` in the study
config, ``analytic`` by default) and writes ``results/<study>/``; ``jointbench run STUDY --backend
mujoco`` runs every part on MuJoCo and writes ``results/<study>/backend-mujoco/`` (its own report,
comparison and figures). Every report then gains:

- **Simulation backends**: which backend simulated which parts, and the median simulation time per
  trial of each run (the whole of :func:`sims.simulate`: inputs, physics, sensors, acquisition);
- **Checks by backend** (when another backend's run of the same study exists): every check's value from
  each run side by side, with whether it falls within the check's tolerance. The status of a check stays
  that of the study's own run (``results/<study>/report.md``); the other columns show what the same
  checks give on physics-engine data.

Nothing here recomputes a case: it reads each run's ``checks.csv`` and ``cases.csv``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from jointbench.benchmarks.harness.pages import Paragraph, Section, table as page_table

PREFIX = "backend-"


def run_folder(study_folder: Path, backend: str | None) -> Path:
    """The output folder of a run: the study's own, or ``backend-<name>/`` inside it."""
    return study_folder if backend is None else study_folder / f"{PREFIX}{backend}"


def runs(folder: Path) -> dict[str, Path]:
    """Every run of the study whose output folder is (or contains) ``folder``: label -> folder.

    The study's own run is labelled ``study`` (it may mix backends across parts), the others by their
    backend. Only runs that wrote a ``checks.csv`` count, except ``folder`` itself.
    """
    base = folder.parent if folder.name.startswith(PREFIX) else folder
    out = {}
    for label, path in [("study", base)] + [(p.name[len(PREFIX):], p) for p in sorted(base.glob(f"{PREFIX}*"))]:
        if path == folder or (path / "checks.csv").is_file():
            out[label] = path
    return out


def _cases(path: Path) -> pd.DataFrame:
    f = path / "cases.csv"
    if not f.is_file():
        return pd.DataFrame()
    return pd.read_csv(f, low_memory=False)


def timing(cases: pd.DataFrame) -> dict:
    """Backends of the simulated parts, and per backend the trials, the responses computed and the
    simulation seconds.

    A trial whose noise-free response was served by :mod:`sims.reuse` (another noise draw, rate or
    scorer of the same response) costs only its sensors and acquisition, so a median over trials would
    say little; the table gives the total simulation time per backend and its mean per computed
    response (``n_responses``; cases written before it was recorded count every trial). Cases that
    simulate nothing are left out; cached cases keep the times of the run that computed them.
    """
    need = {"case_id", "backend", "sim_time_s", "n_trials", "part"}
    if cases.empty or not need <= set(cases.columns):
        return {"backends": {}, "rows": []}
    per_case = cases.drop_duplicates("case_id")
    per_case = per_case[per_case["n_trials"] > 0]
    by_backend = {b: sorted(g["part"].unique()) for b, g in per_case.groupby("backend")}
    responses = (per_case["n_responses"].fillna(per_case["n_trials"]) if "n_responses" in per_case
                 else per_case["n_trials"])
    rows = []
    for b, g in per_case.assign(responses=responses).groupby("backend"):
        total, n = float(g["sim_time_s"].sum()), int(g["responses"].sum())
        rows.append({"backend": b, "trials": int(g["n_trials"].sum()), "responses": n, "total_s": total,
                     "per_response_s": total / n if n else float("nan")})
    return {"backends": by_backend, "rows": rows,
            "commit": str(per_case["git_commit"].iloc[0]) if "git_commit" in per_case and len(per_case) else ""}


def _label(label: str, info: dict) -> str:
    names = "+".join(sorted(info["backends"])) or "none"
    return names if label != "study" else f"{names} (study)"


def sections(study, comparison: pd.DataFrame, meta: dict) -> list[Section]:
    """The report's "Simulation backends" section, with "Checks by backend" when another run exists."""
    folder = meta.get("folder")
    if folder is None:
        return []
    folder = Path(folder)
    found = runs(folder)
    stage = meta.get("stage")        # this run's tables, while its outputs are staged (benchmarks/study.py)
    infos = {label: timing(_cases(Path(stage) if stage is not None and path == folder else path))
             for label, path in found.items()}
    this = next(label for label, path in found.items() if path == folder)
    if not infos[this]["backends"]:
        return []   # nothing simulated (analytic parts only)
    rows = []
    for label, path in found.items():
        info = infos[label]
        for r in info["rows"]:
            rows.append({"run": ("this report" if label == this else f"`{path.relative_to(path.parents[1])}`"),
                         "backend": r["backend"], "parts": ", ".join(info["backends"][r["backend"]]),
                         "trials": r["trials"], "responses computed": r["responses"],
                         "simulation time (s)": r["total_s"], "per computed response (mean, s)": r["per_response_s"],
                         "commit": info.get("commit", "")})
    sec = Section("Simulation backends", anchor="backends", body=[
        Paragraph("Which backend simulated each part's trials, how many noise-free responses it computed (trials "
                  "that differ only in their noise draw, rate or scoring share one: sims/reuse.py), and the "
                  "simulation time (inputs, physics, sensors, acquisition) in all and per computed response. "
                  "Cached cases keep the times of the run that computed them."), page_table("", pd.DataFrame(rows))])
    others = {label: path for label, path in found.items() if label != this}
    if comparison.empty or not others:
        return [sec]
    table = comparison[["check", "description", "published"]].copy()
    table[_label(this, infos[this])] = comparison["reproduced"].to_numpy(float)
    for label, path in others.items():
        other = pd.read_csv(path / "checks.csv")
        got = dict(zip(other["check"].astype(str), other["reproduced"]))
        col = _label(label, infos[label])
        table[col] = [got.get(c, np.nan) for c in comparison["check"].astype(str)]
        table[f"{col} within"] = ["yes" if np.isfinite(v) and lo <= v <= hi else ("" if not np.isfinite(v) else "no")
                                  for v, lo, hi in zip(table[col], comparison["low"], comparison["high"])]
    table["low"], table["high"] = comparison["low"].to_numpy(), comparison["high"].to_numpy()
    table["status"] = comparison["status"].to_numpy()
    own = "this run's" if this == "study" else "the study's own run's (`../report.md`)"
    sec.add(Section("Checks by backend", anchor="checks-by-backend", body=[
        Paragraph(f"Every check computed from each run of this study (`within`: inside the tolerance). The "
                  f"status column is this report's; the study's status is {own}. A difference between the "
                  f"columns is what the physics engine's apparatus and integration change."),
        page_table("", table, classes=lambda r: {"status": "pass" if r["status"] == "pass" else "miss"})]))
    return [sec]
