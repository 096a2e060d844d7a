"""An :class:`Ensemble`: realizations of one time-varying condition, aligned in time.

Ensemble identification (MacNeil, Kearney & Hunter 1992; Ludvig & Perreault 2012; Guarin & Kearney
2017) rests on repetitions of the same time-varying behaviour: realization ``r`` at sample ``i`` is
taken at the same point of the behaviour as every other realization at sample ``i``. That is a
different thing from several records of one *stationary* condition, which the time-invariant
estimators pool row by row; so an ensemble has its own type, and every estimator declares which of
the three kinds of data it accepts (:func:`data_kind`): one ``trial``, ``pooled`` records, or an
``ensemble``.

Alignment is by sample index: all realizations have the same sampling rate and the same number of
samples, and the ensemble's time base is that of its first realization.

References
----------
MacNeil, J. B., Kearney, R. E. & Hunter, I. W. (1992). Identification of time-varying biological
systems from ensemble data. IEEE Trans. Biomed. Eng. 39(12), 1213-1225.
"""
from __future__ import annotations

import copy
import dataclasses
from typing import Iterator, Literal, Sequence

import numpy as np

from jointbench.core.errors import InputError
from jointbench.core.types import HiddenTruth, Trial, Truth

DataKind = Literal["trial", "pooled", "ensemble"]
#: the kinds of data an estimator may accept (``Estimator.accepts``)
DATA_KINDS: tuple[str, ...] = ("trial", "pooled", "ensemble")


@dataclasses.dataclass(frozen=True, eq=False)
class Ensemble:
    """Realizations of one time-varying condition, aligned sample by sample.

    Attributes
    ----------
    realizations : tuple of Trial
        At least one; the same sampling rate, number of samples and imposed signal.
    name : str
        Label used in messages.

    Raises
    ------
    InputError
        No realization, an element that is not a :class:`~jointbench.core.types.Trial`, or realizations
        that differ in sampling rate, length or imposed signal (one line naming both realizations).
    """

    realizations: tuple[Trial, ...]
    name: str = "ensemble"

    def __post_init__(self):
        reals = tuple(self.realizations) if not isinstance(self.realizations, Trial) else (self.realizations,)
        where = f"ensemble '{self.name}'"
        if not reals:
            raise InputError(f"{where}: has no realization")
        for i, t in enumerate(reals):
            if not isinstance(t, Trial):
                raise InputError(f"{where}: realization {i} is a {type(t).__name__}, not a Trial")
        first = reals[0]
        for t in reals[1:]:
            if t.fs != first.fs:
                raise InputError(f"{where}: realization '{t.name}' is sampled at {t.fs:g} Hz and '{first.name}' at "
                                 f"{first.fs:g} Hz; the realizations of an ensemble must share one sampling rate")
            if t.n != first.n:
                raise InputError(f"{where}: realization '{t.name}' has {t.n} samples and '{first.name}' {first.n}; "
                                 f"the realizations of an ensemble must have the same length")
            if t.imposed != first.imposed:
                raise InputError(f"{where}: realization '{t.name}' imposes the {t.imposed} and '{first.name}' the "
                                 f"{first.imposed}; the realizations of an ensemble must impose the same signal")
        object.__setattr__(self, "realizations", reals)

    def blind(self, estimator: str = "?") -> "Ensemble":
        """The ensemble as an estimator may see it: every realization :meth:`~jointbench.core.types.Trial.blind`."""
        reals = tuple(t.blind(estimator) for t in self.realizations)
        if all(a is b for a, b in zip(reals, self.realizations)):
            return self
        out = copy.copy(self)
        object.__setattr__(out, "realizations", reals)
        return out

    # -------------------------------------------------------------------------------- construction
    @classmethod
    def from_arrays(cls, angle, torque, fs: float, t0: float = 0.0, imposed: Literal["angle", "torque"] = "angle",
                    name: str = "ensemble", names: Sequence[str] | None = None) -> "Ensemble":
        """An ensemble from 2-D ``angle`` and ``torque`` arrays (samples × realizations).

        Raises
        ------
        InputError
            Arrays that are not 2-D or differ in shape, fewer samples (rows) than realizations (columns: the
            arrays look transposed), or names that do not match the realizations.
        """
        a = np.asarray(angle, float)
        y = np.asarray(torque, float)
        where = f"ensemble '{name}'"
        if a.ndim != 2 or y.ndim != 2:
            raise InputError(f"{where}: angle and torque must be 2-D (samples x realizations), got shapes "
                             f"{a.shape} and {y.shape}")
        if a.shape != y.shape:
            raise InputError(f"{where}: angle {a.shape} and torque {y.shape} differ in shape")
        if a.shape[0] < a.shape[1]:
            raise InputError(f"{where}: angle and torque are {a.shape[0]} x {a.shape[1]}, fewer samples than "
                             f"realizations: transposed? an ensemble is samples x realizations (transpose them)")
        labels = list(names) if names is not None else [f"{name}[{r}]" for r in range(a.shape[1])]
        if len(labels) != a.shape[1]:
            raise InputError(f"{where}: {len(labels)} names for {a.shape[1]} realizations")
        return cls(tuple(Trial.from_arrays(a[:, r], y[:, r], fs, t0=t0, imposed=imposed, name=labels[r])
                         for r in range(a.shape[1])), name=name)

    # ------------------------------------------------------------------------------------- access
    def __len__(self) -> int:
        return len(self.realizations)

    def __iter__(self) -> Iterator[Trial]:
        return iter(self.realizations)

    def __getitem__(self, i: int) -> Trial:
        return self.realizations[i]

    @property
    def size(self) -> int:
        """Number of realizations R."""
        return len(self.realizations)

    @property
    def fs(self) -> float:
        return self.realizations[0].fs

    @property
    def n(self) -> int:
        """Samples per realization."""
        return self.realizations[0].n

    @property
    def time(self) -> np.ndarray:
        """Time base (s): the first realization's."""
        return self.realizations[0].time

    @property
    def imposed(self) -> str:
        return self.realizations[0].imposed

    @property
    def inputs(self) -> np.ndarray:
        """The imposed signals, shape ``(n, R)``."""
        return np.stack([t.input for t in self.realizations], axis=1)

    @property
    def outputs(self) -> np.ndarray:
        """The measured responses, shape ``(n, R)``."""
        return np.stack([t.output for t in self.realizations], axis=1)

    def subset(self, indices: Sequence[int], name: str | None = None) -> "Ensemble":
        """The ensemble of the realizations at ``indices`` (e.g. all but a validation trial)."""
        return Ensemble(tuple(self.realizations[i] for i in indices), name=name or self.name)

    def average(self, name: str | None = None) -> Trial:
        """The ensemble average: one trial whose angle and torque are the means over realizations.

        The truth, when every realization has one, averages the parameters and noise-free signals
        (``num``/``den`` are dropped: an average of systems has no single rational transfer function).

        References
        ----------
        van de Ruit et al. (2018), Sec. V-E and Table II ("the ensemble average of 5 trials was used
        for model estimation").
        """
        truth = None
        truths = [t.truth for t in self.realizations]
        hidden = [tr for tr in truths if isinstance(tr, HiddenTruth)]
        if hidden:                  # while an estimator fits, the average's truth is hidden too
            truth = hidden[0]
        elif all(tr is not None for tr in truths):
            keys = set.intersection(*(set(tr.signals) for tr in truths))
            truth = Truth(I=_mean([tr.I for tr in truths]), B=_mean([tr.B for tr in truths]),
                          K=_mean([tr.K for tr in truths]),
                          signals={k: np.mean([tr.signals[k] for tr in truths], axis=0) for k in sorted(keys)})
        first = self.realizations[0]
        return Trial(time=first.time, angle=np.mean([t.angle for t in self.realizations], axis=0),
                     torque=np.mean([t.torque for t in self.realizations], axis=0), fs=first.fs,
                     imposed=first.imposed, truth=truth, name=name or f"{self.name} (average of {self.size})")


