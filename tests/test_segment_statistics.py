"""What the segments of :func:`jointbench.core.intervals.segment_covariance` give besides the covariance (issue 33):
the degrees of freedom of one of its variances (:func:`~jointbench.core.intervals.contrast_dof`: known answers,
and the property they are defined by, checked by simulation against segment_covariance itself), the
leave-one-segment-out prediction error (:func:`~jointbench.core.intervals.segment_press`) and the reason there is
no covariance (:func:`~jointbench.core.intervals.segment_shortfall`).

Satterthwaite's degrees of freedom ``nu`` of a variance estimate ``V`` are those of the scaled chi-square with
its mean and variance: ``Var(V) / E(V)^2 = 2 / nu``.
"""
import numpy as np
import pytest

from jointbench.core.intervals import (MIN_SEGMENTS, SEGMENT_COLUMNS, contrast_dof, segment_covariance,
                                       segment_press, segment_shortfall)


#: rows of a record one segment long for one regressor (SEGMENT_COLUMNS rows; at most MAX_SEGMENTS records)
ONE = SEGMENT_COLUMNS


def test_a_mean_over_equal_segments_has_g_minus_1():
    """The mean of G equal segments (each its own record): the jackknife variance is the sample variance of
    G segment means, exactly (G - 1) chi-square: G - 1 degrees of freedom."""
    for G in (MIN_SEGMENTS, 12, 30):
        designs = [np.ones((ONE, 1))] * G
        P = np.array([[1.0 / (ONE * G)]])
        assert contrast_dof(designs, P, np.array([[1.0]]), columns=1) == pytest.approx(G - 1, rel=1e-9)


def test_a_regressor_present_in_three_segments_has_two():
    """A regressor that is zero outside 3 of G segments: only those three inform it, whatever G: 2 degrees of
    freedom (the G - 1 of the whole covariance would claim a t quantile of G - 1)."""
    G, n = 20, ONE
    designs = [np.hstack([np.ones((n, 1)) * (g < 3), np.ones((n, 1)) * (g >= 3)]) for g in range(G)]
    X = np.vstack(designs)
    P = np.linalg.inv(X.T @ X)
    dof = contrast_dof(designs, P, np.eye(2), columns=1)
    assert dof[0] == pytest.approx(2.0, rel=1e-9)
    assert dof[1] == pytest.approx(G - 3 - 1, rel=1e-9)


def test_not_enough_segments_gives_none():
    assert contrast_dof([np.ones((ONE, 1))] * (MIN_SEGMENTS - 1), np.eye(1), np.eye(1), columns=1).size == 0


@pytest.mark.parametrize("records", [1, 3])
def test_dof_are_those_of_segment_covariance_by_simulation(records):
    """For a fixed design (a record or three, neighbours weighted within each; contrasts informed by all
    segments and by a few), white noise drawn 4000 times: ``2 E(V)^2 / Var(V)`` of segment_covariance's variance
    of each contrast matches contrast_dof within 12 % (the Monte Carlo error of a variance's variance over 4000
    draws with tails of a few dof is about 5 %)."""
    rng = np.random.default_rng(7)
    N = 1200
    designs = []
    for r in range(records):
        n = N // records
        t = np.linspace(0, 1, n)
        slow = np.exp(-((t - 0.15) / 0.05) ** 2)     # a regressor that lives in a few segments
        designs.append(np.column_stack([rng.standard_normal(n), slow * rng.standard_normal(n), np.ones(n)]))
    X = np.vstack(designs)
    P = np.linalg.inv(X.T @ X)
    contrasts = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.5]])
    dof = contrast_dof(designs, P, contrasts, columns=1)
    assert len(dof) == 3 and dof[1] < dof[0]
    V = np.empty((4000, 3))
    for i in range(len(V)):
        y = rng.standard_normal(N)
        e = y - X @ (P @ (X.T @ y))
        starts = np.cumsum([0] + [len(d) for d in designs])
        cov, G = segment_covariance([(d, e[a:a + len(d)]) for d, a in zip(designs, starts)], P, columns=1)
        V[i] = np.einsum("kp,pq,kq->k", contrasts, cov, contrasts)
    simulated = 2 * V.mean(axis=0) ** 2 / V.var(axis=0)
    assert G >= 30
    np.testing.assert_allclose(simulated, dof, rtol=0.12)


def test_press_predicts_each_segment_from_the_others():
    """The mean of G one-segment records: each segment predicted by the mean of the others (known answer, not
    the left-out change's algebra)."""
    rng = np.random.default_rng(3)
    G = 12
    ys = [rng.standard_normal(ONE) + 5.0 for _ in range(G)]
    y = np.concatenate(ys)
    X = np.ones((len(y), 1))
    c = np.array([y.mean()])
    want = sum(float(np.sum((yg - np.mean(np.concatenate(ys[:g] + ys[g + 1:]))) ** 2)) for g, yg in enumerate(ys))
    records = [(np.ones((ONE, 1)), yg - c[0]) for yg in ys]
    assert segment_press(records, np.linalg.pinv(X.T @ X), columns=1) == pytest.approx(want, rel=1e-12)
    assert np.isnan(segment_press(records[:MIN_SEGMENTS - 1], np.eye(1), columns=1))


def test_press_rises_with_a_regressor_of_noise_where_the_rss_falls():
    """A regressor unrelated to the data always lowers the residual sum of squares; the prediction error of
    left-out segments rises in most draws (17 of these 20)."""
    rng = np.random.default_rng(11)
    rises = 0
    for _ in range(20):
        n = 400
        x = rng.standard_normal(n)
        y = 2.0 * x + rng.standard_normal(n)
        press = []
        for X in (x[:, None], np.column_stack([x, rng.standard_normal(n)])):
            c = np.linalg.lstsq(X, y, rcond=None)[0]
            press.append(segment_press([(X, y - X @ c)], np.linalg.inv(X.T @ X), columns=2))
        rises += press[1] > press[0]
    assert rises >= 16, rises


def test_shortfall_names_the_segments_and_the_remedy():
    text = segment_shortfall([7 * ONE * 10], 10)
    assert text.startswith(f"the fitted rows hold 7 segments of {ONE * 10} rows") and "shorten the lags" in text


def test_an_estimate_without_a_band_says_why_on_the_command_line(tmp_path):
    """pv_irf at +-100 ms on issue 33's narrow-band record: too few segments for the band; the command says so
    and what to change, instead of "this estimator provides none"."""
    from jointbench.testing.data import narrow_band
    from tests.estimate_data import run, save

    path = save(tmp_path / "nb.npz", narrow_band(0))
    code, out, err = run(["-e", "pv_irf", "-i", path, "-o", tmp_path / "o.csv", "--set", "lag_before=100ms", "--set",
                          "lag_after=100ms"])
    assert code == 0, err
    assert "(no confidence intervals: the fitted rows hold 7 segments" in out and "shorten the lags" in out
    assert "provides none" not in out
