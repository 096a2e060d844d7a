"""The same study on every executor: serial, the process pool and a local Dask cluster give identical
rows (everything but the timings), and Dask workers compute with one BLAS thread."""
from __future__ import annotations

import pandas as pd
import pytest

from jointbench.benchmarks.study import run_study
from tests.harness_studies import tiny_grid_part, tiny_study

#: columns and metrics that are timings (they differ from run to run); everything else must be identical
TIMINGS = ("wall_time_s", "sim_time_s")


def _numbers(run) -> pd.DataFrame:
    rows = run.rows.drop(columns=[c for c in TIMINGS if c in run.rows.columns])
    rows = rows[rows["metric"] != "fit_time_s"]
    return rows.sort_values(["part", "case_id", "estimator", "metric"], kind="stable").reset_index(drop=True)


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("executors")
    return tiny_study(folder, seeds=3, extra_parts={"grid": tiny_grid_part(["ibk_spectral", "kbr", "sds"])})


@pytest.fixture(scope="module")
def serial(study, tmp_path_factory):
    return run_study(study, out_root=tmp_path_factory.mktemp("serial"), serial=True, progress=False)


def test_process_pool_rows_equal_serial(study, serial, tmp_path):
    pool = run_study(study, out_root=tmp_path, workers=2, progress=False)
    assert not serial.failed and not pool.failed
    assert len(serial.rows) > 50 and "skipped" in set(serial.rows["metric"])
    pd.testing.assert_frame_equal(_numbers(pool), _numbers(serial))


def test_local_dask_cluster_rows_equal_serial(study, serial, tmp_path):
    pytest.importorskip("dask.distributed")
    from jointbench.benchmarks.harness.dask_executor import DaskExecutor
    from jointbench.benchmarks.harness.fingerprint import code_hash
    from jointbench.benchmarks.harness.pool import run_task

    ex = DaskExecutor(workers=2)
    try:
        run = run_study(study, out_root=tmp_path, executor=ex, progress=False)

        def blas_threads_in_a_task():     # what a worker runs (run_task), then its BLAS thread count
            from threadpoolctl import threadpool_info
            run_task([], code_hash())
            return max([i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"] or [1])

        threads = [ex.submit(blas_threads_in_a_task).result() for _ in range(4)]
    finally:
        ex.shutdown()
    assert not run.failed, [r.error for r in run.failed]
    pd.testing.assert_frame_equal(_numbers(run), _numbers(serial))
    assert threads == [1, 1, 1, 1]


def test_a_worker_with_other_code_refuses(study):
    from jointbench.benchmarks.harness.pool import run_task

    with pytest.raises(RuntimeError, match="runs other code"):
        run_task([], code_hash="0" * 16)
