"""The scores: the one definition of the variance accounted for (VAF).

Every estimator, protocol, figure, the API and the CLI compute a VAF here (``tests/test_one_home.py``
fails on a second definition). Metrics built on it (a stiffness's VAF, where an offset counts as an error)
call :func:`vaf` with ``bias_counts=True``.

Degenerate input (stated, tested in ``tests/test_scores.py``): shapes that differ are a caller's error
(:class:`~jointbench.core.errors.InputError`, always). A VAF is *undefined* when fewer than 2 samples are
scored, when a value of ``y`` or ``yhat`` is not finite (NaN, inf: an all-NaN record too), or when ``y``
does not vary (a constant truth: nothing to explain). An undefined VAF raises
:class:`~jointbench.core.errors.InputError` naming the cause, unless the caller asks for NaN with
``undefined="nan"`` (the one visible way to do so).
"""
from __future__ import annotations

from typing import Literal

import numpy as np

from jointbench.core.errors import InputError

__all__ = ["vaf"]

Undefined = Literal["raise", "nan"]


def _undefined(cause: str, undefined: Undefined) -> float:
    if undefined == "nan":
        return float("nan")
    raise InputError(f"the VAF is undefined: {cause}")


def vaf(y, yhat, *, bias_counts: bool = False, axis: int | None = None,
        undefined: Undefined = "raise") -> float:
    """Variance accounted for, in percent: ``100 (1 - var(y - yhat) / var(y))``.

    Parameters
    ----------
    y, yhat : array_like
        The measured (or true) signal and its prediction, of one shape; pooled over every sample (a 2-D
        array of records is scored as one set).
    bias_counts : bool
        False (the VAF): the residual's variance, so a constant offset of ``yhat`` is not an error. True:
        its mean square, ``100 (1 - mean((y - yhat)^2) / var(y))``, so an offset lowers the score (a
        stiffness's VAF, van de Ruit et al.'s metric 1).
    axis : int, optional
        The variance of ``y`` (and of the residual, unless ``bias_counts``) about its mean along ``axis``,
        pooled over the other axes: one mean per record when records are the columns (``axis=0``). None:
        about the mean of all samples.
    undefined : {"raise", "nan"}
        What an undefined VAF gives (see the module): an ``InputError``, or NaN.

    Returns
    -------
    float
        The VAF in percent (100: a perfect prediction; 0: no better than the mean; negative: worse).

    Raises
    ------
    InputError
        Shapes differ; or the VAF is undefined (fewer than 2 samples, a non-finite value, ``y`` constant)
        and ``undefined="raise"``.

    References
    ----------
    van de Ruit et al. (2018), eq. 17; Westwick & Perreault (2012), Table I (%VAF); Kearney, Stein &
    Parameswaran (1997), the parallel-cascade VAF.
    """
    if undefined not in ("raise", "nan"):
        raise ValueError(f"vaf: undefined must be 'raise' or 'nan', got {undefined!r}")
    y = np.asarray(y, float)
    yhat = np.asarray(yhat, float)
    if y.shape != yhat.shape:
        raise InputError(f"the VAF needs a prediction of the signal's shape: {y.shape} vs {yhat.shape}")
    if y.size < 2:
        return _undefined(f"{y.size} sample(s) scored (at least 2 needed)", undefined)
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(yhat))):
        return _undefined("a value of the signal or of its prediction is not finite (NaN or inf)", undefined)
    keep = axis is not None
    vy = float(np.mean((y - np.mean(y, axis=axis, keepdims=keep)) ** 2))
    if not vy > 0:
        return _undefined("the signal does not vary (constant: nothing to explain)", undefined)
    e = y - yhat
    ve = float(np.mean(e * e)) if bias_counts else float(np.mean((e - np.mean(e, axis=axis, keepdims=keep)) ** 2))
    return float(100.0 * (1.0 - ve / vy))
