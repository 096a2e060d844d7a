"""Cases on a Dask cluster: ``jointbench run STUDY --executor dask [--scheduler ADDRESS]``.

:class:`DaskExecutor` is a ``concurrent.futures`` executor over a ``dask.distributed`` client, so the
runner's loop (:func:`benchmarks.runner.run_cases`) uses it like the process pool: ``submit`` returns a
:class:`concurrent.futures.Future` completed from the Dask future's callback. Without an address it
starts a local cluster (``LocalCluster``: one process per worker, one thread each); with one it connects
to a running scheduler (``dask scheduler`` and ``dask worker ADDRESS --nthreads 1`` on the machines, each
with this checkout installed: a worker running other code refuses its tasks,
:func:`benchmarks.harness.pool.run_task`). Every task runs with one BLAS thread, as in the process pool,
so the numbers are identical, row for row, to a serial run (tests/test_executors.py).

Dask is an optional dependency (``pip install 'jointbench[dask]'``; ``make test`` installs it).
"""
from __future__ import annotations

import concurrent.futures as cf
import threading

from jointbench.errors import ConfigError

#: seconds to wait for a remote scheduler before giving up with a one-line error
CONNECT_TIMEOUT_S = 20


class DaskExecutor(cf.Executor):
    """A ``concurrent.futures`` executor on a Dask cluster (local, or at ``scheduler``)."""

    def __init__(self, scheduler: str | None = None, workers: int | None = None, processes: bool = True):
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:
            raise ConfigError("--executor dask needs Dask: pip install 'jointbench[dask]' (or dask[distributed])") \
                from None
        self.cluster = None
        if scheduler:
            try:
                self.client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
            except (OSError, TimeoutError) as exc:
                raise ConfigError(f"--scheduler {scheduler}: cannot reach a Dask scheduler there "
                                  f"({type(exc).__name__}: {exc})") from None
        else:
            import os

            n = workers or os.cpu_count() or 1
            self.cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=processes,
                                        dashboard_address=None, silence_logs=40)
            self.client = Client(self.cluster)
        self._max_workers = max(1, sum(self.client.nthreads().values()))
        self._lock = threading.Lock()
        self._pending: dict = {}

    @property
    def address(self) -> str:
        return self.client.scheduler.address

    def submit(self, fn, /, *args, **kwargs) -> cf.Future:
        out: cf.Future = cf.Future()
        remote = self.client.submit(fn, *args, pure=False, **kwargs)
        with self._lock:
            self._pending[out] = remote

        def done(d) -> None:
            with self._lock:
                self._pending.pop(out, None)
            if d.cancelled() or d.status == "cancelled":
                out.cancel()
                out.set_running_or_notify_cancel()
                return
            if not out.set_running_or_notify_cancel():
                return
            try:
                out.set_result(d.result())
            except BaseException as exc:  # noqa: BLE001 - the task's error, raised where the result is read
                out.set_exception(exc)

        remote.add_done_callback(done)
        return out

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        if cancel_futures:
            with self._lock:
                remote = list(self._pending.values())
            if remote:
                self.client.cancel(remote)
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()

    def terminate_workers(self) -> None:
        """Ctrl-C: cancel what has not finished and close the client (and the local cluster)."""
        self.shutdown(wait=False, cancel_futures=True)
