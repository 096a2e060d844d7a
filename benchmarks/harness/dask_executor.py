"""Cases on a Dask cluster: ``jointbench run STUDY --executor dask [--scheduler ADDRESS]``.

:class:`DaskExecutor` is a ``concurrent.futures`` executor over a ``dask.distributed`` client, so the
runner's loop (:func:`benchmarks.runner.run_cases`) uses it like the process pool: ``submit`` returns a
:class:`concurrent.futures.Future` completed from the Dask future's callback. Without an address it
starts a local cluster (``LocalCluster``: one process per worker, one thread each); with one it connects
to a running scheduler (``dask scheduler`` and ``dask worker ADDRESS --nthreads 1`` on the machines, each
with this checkout installed). Every task runs with one BLAS thread, as in the process pool, so the
numbers are identical, row for row, to a serial run (tests/test_executors.py).

What the cluster does to a run (tests/test_dask_faults.py):

- an address that is malformed, unreachable or not a Dask scheduler (a web server, anything that does
  not greet like one within :data:`HANDSHAKE_TIMEOUT_S`) is one line before anything runs;
- a worker that runs other code or other numerical libraries (its code hash or key environment differs,
  :mod:`benchmarks.harness.fingerprint`) is refused in one line: when the run starts (every worker is
  asked) and in each task (a worker that joins later, :func:`benchmarks.harness.pool.run_task`);
- a lost worker is survived: the scheduler runs its tasks again elsewhere (same numbers), and the report
  says how many workers took part and how many were lost (:meth:`DaskExecutor.describe`);
- a lost scheduler is lost infrastructure, not failed cases: every pending future fails with
  :class:`~benchmarks.harness.workers.ExecutorLost`, on which the runner stops the run with one line
  ("lost the scheduler at ADDRESS after N of M cases; run again to resume"), keeps every finished case
  and records the run as interrupted. Workers store each case in the cache the moment it finishes
  (when the cache folder is theirs too, as on one machine or a shared file system), so a group of cases
  that shares one simulated response keeps what finished.

Dask is an optional dependency (``pip install 'jointbench[dask]'``; ``make test`` installs it).
"""
from __future__ import annotations

import concurrent.futures as cf
import logging
import os
import re
import socket
import struct
import threading

from jointbench.benchmarks.harness.workers import ExecutorLost, WorkerMismatch, identity_problem, worker_identity
from jointbench.core.errors import ConfigError

#: seconds to wait for a remote scheduler before giving up with a one-line error
CONNECT_TIMEOUT_S = 20
#: seconds a server at --scheduler has to greet like a Dask scheduler (it does at once)
HANDSHAKE_TIMEOUT_S = 5
#: schemes of Dask addresses; ``tcp`` when none is given
SCHEMES = ("tcp", "tls", "ws", "wss", "ucx", "inproc")
DEFAULT_PORT = 8786


def parse_scheduler(address: str) -> tuple[str, str, int | None]:
    """``(scheme, host, port)`` of a ``--scheduler`` address such as ``tcp://10.0.0.5:8786`` (or
    ``10.0.0.5:8786``); a one-line error naming the address and the form expected otherwise."""
    form = "expected [tcp://]HOST:PORT, e.g. tcp://10.0.0.5:8786"
    text = address.strip() if isinstance(address, str) else ""
    if not text:
        raise ConfigError(f"--scheduler {address!r}: an empty address; {form}")
    scheme, sep, loc = text.rpartition("://")
    scheme = scheme if sep else "tcp"
    if scheme not in SCHEMES:
        raise ConfigError(f"--scheduler {address}: unknown scheme {scheme!r}; {form} (schemes: {', '.join(SCHEMES)})")
    if scheme == "inproc":
        raise ConfigError(f"--scheduler {address}: an inproc:// address names a scheduler inside another "
                          f"process's memory, unreachable from here; {form}")
    m = re.fullmatch(r"(\[[0-9A-Fa-f:.]+\]|[^:/\[\]\s]+)(?::(\d{1,5}))?", loc)
    if m is None:
        raise ConfigError(f"--scheduler {address}: not an address ({form}; IPv6 in brackets: tcp://[::1]:8786)")
    host, port = m.group(1).strip("[]"), int(m.group(2)) if m.group(2) else DEFAULT_PORT
    if not 1 <= port <= 65535:
        raise ConfigError(f"--scheduler {address}: port {port} is not between 1 and 65535; {form}")
    if scheme == "ucx":
        try:
            from distributed.comm.registry import get_backend
            get_backend("ucx")
        except (ImportError, ValueError):
            raise ConfigError(f"--scheduler {address}: ucx:// needs the ucx backend of Dask (distributed-ucxx), "
                              f"which is not installed; use tcp://") from None
    return scheme, host, port


