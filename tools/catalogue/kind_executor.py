"""Executors: Dask schedulers lost, unreachable, malformed or not Dask at all; workers lost or running other
code; absurd worker counts."""
from __future__ import annotations

import time

import pandas as pd

from tools.catalogue import fixtures as fx
from tools.catalogue.core import Outcome, case, kill_group


def _dask():
    try:
        import distributed  # noqa: F401
    except ImportError:
        return "needs dask.distributed"
    return None


def _study(ws, seeds=24, duration="120 s", parts=None):
    exp = dict(fx.EXPERIMENT, duration=duration)
    fx.study(ws, parts=parts or {"fit": fx.fit_part(seeds=seeds, experiment=exp)}, name="s")


def _args(ws, *more):
    return ["run", ws.path("configs", "s.yaml"), "--out", ws.out, "--quiet", *more]


def _wait_log(ws, log, text, timeout=90):
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if text in ws.path(log).read_text(errors="replace"):
            return True
        time.sleep(0.2)
    return False


def scheduler(ws, log="scheduler.log"):
    port = fx.free_port()
    p = ws.spawn([ws.python, "-m", "dask", "scheduler", "--host", "127.0.0.1", "--port", str(port),
                  "--no-dashboard"], log)
    if not _wait_log(ws, log, "Scheduler at"):
        raise RuntimeError("the Dask scheduler did not start")
    return p, f"tcp://127.0.0.1:{port}"


def worker(ws, address, log, env=None):
    p = ws.spawn([ws.python, "-m", "dask", "worker", address, "--nthreads", "1", "--nworkers", "1",
                  "--no-dashboard", "--death-timeout", "30"], log, env=env)
    if not _wait_log(ws, log, "Registered to"):
        raise RuntimeError("a Dask worker did not start")
    return p


def _entries(ws):
    return len(list((ws.out / "cache").glob("??/*.json")))


def _lost_scheduler(group=False):
    def driver(ws):
        if group:
            part = fx.grid_part(estimator=["ibk_spectral", "ibk_irf", "irf2_ls", "spectral", "irf2_corr"],
                                noise=[0.05], variation=["square"])
            part["params"]["realizations"] = 8
            part["scenarios"]["elbow"]["experiment"]["duration"] = "60 s"     # the group takes over a minute
            _study(ws, parts={"grid": part})
        else:
            _study(ws)
        sched, address = scheduler(ws)
        for i in range(2):
            worker(ws, address, f"worker{i}.log")
        t0 = time.monotonic()
        p = ws.start(_args(ws, "--executor", "dask", "--scheduler", address, "--yes"))
        while time.monotonic() - t0 < 120 and p.poll() is None and (_entries(ws) < 3 if not group else
                                                                      _entries(ws) < 1 and time.monotonic() - t0 < 30):
            time.sleep(0.2)                # a group: kill when its first case is stored, or after 30 s
        if p.poll() is not None:
            raise RuntimeError("the run ended before the scheduler could be killed")
        kill_group(sched)
        t_kill = time.monotonic()
        try:
            p.wait(120)
        except Exception:
            kill_group(p)
            return Outcome(None, "", ws.path("run.log").read_text(), time.monotonic() - t0, timed_out=True)
        text = ws.path("run.log").read_text(errors="replace")
        o = Outcome(p.returncode, "", text, time.monotonic() - t_kill)
        kept = _entries(ws)
        if kept == 0:
            o.lost = "nothing of the finished work was kept"
            return o
        # the next run resumes: a new scheduler, the cached cases served
        sched2, address2 = scheduler(ws, "scheduler2.log")
        worker(ws, address2, "worker2.log")
        again = ws.jb(*_args(ws, "--executor", "dask", "--scheduler", address2, "--yes"), timeout=600)
        if again.rc != 0 or f"({kept} from cache" not in again.stdout and "from cache" not in again.stdout:
            o.problem = f"the next run did not resume ({again.rc}): {(again.stdout + again.stderr)[-200:]}"
        if o.rc != 0:
            try:
                import sqlite3
                with sqlite3.connect(ws.out / "history.sqlite") as db:
                    st = db.execute("SELECT status FROM runs ORDER BY id LIMIT 1").fetchone()[0]
                if st != "interrupted":
                    o.problem = o.problem or f"the run was recorded as {st!r}, not interrupted"
            except Exception as exc:  # noqa: BLE001
                o.problem = o.problem or f"no history of the run: {exc}"
        return o
    return driver


kind = "executor"
case(kind, "lost scheduler", driver=_lost_scheduler(), names=r"lost the scheduler.*run again", needs=_dask,
     timeout=900)
case(kind, "lost scheduler during a group sharing one response", driver=_lost_scheduler(group=True),
     names=r"lost the scheduler.*run again", needs=_dask, timeout=900)


def _serial_rows(ws):
    ws.jb(*[a if a != ws.out else ws.path("serial") for a in _args(ws)], "--serial", check=True, timeout=600)


def _numbers(path):
    rows = pd.read_csv(path)
    rows = rows[rows["metric"] != "fit_time_s"].drop(columns=[c for c in ("wall_time_s", "sim_time_s", "git_commit")
                                                                if c in rows])
    return rows.sort_values(list(rows.columns[:5])).reset_index(drop=True)


