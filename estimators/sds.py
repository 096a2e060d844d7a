"""Short data segments (SDS): one two-sided IRF per time window from the segments of all trials."""
from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np

from jointbench.estimators import register
from jointbench.estimators._resample import JackknifeSettings, realization_jackknife
from jointbench.estimators._tvirf import EnsembleEstimator, TVLagSettings, fill_invalid, lagged, mdl_solve
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.core.estimate_tv import TVIRFEstimate
from jointbench.core.schema import Tune, param


#: windows whose normal equations are formed at once (bounds memory at about 2000 L^2 numbers)
_CHUNK = 2000


@register("sds", tags=("ltv", "nonparametric", "irf", "ensemble"))
class SDS(EnsembleEstimator):
    """Short data segments: a time-invariant two-sided IRF per window, from that window in every trial.

    For each window of ``W = round(window fs)`` samples (starting every ``step``), the segment of
    every trial of the ensemble at that window contributes the regression rows whose lags all lie in
    the segment: samples ``s + M2 ... s + W - 1 - M1`` of a segment starting at ``s``, so that no lag
    reaches across a segment boundary into the neighbouring data (Ludvig & Perreault's point: the
    segments are short, and the rows are built per segment rather than from a record cut into
    pieces). The segments are pooled (``R (W - L + 1)`` rows for ``L`` lags), each with its own mean
    removed (``remove_mean = 'segment'``), and the IRF solves the normal equations with the
    pseudo-inverse of :func:`estimators._tvirf.mdl_solve` (order by MDL) or plain least squares.

    The normal equations of all windows come from prefix sums of the lagged products (which depend
    only on the lag difference), so the cost does not grow with the window and the memory grows with
    ``n L``; they are formed and solved a chunk of windows at a time. The IRF of a window is assigned
    to its sample ``s + W // 2`` (for an even ``W`` the later of the two middle samples); with ``step``
    above one sample the IRF is interpolated linearly between windows.

    Parameters
    ----------
    settings : Settings
        ``window`` (s, default 1 s), ``step`` (s, default one sample), ``lag_before``, ``lag_after``
        (s, default 0.04 each: van de Ruit et al. 2018, Sec. V-E at 100 Hz), ``remove_mean``
        ('segment' or 'none'), ``solver`` ('mdl' or 'full'), ``rcond``.

    Notes
    -----
    Takes one trial (segments of that trial alone) or an :class:`~jointbench.core.ensemble.Ensemble`
    (realizations of equal length and rate, aligned in time); several records are taken as an
    ensemble. Returns a :class:`~jointbench.core.estimate.TVIRFEstimate`, valid from sample ``W // 2`` of
    the first window to that of the last, held outside; ``h`` is not scaled by ``1/fs``.

    References
    ----------
    Ludvig, D. & Perreault, E. J. (2012). System identification of physiological systems using short
    data segments. IEEE Trans. Biomed. Eng. 59(12), 3541-3549. Ludvig, D. & Perreault, E. J. (2011).
    Estimation of joint impedance using short data segments. Proc. IEEE EMBC 2011, 4120-4123.
    van de Ruit et al. (2018), Sec. V-E (window of 100 samples at 100 Hz, IRF lags up to 40 ms).
    """

    accepts = frozenset({"trial", "pooled", "ensemble"})

    @dataclasses.dataclass(frozen=True)
    class Settings(TVLagSettings, JackknifeSettings):
        window: float = param(1.0, unit="s", gt=0, doc="segment length: the IRF is taken constant over it",
                              tune=Tune())
        step: float | None = param(None, unit="s", gt=0, doc="distance between successive windows; none = one "
                                                              "sample")
        remove_mean: Literal["segment", "none"] = param("segment", doc="'segment': each segment's own mean "
                                                                       "is removed from input and output")

    def _fit_ensemble(self, ens: Ensemble) -> TVIRFEstimate:
        s = self.settings
        fs, n, R = ens.fs, ens.n, ens.size
        m1, m2 = self._lags(ens)
        L = m1 + m2 + 1
        W = int(round(s.window * fs))
        rows = W - L + 1
        if rows < 1:
            raise InputError(f"{self.name}: window = {s.window:g} s ({W} samples at {fs:g} Hz) is shorter than the "
                             f"lag range M1+M2+1 = {L} samples (lag_before = {s.lag_before:g} s, lag_after = "
                             f"{s.lag_after:g} s); lengthen the window or shorten the lags")
        if R * rows < L:
            raise InputError(f"{self.name}: window = {s.window:g} s gives {R} segment(s) x {rows} rows = {R * rows} "
                             f"equations for {L} lags; lengthen the window or shorten the lags")
        if W > n:
            raise InputError(f"{self.name}: window = {s.window:g} s ({W} samples) is longer than the records "
                             f"of '{ens.name}' ({n} samples, {n / fs:g} s)")
        step = 1 if s.step is None else max(1, int(round(s.step * fs)))
        starts = np.arange(0, n - W + 1, step)
        U, Y = ens.inputs, ens.outputs
        scale = float(np.abs(U).max()) or 1.0
        if not np.abs(U - U.mean(axis=0)).max() > 1e-9 * scale:
            raise InputError(f"{self.name}: the input (imposed {ens.imposed}) is constant; nothing to identify")
        # Prefix sums (summed over trials) of every product the centred normal equations need; memory
        # grows with n L, not n L^2: the lagged products depend only on the lag difference.
        # P[d, i] = sum_{tau < i} sum_r u_r(tau) u_r(tau + d)
        P = np.zeros((L, n + 1))
        for d in range(L):
            P[d, 1:n - d + 1] = np.cumsum(np.einsum("tr,tr->t", U[:n - d], U[d:]))
            P[d, n - d + 1:] = P[d, n - d]
        X = lagged(U, m1, m2)                                        # row i <-> sample i + M2
        Yv = Y[m2:n - m1]
        Q = np.vstack([np.zeros((1, L)), np.cumsum(np.einsum("trl,tr->tl", X, Yv), axis=0)])
        Qyy = np.concatenate([[0.0], np.cumsum(np.einsum("tr,tr->t", Yv, Yv))])
        CU = np.vstack([np.zeros((1, R)), np.cumsum(U, axis=0)])
        CY = np.vstack([np.zeros((1, R)), np.cumsum(Y, axis=0)])
        j = np.arange(L)
        D = np.abs(j[:, None] - j[None, :])                          # lag difference of column pair (j, l)
        B = L - 1 - np.maximum(j[:, None], j[None, :])               # where its product series starts
        n_obs = R * rows
        hw, order = np.empty((len(starts), L)), np.empty(len(starts), int)
        for c0 in range(0, len(starts), _CHUNK):                     # bounded memory: a chunk of windows
            w = starts[c0:c0 + _CHUNK]
            # S_xx[:, j, l] = P[D_jl, w + B_jl + rows] - P[D_jl, w + B_jl]: w steps by `step`, so for each
            # column pair (the pairs l >= j, mirrored) both terms are strided slices
            S_xx = np.empty((len(w), L, L))
            for jj, ll in zip(*np.triu_indices(L)):
                d, b0 = D[jj, ll], w[0] + B[jj, ll]
                S_xx[:, jj, ll] = S_xx[:, ll, jj] = (P[d, b0 + rows:b0 + rows + step * len(w):step]
                                                     - P[d, b0:b0 + step * len(w):step])
            S_xy = Q[w + rows] - Q[w]                                 # rows i = s ... s + rows - 1
            S_yy = Qyy[w + rows] - Qyy[w]
            if s.remove_mean == "segment":
                # each trial's segment mean over its whole segment (samples s ... s + W - 1)
                mu, nu = (CU[w + W] - CU[w]) / W, (CY[w + W] - CY[w]) / W                   # (windows, R)
                off = w[:, None] + (L - 1 - j)[None, :]               # sample of column j at the first row
                S_x = (CU[off + rows] - CU[off]).transpose(0, 2, 1)   # (windows, R, L): sum of u_r(t - k_j)
                S_y = CY[w + m2 + rows] - CY[w + m2]                  # (windows, R)
                mx = np.einsum("wr,wrl->wl", mu, S_x)
                S_xx = S_xx - mx[:, None, :] - mx[:, :, None] + rows * np.einsum("wr,wr->w", mu, mu)[:, None, None]
                S_xy = (S_xy - np.einsum("wr,wrl->wl", nu, S_x) - np.einsum("wr,wr->w", mu, S_y)[:, None]
                        + rows * np.einsum("wr,wr->w", mu, nu)[:, None])
                S_yy = S_yy - 2 * np.einsum("wr,wr->w", nu, S_y) + rows * np.einsum("wr,wr->w", nu, nu)
            hw[c0:c0 + len(w)], order[c0:c0 + len(w)] = mdl_solve(S_xx / n_obs, S_xy / n_obs, S_yy / n_obs, n_obs,
                                                                  s.solver, s.rcond)
        at = starts + W // 2
        valid = np.zeros(n, bool)
        valid[at[0]:at[-1] + 1] = True
        h = np.zeros((L, n))
        if len(at) == 1:
            h[:, at[0]] = hw[0]
        else:
            idx = np.arange(at[0], at[-1] + 1)
            h[:, idx] = np.array([np.interp(idx, at, hw[:, j]) for j in range(L)])
        info = {"realizations": R, "window_samples": W, "rows_per_segment": rows, "windows": len(starts),
                "step_samples": step,
                "order": f"{int(order.min())} ... {int(order.max())} of {L} (median {int(np.median(order))})"}
        est = TVIRFEstimate(lags=np.arange(-m1, m2 + 1), h=fill_invalid(h, valid), fs=fs, time=ens.time,
                             valid=valid, estimator=self.name, info=info)
        return est.with_intervals(lambda: realization_jackknife(self.name, ens, self._fit_ensemble, est, s))