def probe_scheduler(address: str, scheme: str, host: str, port: int) -> None:
    """Connect to ``host:port`` and check that it greets like a Dask scheduler (a small handshake frame,
    sent at once), before the Dask client reads anything from it: a web server or another program at
    that port would otherwise be read as frame lengths (exabytes) or waited on forever."""
    try:
        sock = socket.create_connection((host, port), timeout=HANDSHAKE_TIMEOUT_S)
    except socket.gaierror as exc:
        raise ConfigError(f"--scheduler {address}: cannot resolve host {host!r} ({exc.strerror or exc})") from None
    except OSError as exc:
        what = "no answer" if isinstance(exc, (socket.timeout, TimeoutError)) else (exc.strerror or str(exc))
        raise ConfigError(f"--scheduler {address}: cannot reach a Dask scheduler there ({what}); is `dask "
                          f"scheduler` running at that address?") from None
    if scheme != "tcp":
        sock.close()
        return                                   # tls/ws: the greeting is encrypted or framed: the client checks
    try:
        sock.settimeout(HANDSHAKE_TIMEOUT_S)
        head = b""
        while len(head) < 8:
            chunk = sock.recv(8 - len(head))
            if not chunk:
                break
            head += chunk
        n = struct.unpack("<Q", head)[0] if len(head) == 8 else -1
        body = b""
        while 0 < n < 65536 and len(body) < n:
            chunk = sock.recv(n - len(body))
            if not chunk:
                break
            body += chunk
    except OSError:
        head, body, n = b"", b"", -1
    finally:
        sock.close()
    if not (0 < n < 65536 and len(body) == n and b"compression" in body):
        seen = "said nothing" if not head else f"answered {head[:16]!r}"
        raise ConfigError(f"--scheduler {address}: the server there is not a Dask scheduler (it {seen} within "
                          f"{HANDSHAKE_TIMEOUT_S} s of connecting; a scheduler greets at once)")


def _on_worker(fn, *args, **kwargs):
    """What a task runs: ``fn`` and the address of the worker that ran it."""
    from distributed import get_worker

    return get_worker().address, fn(*args, **kwargs)


def _quiet_dask() -> None:
    """The client's own logging (reconnect attempts with tracebacks) is not for the user: what a lost
    scheduler means is said in one line by the runner."""
    for name in ("distributed", "distributed.client", "distributed.comm", "distributed.core",
                 "distributed.batched", "distributed.utils"):
        logging.getLogger(name).setLevel(logging.CRITICAL)


