"""Two-sided impedance IRF by the correlation (Toeplitz) method of Hunter & Kearney (eq. 15)."""
from __future__ import annotations

import dataclasses

from jointbench.estimators import Estimator, register
from jointbench.estimators._twosided import LagSettings, estimate_irf
from jointbench.core.estimate import IRFEstimate
from jointbench.core.types import Trial


@register("irf2_corr", tags=("lti", "nonparametric", "irf"))
class IRFCorrelation(Estimator):
    """Two-sided (acausal) impulse response from angle to torque by correlation: ``h = Phi_uu^{-1} phi_uy``.

    ``Phi_uu`` is the symmetric Toeplitz matrix of the input autocorrelation ``phi_uu(i - j)`` and
    ``phi_uy`` the input-output cross-correlation ``sum_t u(t - k) y(t)`` at lags ``k = -M1 ... M2``
    (``M1 = round(lag_before * fs)``, ``M2 = round(lag_after * fs)``). Both are computed by zero-padded
    FFT (linear, not circular; biased, i.e. un-normalised sums), summed over records (pooling), and the
    system is solved by Levinson recursion (:func:`scipy.linalg.solve_toeplitz`) in ``O(L^2)`` for
    ``L = M1 + M2 + 1`` lags.

    These are the normal equations of :class:`estimators.irf_ls.IRFLeastSquares` with ``U^T U``
    replaced by its Toeplitz approximation: the two estimates differ only by end effects of order
    ``M/N`` (the ``M`` samples at each end of an ``N``-sample record), and coincide with ``irf2_ls``
    (``edges='zero'``) when the input is zero on the first and last ``max(M1, M2)`` samples. Like
    'zero' edges, the biased correlations implicitly pad the record with zeros, so the end effect can be
    sizeable when the torque is inertia-dominated. Being normal equations solved by Levinson recursion,
    the method is less accurate than the QR-based least squares for very ill-conditioned (narrow-band)
    inputs.

    Parameters
    ----------
    settings : Settings
        ``lag_before``, ``lag_after`` (s, default 0.1 each): anticipatory and causal memory;
        ``remove_mean`` (default True): subtract each record's mean from angle and torque.

    Notes
    -----
    :meth:`fit` returns an :class:`~jointbench.core.estimate.IRFEstimate` with ``lags = -M1 ... M2``
    (samples) and ``h`` not scaled by ``1/fs``.

    References
    ----------
    Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models. IEEE Trans.
    Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339, Sec. III-C, eq. 15.

    Hunter, I. W. & Kearney, R. E. (1983). Two-sided linear filter identification. Med. Biol. Eng.
    Comput. 21, 203-209.
    """

    accepts = frozenset({"trial", "pooled"})      # every record given enters the fit

    @dataclasses.dataclass(frozen=True)
    class Settings(LagSettings):
        pass

    def _fit(self, trials: list[Trial]) -> IRFEstimate:
        return estimate_irf(self.name, trials, self.settings, "corr", "zero", self.name)
