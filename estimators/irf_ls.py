"""Two-sided impedance IRF by ordinary least squares (Westwick & Perreault 2012, eq. 14)."""
from __future__ import annotations

import dataclasses

from jointbench.estimators import Estimator, register
from jointbench.estimators._twosided import Edges, LagSettings, estimate_irf
from jointbench.core.estimate import IRFEstimate
from jointbench.core.schema import param
from jointbench.core.types import Trial


@register("irf2_ls", tags=("lti", "nonparametric", "irf"))
class IRFLeastSquares(Estimator):
    """Two-sided (acausal) impulse response from angle to torque by least squares.

    The model is ``y(t) = sum_{k=-M1}^{M2} h(k) u(t - k)`` with ``u`` the angle and ``y`` the torque,
    ``M1 = round(lag_before * fs)`` and ``M2 = round(lag_after * fs)``. The regression matrix has
    elements ``U(i, j) = u(i - j + M1)``; it is built as a strided view of a zero-padded copy of the
    record (:func:`numpy.lib.stride_tricks.sliding_window_view`), never as an explicit Python loop.

    Several trials are pooled by stacking their regression rows (records are never joined end to end).
    The stacked system is reduced block by block with Householder QR and the small triangular system is
    solved with :func:`scipy.linalg.lstsq`. QR is used rather than the normal equations
    ``(U^T U)^{-1} U^T y``: forming ``U^T U`` squares the condition number of ``U``, which is large for
    the low-pass perturbations typical of joint experiments (2-10 Hz at 500 Hz sampling); the fast
    normal-equation route is :class:`estimators.irf_corr.IRFCorrelation`.

    Parameters
    ----------
    settings : Settings
        ``lag_before``, ``lag_after`` (s, default 0.1 each): anticipatory and causal memory;
        ``remove_mean`` (default True): subtract each record's mean from angle and torque;
        ``edges`` ('zero' or 'valid', default 'valid'): 'zero' takes ``u = 0`` outside the record, one
        regression row per sample (eq. 14 as printed); 'valid' keeps only rows whose lags all fall inside
        the record (the default: a recording does not start or end at rest).

    Notes
    -----
    :meth:`fit` returns an :class:`~jointbench.core.estimate.IRFEstimate` with ``lags = -M1 ... M2``
    (samples) and ``h`` not scaled by ``1/fs``.

    With 'zero' edges the padding puts a step in the angle at each record end; the inertial part of the
    impedance turns it into a large torque misfit over the first and last ``M`` rows, which biases the
    whole IRF when the torque is inertia-dominated (an end effect of order ``M/N`` with a large
    constant). 'valid' avoids it at the cost of ``M1 + M2`` rows per record.

    References
    ----------
    Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models. IEEE Trans.
    Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339, Sec. III-C, eq. 14.
    """

    accepts = frozenset({"trial", "pooled"})      # every record given enters the fit

    @dataclasses.dataclass(frozen=True)
    class Settings(LagSettings):
        edges: Edges = param("valid", doc="'valid': only rows whose lags all lie inside the record; "
                                          "'zero': u = 0 outside the record (eq. 14 as printed)")

    def _fit(self, trials: list[Trial]) -> IRFEstimate:
        s = self.settings
        return estimate_irf(self.name, trials, s, "ls", s.edges, self.name)
