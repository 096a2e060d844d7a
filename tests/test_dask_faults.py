"""Dask and executor faults end to end (issue 20): a lost scheduler stops the run with one line and exit 75,
keeping every finished case (a group of cases sharing one response too) and recording the run as
interrupted, and the next run resumes; an unreachable, malformed or non-Dask address is one line before
anything runs; a lost worker is survived with identical rows and the report says what ran; a worker with
other code is refused in one line; an absurd worker count is refused.

The clusters are real processes on this machine (``dask scheduler`` and ``dask worker``), so that the test
can kill one; each study is small (seconds)."""
from __future__ import annotations

import os
import re
import signal
import socket
import sqlite3
import subprocess
import sys
import threading
from pathlib import Path

import pandas as pd
import pytest

from tests.harness_studies import (REPO, cache_entries, cli_env, cli_here, start, tiny_grid_part, tiny_study,
                                   wait_for)

pytest.importorskip("dask.distributed")
pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses POSIX signals")


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Cluster:
    """A Dask scheduler and workers as separate processes (each in its own process group)."""

    def __init__(self, folder: Path, workers: int = 1, worker_env: dict | None = None):
        self.folder, self.procs = folder, []
        folder.mkdir(parents=True, exist_ok=True)
        self.address = f"tcp://127.0.0.1:{_port()}"
        self.scheduler = self._spawn("scheduler", ["scheduler", "--host", "127.0.0.1", "--port",
                                                   self.address.rsplit(":", 1)[1], "--no-dashboard"], "Scheduler at")
        # --no-nanny: the worker is the process started here (a nanny would start it in a second process,
        # importing everything again: 2 CPU-s a worker); killing its process group loses it all the same
        self.workers = [self._spawn(f"worker{i}", ["worker", self.address, "--nthreads", "1", "--no-dashboard",
                                                   "--no-nanny", "--death-timeout", "60"], "Registered to",
                                    worker_env)
                        for i in range(workers)]

    def _spawn(self, name: str, args: list[str], ready: str, env: dict | None = None) -> subprocess.Popen:
        log = self.folder / f"{name}.log"
        p = subprocess.Popen([sys.executable, "-m", "dask", *args], cwd=REPO, stdout=open(log, "w"),
                             stderr=subprocess.STDOUT, env={**cli_env(), **(env or {})}, start_new_session=True)
        self.procs.append(p)
        assert wait_for(lambda: ready in log.read_text(errors="replace") or p.poll() is not None, 120), log.read_text()
        assert p.poll() is None, log.read_text()
        return p

    @staticmethod
    def kill(p: subprocess.Popen) -> None:
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        p.wait(30)

    def close(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                self.kill(p)


@pytest.fixture
def cluster(tmp_path):
    made = []

    def make(**kw) -> Cluster:
        made.append(Cluster(tmp_path / f"cluster{len(made)}", **kw))
        return made[-1]
    yield make
    for c in made:
        c.close()


def _statuses(out: Path) -> list[tuple[str, int, int]]:
    with sqlite3.connect(out / "history.sqlite") as db:
        return db.execute("SELECT status, n_done, n_failed FROM runs ORDER BY id").fetchall()


def _error_lines(text: str) -> list[str]:
    return [ln for ln in text.splitlines() if ln.strip()]


def test_a_lost_scheduler_stops_the_run_in_one_line_and_the_next_run_resumes(tmp_path, cluster):
    seeds = 16
    study = tiny_study(tmp_path / "cfg", seeds=seeds, duration="60 s")
    out = tmp_path / "out"
    c = cluster(workers=1)              # what a lost scheduler does to the run does not depend on its workers
    p = start("run", study, "--out", out, "--quiet", "--executor", "dask", "--scheduler", c.address,
              log=tmp_path / "run.log")
    assert wait_for(lambda: len(cache_entries(out)) >= 2 or p.poll() is not None, 300)
    assert p.poll() is None, "the run ended before the scheduler was killed"
    Cluster.kill(c.scheduler)
    p.wait(120)
    log = (tmp_path / "run.log").read_text()
    assert p.returncode == 75, log
    lines = _error_lines(log)
    assert len(lines) == 1 and "Traceback" not in log, log
    m = re.fullmatch(rf"jointbench: error: lost the scheduler at {re.escape(c.address)} after (\d+) of {seeds} "
                     r"cases; run again to resume \(history run 1\)", lines[0])
    assert m, lines[0]
    kept = int(m.group(1))
    assert 2 <= kept < seeds and len(cache_entries(out)) >= kept
    [(status, n_done, n_failed)] = _statuses(out)
    assert status == "interrupted" and n_failed == 0          # unfinished cases are not failures
    assert not (out / "tiny" / "cases.csv").exists()          # no report of a half run
    # The next run serves the cases the Dask worker stored and computes the rest. It runs in this process: the
    # cache is read by the run's own process before any executor sees a case (benchmarks.runner.run_cases),
    # so a second cluster and a second interpreter (7 CPU-s) would check nothing more.
    r = cli_here("run", study, "--out", out, "--quiet", "--serial")
    assert r.returncode == 0, r.stderr
    n_cached = int(re.search(r"(\d+) from cache", r.stdout).group(1))
    assert n_cached >= kept, r.stdout


def test_a_lost_scheduler_keeps_what_finished_of_a_group_sharing_one_response(tmp_path, cluster):
    """One task (five estimators on one simulated response): the worker stores each case as it finishes,
    so the cases done before the scheduler is lost are kept, though the task never returned."""
    part = tiny_grid_part(["ibk_spectral", "ibk_irf", "irf2_ls", "spectral", "irf2_corr"], realizations=4,
                          noise=[0.05])
    part["scenarios"]["elbow"]["experiment"]["duration"] = "40 s"
    study = tiny_study(tmp_path / "cfg", seeds=1, extra_parts={"grid": part})
    out = tmp_path / "out"
    c = cluster(workers=1)
    p = start("run", study, "--parts", "grid", "--out", out, "--quiet", "--yes", "--executor", "dask",
              "--scheduler", c.address, log=tmp_path / "run.log")
    assert wait_for(lambda: len(cache_entries(out)) >= 1 or p.poll() is not None, 300)
    assert p.poll() is None, "the group finished before the scheduler was killed"
    Cluster.kill(c.scheduler)
    p.wait(120)
    log = (tmp_path / "run.log").read_text()
    assert p.returncode == 75, log
    m = re.search(r"lost the scheduler at \S+ after (\d+) of 5 cases; run again to resume", log)
    assert m and int(m.group(1)) >= 1, log
    assert len(cache_entries(out)) >= 1
    assert _statuses(out)[0][0] == "interrupted"


def _numbers(path: Path) -> pd.DataFrame:
    rows = pd.read_csv(path)
    rows = rows[rows["metric"] != "fit_time_s"].drop(columns=["wall_time_s", "sim_time_s", "git_commit"],
                                                     errors="ignore")
    return rows.sort_values(["part", "case_id", "estimator", "metric"], kind="stable").reset_index(drop=True)


def test_a_lost_worker_is_survived_with_identical_rows_and_the_report_says_so(tmp_path, cluster):
    study = tiny_study(tmp_path / "cfg", seeds=12, duration="60 s")
    serial = cli_here("run", study, "--out", tmp_path / "serial", "--quiet", "--serial")
    assert serial.returncode == 0, serial.stderr
    out = tmp_path / "out"
    c = cluster(workers=2)
    p = start("run", study, "--out", out, "--quiet", "--executor", "dask", "--scheduler", c.address,
              log=tmp_path / "run.log")
    assert wait_for(lambda: len(cache_entries(out)) >= 2 or p.poll() is not None, 300)
    assert p.poll() is None, "the run ended before a worker was killed"
    Cluster.kill(c.workers[0])
    p.wait(600)
    log = (tmp_path / "run.log").read_text()
    assert p.returncode == 0, log
    pd.testing.assert_frame_equal(_numbers(out / "tiny" / "cases.csv"),
                                  _numbers(tmp_path / "serial" / "tiny" / "cases.csv"))
    head = next(par for par in (out / "tiny" / "report.md").read_text().split("\n\n") if "wall time on" in par)
    lost = r"wall time on \d Dask worker\(s\) \(tcp://\S+\); 1 of the 2 seen were lost during the run"
    assert re.search(lost, head), head
    assert "on 2 worker(s)" not in head


def test_a_worker_with_other_code_is_refused_in_one_line(tmp_path, cluster):
    patch = tmp_path / "other"
    patch.mkdir()
    (patch / "sitecustomize.py").write_text(
        "import jointbench.benchmarks.harness.fingerprint as f\n"
        "_code = f.code_hash\n"
        "f.code_hash = lambda: 'other' + _code()[5:]\n")
    study = tiny_study(tmp_path / "cfg", seeds=2)
    c = cluster(workers=1, worker_env={"PYTHONPATH": str(patch)})
    # the run in this process (its refusal is the point, not its process: an interpreter's start-up saved)
    r = cli_here("run", study, "--out", tmp_path / "out", "--quiet", "--executor", "dask", "--scheduler", c.address)
    assert r.returncode == 2, r.stderr
    lines = _error_lines(r.stderr)
    assert len(lines) == 1 and re.match(r"jointbench: error: worker tcp://127\.0\.0\.1:\d+ runs other code \(code hash "
                                        r"other\w+, the run's \w+\): install the same checkout on every worker$",
                                        lines[0]), r.stderr


def test_a_worker_joining_later_with_other_libraries_refuses_its_task():
    from jointbench.benchmarks.harness.fingerprint import code_hash, key_environment
    from jointbench.benchmarks.harness.pool import run_task
    from jointbench.benchmarks.harness.workers import WorkerMismatch

    with pytest.raises(WorkerMismatch, match=r"runs other library versions: numpy \S+ \(the run's 0\.0\.1\); "
                                             r"install the same versions on every worker"):
        run_task([], code_hash(), {**key_environment(), "numpy": "0.0.1"})


def test_an_unreachable_scheduler_is_one_line_before_anything_runs(tmp_path):
    address = f"tcp://127.0.0.1:{_port()}"
    r = cli_here("run", tiny_study(tmp_path / "cfg"), "--out", tmp_path / "out", "--quiet", "--executor", "dask",
            "--scheduler", address, timeout=120)
    assert r.returncode == 2 and len(_error_lines(r.stderr)) == 1, r.stderr
    assert r.stderr.startswith(f"jointbench: error: --scheduler {address}: cannot reach a Dask scheduler there")
    assert not (tmp_path / "out" / "history.sqlite").exists()


@pytest.mark.parametrize("address, words", [
    ("foo:bar", "not an address"), ("tcp://", "not an address"), ("tcp://127.0.0.1:notaport", "not an address"),
    ("http://127.0.0.1:8786", "unknown scheme 'http'"), ("tcp://[::1", "not an address"),
    ("127.0.0.1:99999", "port 99999 is not between 1 and 65535"), ("", "an empty address"),
    ("inproc://x", "inproc:// address"), ("tcp://:8786", "not an address")])
def test_malformed_scheduler_addresses_are_one_line(address, words):
    from jointbench.benchmarks.harness.dask_executor import parse_scheduler
    from jointbench.core.errors import ConfigError

    with pytest.raises(ConfigError, match=re.escape(words)) as err:
        parse_scheduler(address)
    assert "\n" not in str(err.value) and "tcp://10.0.0.5:8786" in str(err.value)


def test_an_empty_scheduler_on_the_command_line_is_refused_not_a_local_cluster(tmp_path):
    r = cli_here("run", tiny_study(tmp_path / "cfg"), "--out", tmp_path / "out", "--executor", "dask",
            "--scheduler", "", timeout=120)
    assert r.returncode == 2 and "--scheduler: expected a non-empty text" in r.stderr \
        and len(_error_lines(r.stderr)) == 1, r.stderr


@pytest.mark.parametrize("reply", [b"\xff" * 64, b"HTTP/1.1 200 OK\r\n\r\n", b""], ids=["0xff", "http", "silent"])
def test_a_server_that_is_not_dask_is_refused_without_reading_it_as_frames(reply, monkeypatch):
    """A reply read as Dask frames would be a frame length of exabytes (0xff...); nothing is allocated: the
    greeting is checked first, and a silent server is given a few seconds (HANDSHAKE_TIMEOUT_S; here half a
    second, which the message names: the shipped 5 s held a test worker idle for 5 s)."""
    from jointbench.benchmarks.harness import dask_executor
    from jointbench.core.errors import ConfigError

    monkeypatch.setattr(dask_executor, "HANDSHAKE_TIMEOUT_S", 0.5)

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(4)
    port = srv.getsockname()[1]

    def serve():
        conns = []
        try:
            while True:
                conn, _ = srv.accept()
                conns.append(conn)
                conn.sendall(reply)
        except OSError:
            pass
    threading.Thread(target=serve, daemon=True).start()
    try:
        with pytest.raises(ConfigError, match=rf"--scheduler tcp://127\.0\.0\.1:{port}: the server there is not a "
                                              r"Dask scheduler \(it (said nothing|answered .*) within 0\.5 s"):
            dask_executor.DaskExecutor(scheduler=f"tcp://127.0.0.1:{port}")
    finally:
        srv.close()


@pytest.mark.parametrize("executor", ["dask", "process"])
def test_an_absurd_worker_count_is_refused(tmp_path, executor):
    r = cli_here("run", tiny_study(tmp_path / "cfg"), "--out", tmp_path / "out", "--quiet", "--executor", executor,
            "--workers", "10000", timeout=120)
    assert r.returncode == 2 and len(_error_lines(r.stderr)) == 1, r.stderr
    assert re.match(r"jointbench: error: --workers 10000: more than 4 worker processes per core", r.stderr)


def test_the_report_says_what_ran(tmp_path):
    from jointbench.benchmarks.study import run_study

    study = tiny_study(tmp_path / "cfg", seeds=2)
    first = run_study(study, out_root=tmp_path / "out", workers=2, progress=False)
    assert "wall time on 2 worker processes." in (first.folder / "report.md").read_text()
    again = run_study(study, out_root=tmp_path / "out", workers=2, progress=False)
    assert "wall time on no worker (every case from the cache)." in (again.folder / "report.md").read_text()
