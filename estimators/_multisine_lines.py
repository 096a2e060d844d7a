"""Excited lines of a sparse multisine on the DFT grid of a record: the one rule of the multisine estimators.

Private module (the leading underscore keeps it out of the estimator registry). A record of ``n``
samples at ``fs`` Hz holding a whole number of periods of a multisine has its lines exactly on DFT
bins ``k`` (frequency ``k fs / n``) and (numerically) nothing in the other bins. Bins are counted
``1 ... (n - 1) // 2``: DC and, for even ``n``, the Nyquist bin are never lines.

:func:`multisine_bins` is what an estimator calls (skirt, KBR): the lines given by a setting
(:func:`bins_of_lines`, each checked to be excited) or detected (:func:`excited_bins`). The rule for a
detected line: its bin stands ``threshold_db`` above the floor (the median bin power, at least
:data:`NUMERICAL_FLOOR_DB` below the strongest bin) and above both neighbouring bins; the lines lie on
a grid ``k0 + d Z`` with ``d >= 2`` (empty bins between them); and at most ``max_leakage`` of the
input's power lies off them (a record that is not a whole number of periods leaks). Each estimator keeps
its own threshold setting.

References
----------
van de Ruit, M. et al. (2018). Revealing time-varying joint impedance with kernel-based regression
and nonparametric decomposition. IEEE Trans. Control Syst. Technol. 28(1), 224-237,
doi:10.1109/TCST.2018.2881664, eq. 6 and Sec. IV-D (the multisine).
"""
from __future__ import annotations

from fractions import Fraction
from functools import reduce
from math import gcd

import numpy as np

from jointbench.core.errors import InputError


#: Bins this far (dB) below the strongest bin count as empty whatever the median: an exactly
#: synthesised multisine has only rounding errors between its lines, and they are not flat.
NUMERICAL_FLOOR_DB = 100.0

#: Largest fraction of the input's power (above DC) allowed off the detected lines.
MAX_LEAKAGE = 0.01