def _mean(values):
    arrays = [np.asarray(v, float) for v in values]
    if all(a.ndim == 0 for a in arrays):
        return float(np.mean(arrays))
    return np.mean(np.broadcast_arrays(*arrays), axis=0)


def data_kind(data) -> DataKind:
    """``'ensemble'`` for an :class:`Ensemble`, ``'pooled'`` for several trials, else ``'trial'``."""
    if isinstance(data, Ensemble):
        return "ensemble"
    if isinstance(data, Trial):
        return "trial"
    return "pooled" if len(list(data)) > 1 else "trial"


def valid_mask(estimate, t: np.ndarray | None = None) -> np.ndarray:
    """Samples at which ``estimate`` rests on data: its ``valid`` mask, or all True when it has none.

    Time-varying estimators that cannot estimate near the record's ends (the lags of an ensemble IRF,
    half a window of SDS) carry a boolean ``valid`` on their ``time`` base; their ``stiffness(t)`` there
    is held from the nearest valid sample. Metrics should use only valid samples.

    Parameters
    ----------
    estimate : Estimate
        Any estimate.
    t : ndarray, optional
        Times (s); default the estimate's own time base. A time counts as valid when the nearest
        sample of the estimate's time base is.
    """
    time = np.asarray(estimate.time, float)
    valid = getattr(estimate, "valid", None)
    if t is None:
        return np.ones(len(time), bool) if valid is None else np.asarray(valid, bool).copy()
    t = np.asarray(t, float)
    if valid is None:
        return np.ones(t.shape, bool)
    i = np.clip(np.rint((t - time[0]) * estimate.fs).astype(int), 0, len(time) - 1)
    return np.asarray(valid, bool)[i]
