"""Finished cases on disk: ``results/cache/<k[:2]>/<key>.json``, one file per entry.

The key is the SHA-256 of the key material: the case as its protocol sees it (no paths, see
:meth:`~benchmarks.harness.case.Case.key_material`), the code hash of the modules that compute it (its
protocol's and estimators' closure, :func:`~benchmarks.harness.fingerprint.case_code_hash`), the
versions of Python, numpy and scipy (:mod:`benchmarks.harness.fingerprint`), and for a case with an
estimator from a plugin, the plugin's distribution, version and source hash. Each entry carries its key,
its material and a checksum of its result, and is verified on every read: an entry copied over another
case's file, edited by hand, truncated or written by other code or libraries is reported and recomputed,
never served. ``put`` never deletes other entries (older code, other cases): the history may refer to
them; :func:`prune` removes the entries no recent run used.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Iterable

from jointbench.benchmarks.harness import fingerprint
from jointbench.benchmarks.harness.case import Case, CaseResult
from jointbench.core.files import atomic_write, sweep_stale_temps

FORMAT = 1


def key_material(case: Case) -> dict:
    material = {"format": FORMAT, "case": case.key_material(),
                "code": fingerprint.case_code_hash(case.code_modules()), "env": fingerprint.key_environment()}
    outside = fingerprint.plugin_hash(case.estimators)     # plugin estimators: their source and version
    if outside:
        material["plugins"] = outside
    return material


def case_key(case: Case) -> str:
    return fingerprint.sha(key_material(case))


def _result_payload(res: CaseResult) -> dict:
    return {"status": res.status, "rows": res.rows, "curves": res.curves, "wall_time_s": res.wall_time_s,
            "error": res.error, "sim_times": res.sim_times}


class Cache:
    """Read and write verified entries under ``folder``.

    Attributes ``hits`` (entries served), ``rejected`` (entries found but refused, with the reasons in
    ``problems``) and ``written`` count this process's use.
    """

    def __init__(self, folder: Path, enabled: bool = True, read: bool = True, warn=None):
        self.folder, self.enabled, self.read = Path(folder), enabled, read
        self.hits = self.rejected = self.written = 0
        self.problems: list[str] = []
        self._warn = warn or (lambda msg: print(f"jointbench: {msg}", file=sys.stderr))

    def path(self, key: str) -> Path:
        return self.folder / key[:2] / f"{key}.json"

    def get(self, case: Case) -> CaseResult | None:
        """The verified entry of ``case``, or None (absent, disabled or refused)."""
        if not (self.enabled and self.read):
            return None
        text = fingerprint.canonical(key_material(case))
        key = fingerprint.sha_text(text)
        p = self.path(key)
        if not p.is_file():
            return None                      # absent (a folder, a FIFO or a device there is replaced by put)
        problem = None
        try:
            # read from JSON: its canonical text is canonical_json's (fingerprint.canonical would take the
            # entry's rows and curves through JSON once more, for the same text: 0.48 CPU-s of a warm
            # xu1998 run's 5.8)
            entry = json.loads(p.read_text())
            if not isinstance(entry, dict) or entry.get("format") != FORMAT:
                problem = "unknown entry format"
            elif entry.get("key") != key:
                problem = f"the entry is keyed {str(entry.get('key'))[:12]}..., another case's or code's"
            elif fingerprint.sha_text(stored := fingerprint.canonical_json(entry.get("material"))) != key:
                problem = "its material does not hash to its key"
            elif stored != text:
                problem = "its material differs from this case's"
            elif fingerprint.sha_text(fingerprint.canonical_json(entry.get("result"))) != entry.get("checksum"):
                problem = "its result does not match its checksum (edited or damaged)"
            else:
                problem = _result_problem(entry["result"])
        except (OSError, ValueError, TypeError, KeyError, RecursionError) as exc:
            problem = f"unreadable ({type(exc).__name__}: {exc})"
        if problem is not None:
            self.rejected += 1
            msg = f"cache entry {p.name} for case {case.case_id} refused: {problem}; recomputing"
            self.problems.append(msg)
            self._warn(msg)
            return None
        r = entry["result"]
        if r["status"] != "ok":
            return None
        self.hits += 1
        return CaseResult(case, r["status"], r["rows"], r["curves"], r["wall_time_s"], r.get("error", ""),
                          cached=True, sim_times=r.get("sim_times", []))

    def put(self, res: CaseResult) -> None:
        """Store a successful result under its key (other entries are left alone)."""
        if not self.enabled or res.status != "ok":
            return
        material = key_material(res.case)
        key = fingerprint.sha(material)
        payload = _result_payload(res)
        entry = {"format": FORMAT, "key": key, "material": material, "case_id": res.case.case_id,
                 "study": res.case.study, "result": payload, "checksum": fingerprint.sha(payload)}
        text = json.dumps(entry, allow_nan=True)
        atomic_write(self.path(key), lambda t: Path(t).write_text(text))
        self.written += 1


def _result_problem(r) -> str | None:
    """What is wrong with the types of a stored result (a forged entry whose checksum was recomputed), or None."""
    if not isinstance(r, dict):
        return f"its result is a {type(r).__name__}, not a mapping"
    if not isinstance(r.get("status"), str):
        return "its result has no status"
    for key in ("rows", "curves"):
        v = r.get(key)
        if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
            return f"its result's {key!r} is not a list of rows"
    if isinstance(r.get("wall_time_s"), bool) or not isinstance(r.get("wall_time_s"), (int, float)):
        return "its result's wall time is not a number"
    if not all(isinstance(row.get("metric"), str) for row in r["rows"]):
        return "a row of its result has no metric"
    return None


def entries(folder: Path) -> Iterable[Path]:
    return sorted(Path(folder).glob("??/*.json"))


def prune(folder: Path, keep: set[str], dry_run: bool = False) -> list[Path]:
    """Delete the entries whose key is not in ``keep`` (and stale temporaries); returns them."""
    from jointbench.core.errors import OutputError

    sweep_stale_temps(folder, recursive=True)
    gone = [p for p in entries(folder) if p.stem not in keep]
    if not dry_run:
        for i, p in enumerate(gone):
            try:
                p.unlink(missing_ok=True)
            except OSError as exc:
                raise OutputError(f"{folder}: cannot remove cache entries ({exc.strerror or exc}; {i} of "
                                  f"{len(gone)} removed); make the cache writable, or run without prune") from None
    return gone