def bin_power(x: np.ndarray) -> np.ndarray:
    """``|X(k)|^2`` for ``k = 0 ... (n - 1) // 2`` (index = bin; DC included, Nyquist excluded)."""
    x = np.asarray(x, float)
    return np.abs(np.fft.rfft(x)[:(len(x) - 1) // 2 + 1]) ** 2


def _floor(ac: np.ndarray) -> float:
    """Power of an empty bin: the median over bins 1 ... (n-1)//2, at least NUMERICAL_FLOOR_DB below the top."""
    return max(float(np.median(ac)), float(ac.max()) * 10 ** (-NUMERICAL_FLOOR_DB / 10))


def _power_above_dc(name: str, x: np.ndarray) -> np.ndarray:
    p = bin_power(x)
    if p.size < 4 or not p[1:].max() > 1e-20 * p.sum():
        raise InputError(f"{name}: the input is constant (no power above DC); nothing to identify")
    return p


def multisine_bins(name: str, x: np.ndarray, fs: float, threshold_db: float, lines_hz=None,
                   max_leakage: float = MAX_LEAKAGE) -> np.ndarray:
    """Excited DFT bins of the record ``x``: the given ``lines_hz``, each checked to be excited (at least
    ``threshold_db`` above the floor of empty bins), or, when None, detected by :func:`excited_bins`.

    Raises
    ------
    InputError
        See :func:`bins_of_lines` and :func:`excited_bins`; a given line that is not excited.
    """
    if lines_hz is None:
        return excited_bins(name, x, fs, threshold_db, max_leakage)
    bins = bins_of_lines(name, lines_hz, len(x), fs)
    p = _power_above_dc(name, x)
    weak = p[bins] <= _floor(p[1:]) * 10 ** (threshold_db / 10)
    if weak.any():
        raise InputError(f"{name}: line {bins[np.argmax(weak)] * fs / len(x):g} Hz of lines_hz is not excited "
                         f"in the input (not {threshold_db:g} dB above the median bin power)")
    return bins


def excited_bins(name: str, x: np.ndarray, fs: float, threshold_db: float,
                 max_leakage: float = MAX_LEAKAGE) -> np.ndarray:
    """Isolated lines: bins standing ``threshold_db`` above the median bin power and above both neighbours.

    The median over bins ``1 ... (n - 1) // 2`` is the floor of a sparse multisine (its lines are a
    small fraction of the bins); it is taken at least :data:`NUMERICAL_FLOOR_DB` below the strongest
    bin. A line must also exceed its two neighbouring bins (one at the ends) by ``threshold_db``:
    smooth spectra (a trend left in the record, leakage, filtered noise) then give no lines. The lines
    must lie on a grid with empty bins between them, and hold all but ``max_leakage`` of the power above
    DC (lines leak into their neighbours when the record is not a whole number of periods).

    Parameters
    ----------
    name : str
        Prefix of the error messages (the estimator's name).
    x : ndarray
        The record (e.g. the imposed angle).
    fs : float
        Sampling rate (Hz), for the messages.
    threshold_db : float
        How far above the floor and above its neighbours a line must stand (dB).
    max_leakage : float
        Largest fraction of the power above DC off the lines.

    Returns
    -------
    ndarray of int
        Excited bins, increasing, on a grid ``k0 + d Z`` with ``d >= 2`` (lines may be missing).

    Raises
    ------
    InputError
        No power above DC; no line (noise, or lines leaking because the record does not hold a whole
        number of periods, e.g. a record shorter than one period); lines not on a regular grid; more
        than ``max_leakage`` of the power off the lines.
    """
    p = _power_above_dc(name, x)
    T = len(x) / fs
    ac = p[1:]
    floor = _floor(ac)
    gain = 10 ** (threshold_db / 10)
    left = np.concatenate([[0.0], ac[:-1]])
    right = np.concatenate([ac[1:], [0.0]])
    hit = np.flatnonzero((ac > gain * floor) & (ac > gain * left) & (ac > gain * right)) + 1
    if hit.size == 0:
        raise InputError(f"{name}: no clearly excited lines in the input: no DFT bin of the {T:g} s record stands "
                         f"{threshold_db:g} dB above the median bin power and above its neighbours. The input is not "
                         f"a sparse multisine (noise?), or the record does not hold a whole number of its periods "
                         f"(e.g. it is shorter than one period) and the lines leak into the neighbouring bins")
    if hit.size >= 2 and reduce(gcd, np.diff(hit).tolist()) < 2:
        raise InputError(f"{name}: the excited bins of the input ({_hz(hit, T)}) are not on a regular grid "
                         f"with empty bins between the lines; the input is not a sparse multisine")
    off = 1.0 - float(ac[hit - 1].sum() / ac.sum())
    if off > max_leakage:
        raise InputError(f"{name}: the input is not a sparse multisine with a whole number of periods in the "
                         f"record: {100 * off:.3g} % of its power lies off the {hit.size} detected line(s) (at "
                         f"most {100 * max_leakage:g} %); is the record ({T:g} s) shorter than one period, or not "
                         f"a whole number of periods? (or give 'lines_hz')")
    return hit


def bins_of_lines(name: str, lines_hz, n: int, fs: float) -> np.ndarray:
    """DFT bins of explicitly given line frequencies; each must be a whole number of cycles per record.

    Raises
    ------
    InputError
        A line is not on the DFT grid of the record (with a clear message when the record is shorter
        than one period of the multisine, the period being ``1 / gcd(lines)``), or above the last bin.
    """
    T = n / fs
    f = np.asarray(lines_hz, float)
    kf = f * T
    k = np.rint(kf).astype(int)
    off = np.abs(kf - k) > 1e-6 * np.maximum(1.0, kf)
    if off.any():
        period = multisine_period(f)
        if T < period * (1 - 1e-9):
            raise InputError(f"{name}: the {T:g} s record is shorter than one period ({period:g} s, from the "
                             f"line grid {1 / period:g} Hz) of the multisine; use a record of whole periods")
        i = int(np.argmax(off))
        raise InputError(f"{name}: line {f[i]:g} Hz is not on the DFT grid of the {T:g} s record (record * line "
                         f"= {kf[i]:.6g} cycles, not a whole number); the record must hold a whole number of "
                         f"periods of the multisine (period {period:g} s)")
    top = (n - 1) // 2
    if k.min() < 1 or k.max() > top:
        raise InputError(f"{name}: lines must lie between {1 / T:g} Hz and {top / T:g} Hz (below Nyquist) for a "
                         f"{T:g} s record at {fs:g} Hz; got {f.min():g} ... {f.max():g} Hz")
    return np.unique(k)


def multisine_period(lines_hz) -> float:
    """Period (s) of a multisine: the inverse of the greatest common divisor of its line frequencies
    (each read as a fraction with denominator up to 10^6)."""
    fr = [Fraction(float(v)).limit_denominator(10 ** 6) for v in np.ravel(lines_hz)]
    den = reduce(lambda a, b: a * b // gcd(a, b), (q.denominator for q in fr), 1)
    return den / reduce(gcd, (q.numerator * (den // q.denominator) for q in fr))


def _hz(bins: np.ndarray, T: float, most: int = 6) -> str:
    shown = ", ".join(f"{k / T:g}" for k in bins[:most])
    return shown + (", ..." if len(bins) > most else "") + " Hz"
