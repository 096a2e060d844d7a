"""Run history (SQLite), the verified case cache and its key, ``jointbench history/diff/cache``."""
from __future__ import annotations

import dataclasses
import json
import re
import shutil
import sqlite3
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.harness import fingerprint
from jointbench.benchmarks.harness.cache import Cache, case_key
from jointbench.benchmarks.harness.history import History
from jointbench.benchmarks.runner import expand, run_cases
from jointbench.benchmarks.study import run_study
from tests.harness_studies import REPO, tiny_grid_part, tiny_study


def test_swapped_cache_entry_is_detected_and_recomputed(tmp_path, capsys):
    cases = expand(load_study(tiny_study(tmp_path / "cfg", seeds=2)))
    cache = Cache(tmp_path / "cache")
    first = run_cases(cases, cache, serial=True, progress=False)
    a, b = (cache.path(case_key(c)) for c in cases)
    shutil.copyfile(a, b)                                  # seed 0's entry now sits in seed 1's file
    again = Cache(tmp_path / "cache")
    second = run_cases(cases, again, serial=True, progress=False)
    assert again.hits == 1 and again.rejected == 1
    assert "for case fit-seed1 refused: the entry is keyed" in capsys.readouterr().err
    assert [r.rows for r in second] == [r.rows for r in first]          # recomputed, not served
    assert not second[1].cached and second[0].cached
    assert Cache(tmp_path / "cache").get(cases[1]).rows == first[1].rows  # and the entry repaired


def test_edited_or_damaged_entry_is_refused(tmp_path):
    cases = expand(load_study(tiny_study(tmp_path / "cfg", seeds=1)))
    cache = Cache(tmp_path / "cache")
    run_cases(cases, cache, serial=True, progress=False)
    p = cache.path(case_key(cases[0]))
    entry = json.loads(p.read_text())
    entry["result"]["rows"][0]["value"] += 1.0
    p.write_text(json.dumps(entry))
    c = Cache(tmp_path / "cache", warn=lambda m: None)
    assert c.get(cases[0]) is None and "checksum" in c.problems[0]
    p.write_text(p.read_text()[:100])
    assert c.get(cases[0]) is None and "unreadable" in c.problems[1]


def test_canonical_text_survives_a_json_round_trip():
    obj = {"variance_ratio": {5: 0.11, 10: 0.034}, "snr": float("inf"), "t": (1, 2), "p": Path("x")}
    back = json.loads(json.dumps(obj, default=str))
    assert fingerprint.canonical(obj) == fingerprint.canonical(back)
    assert fingerprint.sha(obj) == fingerprint.sha(back)


def test_a_case_with_number_keys_is_served_from_the_cache(tmp_path):
    """vanderuit2018_table1's params map SNR levels (numbers) to variance ratios: its entries must verify
    (they did not, and every run recomputed its 240 cases)."""
    from jointbench.benchmarks.harness.case import CaseResult

    case = expand(load_study(tiny_study(tmp_path / "cfg", seeds=1)))[0]
    case = dataclasses.replace(case, params={"levels": {5: 0.11, 10: 0.034}})
    rows = [{"estimator": "e", "metric": "K", "value": 1.0}]
    Cache(tmp_path / "cache").put(CaseResult(case, "ok", rows, [], 0.1))
    again = Cache(tmp_path / "cache", warn=lambda m: None)
    got = again.get(case)
    assert got is not None and got.rows == rows and again.rejected == 0, again.problems


def test_key_has_no_paths_but_everything_a_protocol_sees(tmp_path):
    one = expand(load_study(tiny_study(tmp_path / "a", seeds=2)))
    two = expand(load_study(tiny_study(tmp_path / "elsewhere" / "b", seeds=2)))   # same study, other folder
    assert [c.where for c in one] != [c.where for c in two]
    assert [case_key(c) for c in one] == [case_key(c) for c in two]
    assert case_key(one[0]) != case_key(one[1])                                    # seed
    other = expand(load_study(tiny_study(tmp_path / "c", seeds=1, duration="5 s")))
    assert case_key(other[0]) != case_key(one[0])                                  # experiment
    for c in one:
        assert str(tmp_path) not in fingerprint.canonical(c.key_material())


