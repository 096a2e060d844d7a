"""Issue 37, the real-data track: `jointbench data fetch reklab` (a pinned address and SHA-256, stored in the user's
data folder) and the `realdata` study (two-fold cross-validated output VAF of every single-trial estimator) on the
shared copy of REKLAB's ankle trials (skipped where ../shared is absent)."""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from jointbench import api, estimators
from jointbench.cli import main
from jointbench.core.errors import InputError
from jointbench.fitting import fetch

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "data" / "reklab-ankle" / "ankle_stationary.npz"
shared = pytest.mark.skipif(not SHARED.is_file(), reason="../shared/data/reklab-ankle absent (developers only)")


@pytest.fixture
def small_dataset(tmp_path, monkeypatch):
    """A stand-in data set (a small file with its SHA-256) in place of REKLAB's, and a data folder of the test's."""
    payload = np.random.default_rng(0).bytes(5000)
    src = tmp_path / "source.bin"
    src.write_bytes(payload)
    ds = fetch.DataSet("reklab", src.as_uri(), hashlib.sha256(payload).hexdigest(), "reklab.mat", "GPL-2", "test")
    monkeypatch.setitem(fetch.DATASETS, "reklab", ds)
    monkeypatch.setenv(fetch.DATA_ENV, str(tmp_path / "data"))
    return src, payload


def test_fetch_stores_a_good_file_and_refuses_a_bad_checksum(small_dataset, tmp_path, capsys):
    src, payload = small_dataset
    assert fetch.located("reklab") is None
    assert main(["data", "fetch", "reklab"]) == 0
    stored = fetch.located("reklab")
    assert stored == tmp_path / "data" / "reklab.mat" and stored.read_bytes() == payload
    assert str(stored) in capsys.readouterr().out
    bad = tmp_path / "bad.bin"
    bad.write_bytes(payload[:-1] + b"x")
    with pytest.raises(InputError, match=r"not the pinned .*refused, nothing stored") as exc:
        api.fetch_data("reklab", url=bad.as_uri(), folder=tmp_path / "other")
    assert "\n" not in str(exc.value)
    assert not any((tmp_path / "other").iterdir())           # no partial file left behind


def test_fetch_through_an_opener_and_a_failed_download(small_dataset, tmp_path):
    import io

    _, payload = small_dataset
    got = fetch.fetch("reklab", folder=tmp_path / "f", opener=lambda url: io.BytesIO(payload))
    assert got.read_bytes() == payload

    def offline(url):
        raise OSError("network unreachable")

    with pytest.raises(InputError, match="cannot download"):
        fetch.fetch("reklab", folder=tmp_path / "g", opener=offline)


def test_pinned_reklab_source():
    ds = fetch.DATASETS["reklab"]
    assert fetch.REKLAB_COMMIT in ds.url and len(fetch.REKLAB_COMMIT) == 40 and len(ds.sha256) == 64
    import jointbench

    assert not str(fetch.data_folder().resolve()).startswith(str(Path(jointbench.__file__).parent.resolve()))


def test_study_lists_every_registered_estimator():
    """The track scores every estimator (those that take no single trial are recorded as skipped)."""
    from jointbench.benchmarks.config import load_study
    from jointbench.benchmarks.locate import study_path

    study = load_study(study_path("realdata"))
    assert set(study.parts["trials"].estimators) == set(estimators.REGISTRY.names())


def test_without_data_each_case_says_so(tmp_path, monkeypatch):
    monkeypatch.setenv(fetch.DATA_ENV, str(tmp_path / "empty"))
    run = api.run("realdata", out=tmp_path / "out", executor="serial", overrides=["trials.sweep.trial=[z_pf]"])
    rows = run.rows
    assert set(rows["metric"]) == {"not_run"}
    assert "jointbench data fetch reklab" in rows["reason"].iloc[0]


@shared
def test_realdata_report_on_the_shared_copy(tmp_path):
    run = api.run("realdata", out=tmp_path / "out", executor="serial", overrides=[f"trials.params.data={SHARED}"])
    r = run.rows
    cv = r[r["metric"] == "vaf_cv_mean"].pivot_table(index="estimator", columns="trial", values="value")
    assert set(cv.columns) == {"z_pf", "z_pf2", "z_df", "z_df2", "z_df3"}
    # the parallel cascade (REKLAB's model of these trials) predicts held-out torque better than the
    # intrinsic-only IRF on every trial (the reflex is real), and both explain most of it
    assert (cv.loc["parallel_cascade"] > cv.loc["irf2_ls"]).all()
    assert (cv.loc[["irf2_ls", "parallel_cascade"]] > 50).all().all()
    ls = r[r["estimator"] == "irf2_ls"]
    held, fitted = (ls[ls["metric"] == m]["value"].mean() for m in ("vaf_cv", "vaf_fit"))
    assert held < fitted                                      # held-out VAF below the in-sample one
    why = r[r["metric"].isin(["skipped", "not_fitted", "not_scored"])].groupby("estimator")["metric"].first()
    assert why.get("ensemble_irf") == "skipped" and why.get("fsewls") == "not_scored"
    assert (tmp_path / "out" / "realdata" / "report.md").is_file()
