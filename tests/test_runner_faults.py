"""The runner under the faults that schedulers and impatient people cause (issue 11), each end to end
through the command line in a separate process: kill -9, Ctrl-C, SIGTERM, two runs at once, a read-only
results folder, a kill during a write."""
from __future__ import annotations

import os
import random
import re
import shutil
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from tests.harness_studies import (REPO, alive, cache_entries, children, cli_here, start, start_time, temporaries,
                                   tiny_study, wait_for)

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc and POSIX signals")


def history_cases(out: Path) -> list[tuple[int, str]]:
    with sqlite3.connect(out / "history.sqlite") as db:
        return db.execute("SELECT run_id, case_id FROM cases ORDER BY run_id, case_id").fetchall()


def run_statuses(out: Path) -> list[str]:
    from jointbench.benchmarks.harness.history import History

    with History(out / "history.sqlite") as h:        # opening marks dead 'running' runs as crashed
        return list(h.runs(limit=None).sort_values("id")["status"])


def pool_workers(pid: int, timeout: float = 300) -> dict[int, int]:
    """The pool workers of run ``pid`` once it has forked them: id -> start time (one process each,
    whatever becomes of the id later). Slow to appear on a loaded machine (imports, the study's set-up);
    the generous wait is not what any test measures."""
    assert wait_for(lambda: len(children(pid)) >= 2, timeout), "the pool never started"
    return {w: start_time(w) for w in children(pid)}