def test_put_never_deletes_other_entries(tmp_path, monkeypatch):
    cases = expand(load_study(tiny_study(tmp_path / "cfg", seeds=1)))
    run_cases(cases, Cache(tmp_path / "cache"), serial=True, progress=False)
    monkeypatch.setattr(fingerprint, "code_hash", lambda: "edited-code")
    monkeypatch.setattr(fingerprint, "case_code_hash", lambda entries=(): "edited-code")
    run_cases(cases, Cache(tmp_path / "cache"), serial=True, progress=False)
    assert len(list((tmp_path / "cache").glob("??/*.json"))) == 2


def test_code_hash_covers_what_computes_a_case_and_nothing_else():
    shared = {p.relative_to(REPO).as_posix() for p in fingerprint.case_modules()}
    assert {"benchmarks/harness/case.py", "sims/backend_ltv.py", "jointbench/core/schema.py",
            "estimators/__init__.py", "benchmarks/protocols/__init__.py"} <= shared
    # protocols and estimators are registered lazily: each case's key adds only its own
    assert not {f for f in shared if f.startswith(("benchmarks/protocols/", "benchmarks/studies/", "estimators/",
                                                   "benchmarks/compare/")) and not f.endswith("__init__.py")}
    files = {p.relative_to(REPO).as_posix() for p in fingerprint.case_modules(
        "jointbench.benchmarks.studies.xu1998.protocol", "jointbench.estimators.kbr")}
    assert shared | {"benchmarks/metrics.py", "benchmarks/studies/xu1998/protocol.py", "estimators/kbr.py",
                     "estimators/_kbr_solve.py", "estimators/fsewls.py"} <= files   # xu1998 imports fsewls
    assert not files & {"estimators/skirt.py", "estimators/sds.py", "benchmarks/studies/westwick2012/protocol.py"}
    assert not {f for f in files if f.startswith(("benchmarks/figures/", "benchmarks/nightly"))
                or f.endswith("/figures.py")}
    assert not files & {"benchmarks/report.py", "benchmarks/tables.py", "jointbench/cli/studies.py",
                        "benchmarks/config.py", "benchmarks/study.py", "benchmarks/runner.py",
                        "benchmarks/harness/cache.py"}


def test_a_case_names_its_protocol_and_estimator_modules(tmp_path):
    cases = expand(load_study(tiny_study(tmp_path, seeds=1, extra_parts={"grid": tiny_grid_part(["sds"])})))
    assert cases[0].code_modules() == ("jointbench.benchmarks.protocols.generic", "jointbench.estimators.ibk_spectral")
    assert cases[-1].code_modules() == ("jointbench.benchmarks.compare.protocol", "jointbench.estimators.sds")
    named = dataclasses.replace(cases[0], params={"estimators_without_noise": {"kbr": {}}})
    assert "jointbench.estimators.kbr" in named.code_modules()        # made by name in a protocol


def test_module_hash_follows_meaning_not_text(tmp_path):
    a, b, c = (tmp_path / f"{n}.py" for n in "abc")
    a.write_text('"""Doc."""\nimport math\n\n\ndef f(x):\n    """Twice."""\n    return 2 * x  # double\n')
    b.write_text('"""Another doc."""\nimport math\n# a comment\ndef f(x):\n\n    return 2 * x\n')
    c.write_text('"""Doc."""\nimport math\n\n\ndef f(x):\n    """Twice."""\n    return 3 * x  # double\n')
    assert fingerprint.module_hash(a) == fingerprint.module_hash(b) != fingerprint.module_hash(c)