def _lost_worker(ws):
    _study(ws, seeds=16, duration="60 s")
    _serial_rows(ws)
    sched, address = scheduler(ws)
    workers = [worker(ws, address, f"worker{i}.log") for i in range(2)]
    t0 = time.monotonic()
    p = ws.start(_args(ws, "--executor", "dask", "--scheduler", address))
    while time.monotonic() - t0 < 200 and p.poll() is None and _entries(ws) < 2:
        time.sleep(0.2)
    kill_group(workers[0])
    p.wait(600)
    text = ws.path("run.log").read_text(errors="replace")
    o = Outcome(p.returncode, "", text, time.monotonic() - t0)
    if o.rc == 0:
        try:
            pd.testing.assert_frame_equal(_numbers(ws.out / "cat" / "cases.csv"), _numbers(ws.path("serial", "cat", "cases.csv")))
        except AssertionError as exc:
            o.problem = "rows differ from a serial run: " + str(exc).splitlines()[0]
        report = (ws.out / "cat" / "report.md").read_text()
        if "lost" not in report:
            o.problem = o.problem or "the report does not say a worker was lost (" + \
                next((ln for ln in report.splitlines() if "worker" in ln), "")[-80:] + ")"
    return o


case(kind, "lost worker is survived, rows identical", expect="ok", driver=_lost_worker, needs=_dask, timeout=900)

PATCH = """
import jointbench.benchmarks.harness.fingerprint as f
_orig_code, _orig_env = f.code_hash, f.key_environment
{body}
"""


def _other(body, names):
    def driver(ws):
        _study(ws, seeds=4, duration="8 s")
        ws.path("other").mkdir()
        ws.path("other", "sitecustomize.py").write_text(PATCH.format(body=body))
        sched, address = scheduler(ws)
        worker(ws, address, "worker.log", env={"PYTHONPATH": str(ws.path("other"))})
        return ws.jb(*_args(ws, "--executor", "dask", "--scheduler", address), timeout=300)
    return driver


case(kind, "a worker with other code", driver=_other("f.code_hash = lambda *a, **k: 'other' + _orig_code(*a, **k)[5:]", ""),
     names=r"other code|code hash", needs=_dask, timeout=400)
case(kind, "a worker with other library versions", needs=_dask, timeout=400, names=r"version|other",
     driver=_other("f.key_environment = lambda *a, **k: dict(_orig_env(*a, **k), numpy='0.0.1')", ""))


def _unused_port(ws):
    return f"tcp://127.0.0.1:{fx.free_port()}"


case(kind, "unreachable scheduler", setup=_study, needs=_dask, timeout=120, names=r"127\.0\.0\.1.*(reach|connect)",
     args=lambda ws: _args(ws, "--executor", "dask", "--scheduler", _unused_port(ws)))
for addr in ["foo", "tcp://", "tcp://127.0.0.1:notaport", "http://127.0.0.1:8786", "tcp://[::1", "127.0.0.1:99999",
             "", "tcp://256.1.1.1:8786", "inproc://x", "ucx://127.0.0.1:8786", "tcp://127.0.0.1:-1", " ", "tcp://:8786",
             "tls://127.0.0.1:1"]:
    case(kind, f"--scheduler {addr!r}", setup=_study, needs=_dask, timeout=120,
         names=r"scheduler|address" if not addr.strip() else r"scheduler|address|" + __import__("re").escape(addr),
         args=(lambda a: lambda ws: _args(ws, "--executor", "dask", "--scheduler", a))(addr))


SERVER = """
import socket, sys, threading
s = socket.socket(); s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
s.bind(("127.0.0.1", int(sys.argv[1]))); s.listen(16); print("listening", flush=True)
def serve(c):
    try:
        c.sendall(sys.argv[2].encode().decode("unicode_escape").encode("latin-1"))
        while c.recv(4096):
            pass
    except OSError:
        pass
while True:
    c, _ = s.accept(); threading.Thread(target=serve, args=(c,), daemon=True).start()
"""


def _not_dask(reply):
    def driver(ws):
        _study(ws, seeds=2, duration="4 s")
        port = fx.free_port()
        ws.path("server.py").write_text(SERVER)
        ws.spawn([ws.python, "server.py", str(port), reply], "server.log")
        if not _wait_log(ws, "server.log", "listening", 30):
            raise RuntimeError("the fake server did not start")
        return ws.jb(*_args(ws, "--executor", "dask", "--scheduler", f"tcp://127.0.0.1:{port}"), timeout=120)
    return driver


for name, reply in [("an HTTP server", "HTTP/1.1 200 OK\\r\\nContent-Length: 2\\r\\n\\r\\nhi"),
                    ("a server sending 0xff bytes", "\\xff" * 64), ("a silent server", "")]:
    case(kind, f"--scheduler at {name}", driver=_not_dask(reply), needs=_dask, timeout=200,
         names=r"127\.0\.0\.1.*(Dask|scheduler)")

case(kind, "--executor dask --workers 10000", setup=lambda ws: _study(ws, seeds=2, duration="4 s"), needs=_dask,
     timeout=150, names=r"workers", args=lambda ws: _args(ws, "--executor", "dask", "--workers", "10000"))
case(kind, "--workers 10000 (process pool)", expect="any", setup=lambda ws: _study(ws, seeds=2, duration="4 s"),
     timeout=150, names=r"workers", args=lambda ws: _args(ws, "--workers", "10000"))
case(kind, "--workers 0", setup=_study, names=r"workers", args=lambda ws: _args(ws, "--workers", "0"))
case(kind, "--serial --executor dask", setup=_study, names=r"serial", args=lambda ws: _args(ws, "--serial", "--executor", "dask"))
case(kind, "--scheduler without --executor dask", setup=_study, names=r"scheduler",
     args=lambda ws: _args(ws, "--scheduler", "tcp://127.0.0.1:8786"))
case(kind, "--executor unknown", setup=_study, names=r"executor", args=lambda ws: _args(ws, "--executor", "ray"))