def test_sigkill_at_a_random_point_resumes_without_orphans(tmp_path):
    """kill -9 of the parent at a random point of the sweep: the pool workers exit too (checked by PID
    and start time); the next run resumes from the cache (serving exactly the cases finished before the
    kill, computing the rest) and the history holds every case exactly once (the killed run has none).

    The random point is one of the sweep, not of the clock: after a random number of finished cases
    (0: right after the workers were forked, possibly before their initializer ran) plus a random
    fraction of a case. A point drawn on the clock (it was 0-2 s after the pool started) could land
    after the sweep on a quick or lightly loaded run -- in the final writes, after the history had
    recorded the run (then it holds every case twice) or after the exit -- and so fail, or prove
    nothing about orphans."""
    seeds = 24
    study = tiny_study(tmp_path / "configs", seeds=seeds, duration="120 s")
    out = tmp_path / "out"
    p = start("run", study, "--out", out, "--workers", "2", "--quiet", log=tmp_path / "killed.log")
    workers = pool_workers(p.pid)
    k = random.randint(0, seeds // 3)                 # at least 2/3 of the sweep (16 cases) still to run
    assert wait_for(lambda: len(cache_entries(out)) >= k or p.poll() is not None, 600)
    time.sleep(random.uniform(0.0, 0.1))
    running = [w for w, t in workers.items() if alive(w, t)]
    os.kill(p.pid, signal.SIGKILL)
    t0 = time.monotonic()
    p.wait(30)
    assert p.returncode == -signal.SIGKILL, f"the run ended before the kill (after {k} cases)"
    assert len(workers) == 2 and len(running) == 2, f"workers {workers}: {running} running at the kill"
    gone = wait_for(lambda: not any(alive(w, t) for w, t in workers.items()), 10)
    assert gone, f"workers {[w for w, t in workers.items() if alive(w, t)]} outlived their parent"
    n_kept = len(cache_entries(out))
    assert k <= n_kept < seeds, (k, n_kept)
    print(f"kill -9 after {n_kept} of {seeds} cases: workers {list(workers)} gone {time.monotonic() - t0:.2f} s later")
    # the next run in this process (the signals were the killed run's; a resume is the cache and the history,
    # the same in any process, without 2 CPU-s of another interpreter's start-up)
    r = cli_here("run", study, "--out", out, "--workers", "2", "--quiet")
    assert r.returncode == 0, r.stderr
    assert re.search(rf"{seeds} cases \({n_kept} from cache, {seeds - n_kept} computed\)", r.stdout), (r.stdout, n_kept)
    recorded = history_cases(out)
    case_ids = [c for _, c in recorded]
    assert sorted(case_ids) == sorted(set(case_ids)) and len(case_ids) == seeds, recorded
    assert run_statuses(out) == ["crashed", "ok"]
    assert temporaries(out) == []


@pytest.mark.parametrize("how", ["SIGINT to the process group (Ctrl-C)", "SIGTERM to the parent"])
def test_interrupt_returns_within_2s_and_keeps_finished_cases(tmp_path, how):
    """Ctrl-C or SIGTERM while both workers run cases: the parent exits within 2 s of the signal (its
    own handling: measured from the signal to its exit, as the test's wait for it sees it) and keeps
    every finished case. The signal comes once the workers are at work (two cases done), with most
    of the sweep still to run, whatever the machine's speed or load; the wait for that is not timed."""
    seeds = 24
    study = tiny_study(tmp_path / "configs", seeds=seeds, duration="120 s")
    out = tmp_path / "out"
    p = start("run", study, "--out", out, "--workers", "2", log=tmp_path / "run.log")
    workers = pool_workers(p.pid)
    assert wait_for(lambda: len(cache_entries(out)) >= 2 or p.poll() is not None, 600)
    assert p.poll() is None, "the run finished before it could be interrupted"
    assert all(alive(w, t) for w, t in workers.items())
    t0 = time.monotonic()
    if how.startswith("SIGINT"):
        os.killpg(p.pid, signal.SIGINT)
    else:
        os.kill(p.pid, signal.SIGTERM)
    p.wait(30)
    took = time.monotonic() - t0
    log = (tmp_path / "run.log").read_text()
    assert p.returncode == (130 if how.startswith("SIGINT") else 143), log
    assert took < 2.0, f"took {took:.2f} s to stop"
    m = re.search(r"(interrupted|terminated): (\d+) of (\d+) cases finished and kept \(history run 1\)", log)
    assert m and int(m.group(3)) == seeds, log
    kept = int(m.group(2))
    assert 2 <= kept < seeds and len(cache_entries(out)) == kept
    assert len(history_cases(out)) == kept and run_statuses(out) == ["interrupted"]
    assert wait_for(lambda: not any(alive(w, t) for w, t in workers.items()), 3)
    assert temporaries(out) == []
    print(f"{how}: stopped in {took:.2f} s keeping {kept} of {seeds} cases")
    if how.startswith("SIGINT"):               # resuming is the same after either signal: once is enough
        r = cli_here("run", study, "--out", out, "--workers", "2", "--quiet")       # in this process, as above
        done = f"{seeds} cases ({kept} from cache, {seeds - kept} computed)"
        assert r.returncode == 0 and done in r.stdout, r.stdout + r.stderr


def test_two_concurrent_runs_of_one_study_both_end_well(tmp_path):
    study = tiny_study(tmp_path / "configs", seeds=8, duration="20 s")
    out = tmp_path / "out"
    procs = [start("run", study, "--out", out, "--workers", "1", "--quiet", log=tmp_path / f"run{i}.log")
             for i in range(2)]
    for p in procs:
        p.wait(300)
    logs = [(tmp_path / f"run{i}.log").read_text() for i in range(2)]
    assert [p.returncode for p in procs] == [0, 0], logs
    assert run_statuses(out) == ["ok", "ok"]
    recorded = history_cases(out)
    assert len(recorded) == 16 and len(set(recorded)) == 16          # each run: every case once
    import pandas as pd
    cases = pd.read_csv(out / "tiny" / "cases.csv")
    assert len(cases) and (cases["status"] == "ok").all()
    assert temporaries(out) == []


def _ro_prefix(folder: Path) -> list[str] | None:
    """A command prefix that runs the CLI with ``folder`` read-only (root ignores permission bits:
    a read-only bind mount in a private mount namespace)."""
    if os.geteuid() != 0:
        folder.chmod(0o555)
        return []
    if shutil.which("unshare") is None:
        return None
    script = f'mount --bind "{folder}" "{folder}" && mount -o remount,bind,ro "{folder}" && exec "$@"'
    probe = subprocess.run(["unshare", "-m", "--propagation", "private", "sh", "-c", script, "sh", "true"],
                           capture_output=True)
    return ["unshare", "-m", "--propagation", "private", "sh", "-c", script, "sh"] if probe.returncode == 0 else None


def test_read_only_results_folder_is_one_line_and_exit_2(tmp_path):
    study = tiny_study(tmp_path / "configs", seeds=1)
    out = tmp_path / "out"
    out.mkdir()
    prefix = _ro_prefix(out)
    if prefix is None:
        pytest.skip("cannot make a folder read-only for root here (no unshare or mount namespaces)")
    p = start("run", study, "--out", out, "--quiet", log=tmp_path / "ro.log", prefix=prefix)
    p.wait(120)
    text = (tmp_path / "ro.log").read_text().strip()
    assert p.returncode == 2, text
    assert len(text.splitlines()) == 1 and "Traceback" not in text
    assert text.startswith(f"jointbench: error: {out}: cannot write results here") and "--out" in text


def test_sigkill_during_a_write_leaves_no_stale_temporary(tmp_path):
    """atomic_write: a process killed mid-write leaves its temporary and the old file intact; the next
    writer's sweep removes that temporary (a live writer's is kept), and a run sweeps its folders."""
    from jointbench.core.files import sweep_stale_temps

    target = tmp_path / "report.md"
    target.write_text("old")
    code = textwrap.dedent(f"""
        import time
        from pathlib import Path
        from jointbench.core.files import atomic_write
        def slow(p):
            Path(p).write_text("half")
            print("writing", flush=True)
            time.sleep(60)
        atomic_write(Path({str(target)!r}), slow)
    """)
    p = subprocess.Popen([sys.executable, "-c", code], cwd=REPO, stdout=subprocess.PIPE, text=True)
    live = subprocess.Popen([sys.executable, "-c", code], cwd=REPO, stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "writing" and live.stdout.readline().strip() == "writing"
        os.kill(p.pid, signal.SIGKILL)
        p.wait(10)
        temps = sorted(tmp_path.glob("*.tmp"))
        assert len(temps) == 2 and target.read_text() == "old"
        removed = sweep_stale_temps(tmp_path)
        assert [t.name for t in removed] == [t.name for t in temps if f".{p.pid}." in t.name]
        assert [t.name for t in tmp_path.glob("*.tmp")] == [t.name for t in temps if f".{live.pid}." in t.name]
    finally:
        live.kill()
        live.wait(10)
    sweep_stale_temps(tmp_path)
    assert not list(tmp_path.glob("*.tmp")) and target.read_text() == "old"


def test_interrupt_during_a_write_removes_the_temporary(tmp_path):
    from jointbench.core.files import atomic_write

    def interrupted(p):
        Path(p).write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        atomic_write(tmp_path / "x.csv", interrupted)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("mode", ["prctl and watchdog", "watchdog only"])
def test_pool_workers_exit_when_the_parent_is_killed(tmp_path, mode):
    """Both mechanisms on their own: PR_SET_PDEATHSIG (Linux) and the parent watchdog (portable)."""
    code = textwrap.dedent(f"""
        import time
        from jointbench.benchmarks.harness import pool
        if {mode == "watchdog only"!r}:
            pool.PR_SET_PDEATHSIG = 0x7FFF      # an invalid prctl option: prctl fails, the watchdog remains
        p = pool.WorkerPool(2)
        futs = [p.submit(time.sleep, 60) for _ in range(2)]
        time.sleep(0.5)
        while len(p.worker_pids()) < 2:
            time.sleep(0.05)
        print(*p.worker_pids(), flush=True)
        time.sleep(60)
    """)
    parent = subprocess.Popen([sys.executable, "-c", code], cwd=REPO, stdout=subprocess.PIPE, text=True)
    pids = [int(x) for x in parent.stdout.readline().split()]
    assert len(pids) == 2 and all(alive(w) for w in pids)
    time.sleep(0.6)                                        # the initializers have run
    os.kill(parent.pid, signal.SIGKILL)
    parent.wait(10)
    t0 = time.monotonic()
    assert wait_for(lambda: not any(alive(w) for w in pids), 3), f"orphans: {[w for w in pids if alive(w)]}"
    print(f"{mode}: workers gone {time.monotonic() - t0:.2f} s after the parent's kill -9")