def test_module_facts_are_remembered_by_content_and_a_damaged_memo_is_ignored(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(fingerprint, "_MEMO", {})
    monkeypatch.setattr(fingerprint, "_MEMO_STATE", {"loaded": False, "dirty": False})
    fingerprint.forget()
    mod = tmp_path / "m.py"
    mod.write_text("import math\nX = 1\n")
    first = fingerprint.case_code_hash(("jointbench.estimators.kbr",)), fingerprint.module_hash(mod)
    fingerprint.hash_modules({"m": mod})                                  # writes the memo
    memo = fingerprint._memo_file()
    assert memo.is_file() and str(tmp_path / "cache") in str(memo) and len(json.loads(memo.read_text())) > 20
    memo.write_text("{not json")                                           # damaged: ignored, rewritten
    monkeypatch.setattr(fingerprint, "_MEMO", {})
    monkeypatch.setattr(fingerprint, "_MEMO_STATE", {"loaded": False, "dirty": False})
    fingerprint.forget()
    assert (fingerprint.case_code_hash(("jointbench.estimators.kbr",)), fingerprint.module_hash(mod)) == first
    mod.write_text("import math\nX = 2\n")                                # new content, new key
    fingerprint.forget()
    assert fingerprint.module_hash(mod) != first[1]
    fingerprint.forget()


@pytest.fixture
def code_copy(tmp_path, monkeypatch):
    """A copy of the code packages that the hasher reads instead of the checkout (the running code is
    the checkout's: only the keys see the copy)."""
    root = tmp_path / "code"
    for folder in fingerprint.PACKAGES:
        shutil.copytree(REPO / folder, root / folder, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    monkeypatch.setattr(fingerprint, "package_root", lambda package: root / fingerprint.PACKAGE_DIRS[package])
    fingerprint.forget()
    yield root
    fingerprint.forget()


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text, f"{path}: {old!r} not found"
    path.write_text(text.replace(old, new, 1))
    fingerprint.forget()


def _two_estimator_study(folder: Path) -> list:
    """Cases of ibk_spectral (a fit part and two grid cases) and of sds (two grid cases)."""
    return expand(load_study(tiny_study(folder, seeds=2, extra_parts={
        "grid": tiny_grid_part(["ibk_spectral", "sds"], realizations=2)})))


def test_a_comment_or_docstring_edit_computes_no_case(tmp_path, code_copy, capsys):
    """A run after comment, docstring and layout edits of shared, protocol and estimator modules, and
    code edits of a figure and the report, serves every case from the cache (and says so)."""
    from jointbench.cli import main

    study = tiny_study(tmp_path / "cfg", seeds=2, extra_parts={
        "grid": tiny_grid_part(["ibk_spectral", "sds"], realizations=2)})
    cases = expand(load_study(study))
    keys = [case_key(c) for c in cases]
    run = ["run", str(study), "--out", str(tmp_path / "out"), "--serial", "--quiet"]
    assert main(run) == 0
    assert "tiny: 6 cases (0 from cache, 6 computed), 0 failed" in capsys.readouterr().out
    _edit(code_copy / "estimators/ibk_spectral.py", "\nMAX_GROUPS = 20",
          "\n# a new comment\n\nMAX_GROUPS = 20  # groups")
    _edit(code_copy / "estimators/sds.py", '"""', '"""A rewritten first line.\n\n')
    _edit(code_copy / "sims/experiment.py", "\ndef ", "\n# shared code, comment only\ndef ")
    _edit(code_copy / "benchmarks/compare/protocol.py", "\ndef ", "\n\n\n# a protocol's comment\ndef ")
    _edit(code_copy / "benchmarks/harness/case.py", "    def code_modules(self)",
          "    # a comment in the case module\n    def code_modules(self)")
    for never in ("benchmarks/studies/westwick2012/figures.py", "benchmarks/report.py"):    # code, but never in a key
        _edit(code_copy / never, "\ndef ", "\n_CHANGED = 1\n\n\ndef ")
    assert [case_key(c) for c in cases] == keys
    assert main(run) == 0
    assert "tiny: 6 cases (6 from cache, 0 computed), 0 failed" in capsys.readouterr().out


def test_a_changed_constant_in_one_estimator_recomputes_exactly_its_cases(tmp_path, code_copy):
    cases = _two_estimator_study(tmp_path / "cfg")
    keys = [case_key(c) for c in cases]
    run_cases(cases, Cache(tmp_path / "cache"), serial=True, progress=False)
    _edit(code_copy / "estimators/ibk_spectral.py", "\nMAX_GROUPS = 20", "\nMAX_GROUPS = 21")
    changed = [case_key(c) != k for c, k in zip(cases, keys)]
    assert changed == ["ibk_spectral" in c.estimators for c in cases] and sum(changed) == 4
    cache = Cache(tmp_path / "cache")
    again = run_cases(cases, cache, serial=True, progress=False)
    assert [not r.cached for r in again] == changed and cache.hits == 2 and cache.written == 4
    _edit(code_copy / "sims/experiment.py", "\ndef ", "\n_SHARED_CHANGE = 1\n\n\ndef ")   # shared code:
    assert not {case_key(c) for c in cases} & set(keys)                            # every key changes


def test_every_module_a_case_loads_is_hashed(tmp_path):
    """The static closure is checked against what a case really imports, in a fresh interpreter that
    imports only the case module: the shared closure and the case's protocol and estimator modules."""
    case = expand(load_study(tiny_study(tmp_path, seeds=1)))[0]
    code = textwrap.dedent("""
        import json, sys
        from jointbench.benchmarks.harness.case import Case, run_case
        res = run_case(Case(**json.loads(sys.argv[1])))
        assert res.status == "ok", res.error
        print(json.dumps(sorted(m.__file__ for m in list(sys.modules.values()) if getattr(m, "__file__", None))))
    """)
    out = subprocess.run([sys.executable, "-c", code, json.dumps(case.spec())], cwd=REPO, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    loaded = {Path(f).resolve() for f in json.loads(out.stdout)}
    ours = {p for p in loaded if REPO in p.parents and p.parts[len(REPO.parts)] in fingerprint.PACKAGES}
    assert len(ours) > 20
    missing = ours - set(fingerprint.case_modules(*case.code_modules()))
    assert not missing, f"loaded by a case but not in the code hash: {sorted(missing)}"


def test_history_records_runs_and_a_crash_mid_write_leaves_no_half_run(tmp_path):
    study = tiny_study(tmp_path / "cfg", seeds=2)
    out = tmp_path / "out"
    run = run_study(study, out_root=out, serial=True, progress=False)
    code = textwrap.dedent(f"""
        import os
        from jointbench.benchmarks.harness.history import History
        from jointbench.benchmarks.study import run_study
        h = History.finish_run
        def crash(self, run_id, status, results, *a, **k):
            real = self.db.executemany
            calls = []
            class DB:
                def __getattr__(s, name):
                    return getattr(real.__self__, name)
                def executemany(s, sql, rows):
                    real(sql, rows)
                    if sql.startswith("INSERT INTO results"):
                        os._exit(9)           # killed inside the final transaction
            self.db = DB()
            return h(self, run_id, status, results, *a, **k)
        History.finish_run = crash
        run_study({str(study)!r}, out_root=__import__("pathlib").Path({str(out)!r}), serial=True, progress=False)
    """)
    p = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert p.returncode == 9, p.stderr
    with History(out / "history.sqlite") as h:
        runs = h.runs().sort_values("id")
        assert list(runs["status"]) == ["ok", "crashed"]
        assert len(h.cases(run.run_id)) == 2 and len(h.rows(run.run_id)) > 0
        crashed = int(runs["id"].iloc[1])
        assert h.cases(crashed).empty and h.rows(crashed).empty and h.checks(crashed).empty
        r = h.run(run.run_id)
        assert r["environment"]["numpy"] and r["code_hash"] == fingerprint.code_hash() and r["parts"] == ["fit"]
    with sqlite3.connect(out / "history.sqlite") as db:
        assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"


def test_history_and_diff_commands(tmp_path, capsys, monkeypatch):
    from jointbench.cli import main

    study = tiny_study(tmp_path / "cfg", seeds=2)
    out = tmp_path / "out"
    run_study(study, out_root=out, serial=True, progress=False)
    monkeypatch.setattr(fingerprint, "code_hash", lambda: "a-new-version")
    monkeypatch.setattr(fingerprint, "case_code_hash", lambda entries=(): "a-new-version")
    run_study(study, out_root=out, serial=True, progress=False)       # recomputed under new "code"
    with sqlite3.connect(out / "history.sqlite") as db:                # ... which changed one metric
        db.execute("UPDATE results SET value = value + 1 WHERE run_id = 2 AND metric = 'B'")
    capsys.readouterr()
    assert main(["history", "--out", str(out)]) == 0
    listing = capsys.readouterr().out
    assert "tiny" in listing and listing.count(" ok ") == 2
    assert main(["history", "2", "--out", str(out)]) == 0
    shown = capsys.readouterr().out
    assert "run 2 (run): study tiny, status ok" in shown and "T-K" in shown and "a-new-version" in shown
    assert re.search(r"T-K\s+sanity\s+fit\s+pass", shown)          # each check with its kind of evidence
    assert main(["diff", "1", "2", "--out", str(out), "--strict"]) == 1
    d = capsys.readouterr().out
    assert "a-new-version" in d and re.search(r"fit\s+ibk_spectral\s+B\s+2\s+1.0\s", d)
    assert "drifted beyond their threshold: fit/ibk_spectral:B" in d
    assert main(["history", "9", "--out", str(out)]) == 2
    assert "no run 9 (runs 1 to 2)" in capsys.readouterr().err


def test_cache_prune_keeps_what_recent_runs_used(tmp_path, capsys, monkeypatch):
    from jointbench.cli import main

    study = tiny_study(tmp_path / "cfg", seeds=2)
    out = tmp_path / "out"
    run_study(study, out_root=out, serial=True, progress=False)
    monkeypatch.setattr(fingerprint, "code_hash", lambda: "newer")
    monkeypatch.setattr(fingerprint, "case_code_hash", lambda entries=(): "newer")
    run_study(study, out_root=out, serial=True, progress=False)
    assert len(list((out / "cache").glob("??/*.json"))) == 4
    assert main(["cache", "prune", "--keep-runs", "1", "--out", str(out)]) == 0
    assert "removed 2 of 4 entries" in capsys.readouterr().out
    left = {p.stem for p in (out / "cache").glob("??/*.json")}
    assert left == {case_key(c) for c in expand(load_study(study))}


def test_unknown_history_is_one_line(tmp_path, capsys):
    from jointbench.cli import main

    assert main(["history", "--out", str(tmp_path)]) == 2
    assert "no run history yet" in capsys.readouterr().err


def test_regenerated_reports_do_not_make_a_run_dirty(tmp_path, monkeypatch):
    """Dirty = uncommitted changes to tracked files outside results/, or new files in the code."""
    git = lambda *a: subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *a], cwd=tmp_path,  # noqa: E731
                                    check=True, capture_output=True)
    git("init", "-q")
    (tmp_path / "results" / "s").mkdir(parents=True)
    (tmp_path / "results" / "s" / "report.md").write_text("old")
    (tmp_path / "sims").mkdir()
    (tmp_path / "sims" / "a.py").write_text("x = 1\n")
    git("add", ".")
    git("commit", "-qm", "c")
    monkeypatch.setattr(fingerprint, "REPO", tmp_path)
    assert fingerprint.git_state()[1] is False
    (tmp_path / "results" / "s" / "report.md").write_text("regenerated")
    assert fingerprint.git_state()[1] is False and not fingerprint.git_commit().endswith("-dirty")
    (tmp_path / "sims" / "new_model.py").write_text("y = 2\n")
    assert fingerprint.git_state()[1] is True
    (tmp_path / "sims" / "new_model.py").unlink()
    (tmp_path / "sims" / "a.py").write_text("x = 2\n")
    assert fingerprint.git_commit().endswith("-dirty")


def test_a_version_1_history_gains_the_evidence_of_each_check(tmp_path):
    """Histories written before checks recorded their kind of evidence are upgraded in place: old
    runs keep their checks (evidence NULL, shown as 'unrecorded'), new runs record it."""
    from jointbench.benchmarks.harness.diff import diff_runs
    from jointbench.benchmarks.harness.history import SCHEMA

    path = tmp_path / "history.sqlite"
    v1 = SCHEMA.replace("note TEXT, evidence TEXT, PRIMARY KEY", "note TEXT, PRIMARY KEY")
    assert v1 != SCHEMA
    with sqlite3.connect(path) as db:
        db.executescript(v1)
        db.execute("INSERT INTO meta VALUES ('schema_version', '1')")
    study = tiny_study(tmp_path / "cfg", seeds=1)
    old = run_study(study, out_root=tmp_path, serial=True, progress=False)   # opens (and upgrades) it
    with sqlite3.connect(path) as db:
        assert db.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone() == ("2",)
        db.execute("UPDATE checks SET evidence = NULL WHERE run_id = ?", (old.run_id,))   # as a v1 run
    new = run_study(study, out_root=tmp_path, serial=True, progress=False, use_cache=False)
    with History(path) as h:
        assert list(h.checks(new.run_id)["evidence"]) == list(new.checks["evidence"]) == ["sanity", "sanity"]
        assert h.checks(old.run_id)["evidence"].isna().all()
        d = diff_runs(h, old.run_id, new.run_id)
    assert list(d.checks["evidence"]) == ["sanity", "sanity"] and d.flipped.empty