class DaskExecutor(cf.Executor):
    """A ``concurrent.futures`` executor on a Dask cluster (local, or at ``scheduler``)."""

    #: the runner passes the cache folder to the tasks: each case is stored on the worker as it finishes
    stores_on_worker = True

    def __init__(self, scheduler: str | None = None, workers: int | None = None, processes: bool = True):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:
            raise ConfigError("--executor dask needs Dask: pip install 'jointbench[dask]' (or dask[distributed])") \
                from None
        _quiet_dask()
        self.cluster = None
        self._closing = False
        self.where = scheduler or "a local cluster"
        if scheduler is not None:
            scheme, host, port = parse_scheduler(scheduler)
            probe_scheduler(scheduler, scheme, host, port)
            try:
                self.client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
            except Exception as exc:  # noqa: BLE001 - any failure to connect (TLS without a context, ...) is one line
                raise ConfigError(f"--scheduler {scheduler}: cannot reach a Dask scheduler there "
                                  f"({type(exc).__name__}: {' '.join(str(exc).split())[:200]})") from None
        else:
            n = workers or os.cpu_count() or 1
            self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=processes,
                                        dashboard_address=None, silence_logs=logging.CRITICAL)
            self.client = Client(self.cluster)
        self._lock = threading.Lock()
        self._pending: dict = {}
        self.used: set[str] = set()
        self.at_start = set(self._workers())
        self._max_workers = max(1, sum(self.client.nthreads().values()))
        if scheduler is not None:
            self.check_workers()

    @property
    def address(self) -> str:
        return self.client.scheduler.address

    def _workers(self) -> list[str]:
        try:
            return list(self.client.scheduler_info().get("workers", {}))
        except Exception:  # noqa: BLE001 - a lost scheduler: no workers known
            return []

    def check_workers(self) -> None:
        """Refuse, before any case runs, a worker that runs other code or other numerical libraries."""
        try:
            theirs = self.client.run(worker_identity)
        except Exception as exc:  # noqa: BLE001 - a worker that cannot even import this checkout
            self.shutdown()
            raise ConfigError(f"--scheduler {self.where}: a worker cannot run jointbench ({type(exc).__name__}: "
                              f"{' '.join(str(exc).split())[:200]}): install the same checkout on every worker") \
                from None
        here = worker_identity()
        for addr, ident in sorted(theirs.items()):
            problem = identity_problem(here, ident, f"worker {addr}")
            if problem:
                self.shutdown()
                raise WorkerMismatch(problem)

    def submit(self, fn, /, *args, **kwargs) -> cf.Future:
        out: cf.Future = cf.Future()
        remote = self.client.submit(_on_worker, fn, *args, pure=False, **kwargs)
        with self._lock:
            self._pending[out] = remote

        def done(d) -> None:
            with self._lock:
                self._pending.pop(out, None)
            if d.cancelled() or d.status == "cancelled":
                if self._closing:
                    out.cancel()
                    out.set_running_or_notify_cancel()
                    return
                if out.set_running_or_notify_cancel():   # not ours: the client lost its scheduler
                    out.set_exception(ExecutorLost(f"lost the scheduler at {self.where}"))
                return
            if not out.set_running_or_notify_cancel():
                return
            try:
                worker, result = d.result()
                self.used.add(worker)
                out.set_result(result)
            except BaseException as exc:  # noqa: BLE001 - the task's error, raised where the result is read
                if d.status != "error" and not self._closing:
                    # the task finished but its result cannot be fetched: the scheduler went away with it
                    out.set_exception(ExecutorLost(f"lost the scheduler at {self.where}"))
                else:
                    out.set_exception(exc)

        remote.add_done_callback(done)
        return out

    def describe(self) -> str:
        """The workers that took part: how many ran tasks, and how many of those seen were lost."""
        alive = set(self._workers())
        seen = self.at_start | self.used
        lost = sorted(seen - alive)
        text = f"{len(self.used)} Dask worker(s) ({self.where})"
        if lost:
            text += f"; {len(lost)} of the {len(seen)} seen were lost during the run and their tasks rerun elsewhere"
        return text

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self._closing = True
        if cancel_futures:
            with self._lock:
                remote = list(self._pending.values())
            if remote and self.client.status == "running":
                try:
                    self.client.cancel(remote)
                except Exception:  # noqa: BLE001 - the scheduler may be gone
                    pass
        try:
            self.client.close(timeout=5)
        except Exception:  # noqa: BLE001 - a lost scheduler: nothing to close cleanly
            pass
        if self.cluster is not None:
            self.cluster.close()

    def terminate_workers(self) -> None:
        """Ctrl-C or a lost scheduler: cancel what has not finished and close the client (and the local
        cluster)."""
        self.shutdown(wait=False, cancel_futures=True)
