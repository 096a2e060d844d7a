"""Estimators fit blind: the harness (and anyone calling ``fit``) hands them trials without the truth."""
import dataclasses

import numpy as np
import pytest

from jointbench import estimators
from jointbench.core.ensemble import Ensemble
from jointbench.estimators import Estimator, register
from jointbench.core.types import HiddenTruth, Trial, Truth, TruthHidden

from .harness_studies import tiny_study


@pytest.fixture
def cheat():
    """An estimator that reads ``trial.truth.K`` inside its fit (registered for one test only)."""
    name = "cheat_reads_truth"

    @register(name)
    class Cheat(Estimator):
        """Returns the true stiffness (a benchmark must make this fail); says it pools records."""

        accepts = frozenset({"trial", "pooled"})

        def _fit(self, trials):
            return float(np.mean(trials[0].truth.K))

    yield name
    estimators.REGISTRY._items.pop(name, None)
    estimators.REGISTRY._tags.pop(name, None)


def _trial(**kw):
    rng = np.random.default_rng(0)
    return Trial.from_arrays(rng.standard_normal(200), rng.standard_normal(200), 100.0,
                             truth=Truth(I=0.01, B=0.5, K=50.0), **kw)


def test_fit_hides_the_truth_and_the_caller_keeps_it(cheat):
    trial = _trial()
    with pytest.raises(TruthHidden, match=r"estimator 'cheat_reads_truth' read Trial.truth.K while fitting"):
        estimators.make(cheat).fit(trial)
    assert trial.truth.K == 50.0                        # the caller's trial is untouched
    with pytest.raises(TruthHidden):
        estimators.make(cheat).fit([trial, _trial(name="b")])          # pooled records


def test_a_hidden_truth_refuses_every_kind_of_look():
    original = _trial()
    t = original.blind("x")
    assert isinstance(t.truth, HiddenTruth) and t.angle is original.angle     # nothing copied
    assert Ensemble((original,)).blind("x")[0].truth.estimator == "x"
    for look in (lambda: t.truth.K, lambda: bool(t.truth), lambda: hasattr(t.truth, "signals"),
                 lambda: getattr(t.truth, "I", None)):
        with pytest.raises(TruthHidden):
            look()
    assert dataclasses.replace(t, name="y").truth is t.truth          # copies keep it hidden
    assert Ensemble((t, t)).average().truth is t.truth                # so does an ensemble average


def test_overriding_fit_does_not_escape():
    class Sneaky(Estimator):
        def fit(self, trials):
            return trials.truth.K

        def _fit(self, trials):
            raise NotImplementedError

    with pytest.raises(TruthHidden):
        Sneaky().fit(_trial())


def test_a_case_whose_estimator_reads_the_truth_fails_with_a_clear_message(tmp_path, cheat):
    from jointbench.benchmarks.study import run_study

    path = tiny_study(tmp_path / "cfg", seeds=1, duration="2 s", estimators={cheat: {}, "ibk_spectral": {}})
    run = run_study(path, out_root=tmp_path / "out", serial=True, progress=False, use_cache=False)
    assert len(run.results) == 1 and run.results[0].status == "failed"
    assert "TruthHidden: estimator 'cheat_reads_truth' read Trial.truth.K while fitting" in run.results[0].error
    log = (run.folder / "failures.log").read_text()
    assert "estimators fit blind" in log
