"""The checked fit of recorded (or simulated) angle and torque: every step that can fail, in order, before
anything is written. :func:`jointbench.api.fit` and ``jointbench estimate`` both run it, so a notebook
fit and the command give the same numbers on the same record.

Steps (:func:`compute`): check the data's magnitudes, negate the torque, decimate, crop (``window``, or
the perturbed part of a gated multisine for the multisine methods), check the records carry information,
check the memory the estimator plans to use, fit (numerical failures turned into one-line errors), check
the estimate is finite, compute each record's prediction and VAF (and, when asked, the figure). Errors
name the arguments as the caller knows them (:class:`~jointbench.fitting.checks.Names`).
"""
from __future__ import annotations

import dataclasses
import io as _io
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

from jointbench.fitting.checks import (PYTHON, Names, check_information, check_magnitudes,
                                                     check_memory, crop_gated, crop_window, decimate_trial,
                                                     gate_hint)
from jointbench.core.errors import ConfigError, InputError

if TYPE_CHECKING:  # pragma: no cover
    from jointbench.core.estimate import Estimate


@dataclasses.dataclass
class Fit:
    """A checked fit: the estimate and everything it was computed from and on.

    Attributes
    ----------
    estimate : Estimate
        The fitted model (:class:`jointbench.core.estimate.Estimate`: ``stiffness(t)``, ``to_frame()``, ...).
    raw, trials : list of Trial
        The records as given, and as fitted (torque sign, decimation and crop applied).
    notes : list of str
        What the pipeline did that the caller did not ask for (a gated multisine cropped to its periods).
    predictions : list
        Each fitted record's torque prediction (:meth:`Estimate.prediction`), on which its VAF is computed.
    frame, response : DataFrame
        ``estimate.to_frame()`` (parameters over time, with intervals) and ``estimate.response_frame()``
        (the IRF or FRF, or None).
    figure : bytes or None
        The figure, when one was asked for.
    """

    estimate: "Estimate"
    raw: list
    trials: list
    notes: list[str]
    predictions: list
    frame: object
    response: object
    figure: bytes | None

    @property
    def vafs(self) -> list[float]:
        """VAF (%) of each fitted record's predicted torque (the definition: ``predictions[i].definition``)."""
        return [p.vaf() for p in self.predictions]

    @property
    def vaf(self) -> float:
        """VAF (%) of the first record (of the only one, usually)."""
        return self.vafs[0]

    def parameters(self) -> dict:
        """The estimate's parameters (``I``, ``B``, ``K``, arrays when time-varying; or the stiffness)."""
        import numpy as np

        params = self.estimate.parameters()
        return params or {"stiffness": np.atleast_1d(self.estimate.stiffness(self.estimate.time))}

    def plot(self, path: str | Path | None = None, fmt: str = "png") -> bytes:
        """Draw the estimate (with the fitted records) and return the image; written to ``path`` when given."""
        from jointbench.fitting.plots import plot_estimate

        fmt = Path(path).suffix[1:].lower() if path else fmt
        buf = _io.BytesIO()
        plot_estimate(self.estimate, buf, trials=self.trials, fmt=fmt)
        if path is not None:
            Path(path).write_bytes(buf.getvalue())
        return buf.getvalue()


def estimator_from(name: str, settings: Mapping[str, Any] | None = None, names: Names = PYTHON):
    """Estimator ``name`` with ``settings`` parsed strictly (units allowed: ``"40 ms"``). ``auto=True``
    sets each of the estimator's :attr:`AUTO` keys to 'auto' (its smoothing chosen from the data)."""
    from jointbench import estimators

    settings = dict(settings or {})
    cls = estimators.REGISTRY.get(name)
    where = names("settings")
    if "auto" in settings:
        value = settings.pop("auto")
        text = str(value).strip().lower()
        if text not in ("true", "false", "yes", "no", "1", "0"):
            raise ConfigError(f"{where} (estimator '{name}'): key 'auto': expected true or false, got {value!r}")
        keys = getattr(cls, "AUTO", ())
        if not keys:
            raise ConfigError(f"{where} (estimator '{name}'): key 'auto': {name} has no smoothing or "
                              f"regularisation parameter to choose from the data (the time-varying methods do)")
        if text in ("true", "yes", "1"):
            for k in keys:
                settings.setdefault(k, "auto")
    return estimators.make(name, settings, where=where)


def compute(estimator, raw: list, *, torque_sign: int = 1, decimate: int = 1,
            window: tuple[float | None, float | None] | None = None, plot: Path | None = None,
            ensemble: str | None = None, names: Names = PYTHON) -> Fit:
    """Every step that can fail, in order, without writing anything (the module docstring).

    With ``ensemble`` (its name), the records are the realizations of one time-varying condition and are
    fitted as an :class:`~jointbench.core.ensemble.Ensemble` (after the same checks and cropping).
    """
    import numpy as np

    if torque_sign not in (1, -1):
        raise ConfigError(f"{names('torque_sign')}: must be 1 or -1, got {torque_sign!r}")
    if isinstance(decimate, bool) or not isinstance(decimate, int) or decimate < 1:
        raise ConfigError(f"{names('decimate')}: must be a whole number >= 1, got {decimate!r}")
    notes: list[str] = []
    check_magnitudes(raw)
    if torque_sign == -1:
        raw = [t.replace(torque=-t.torque) for t in raw]
    trials = [decimate_trial(t, decimate, names) for t in raw]
    if window is not None:
        trials = [crop_window(t, window, names) for t in trials]
    else:
        trials, gate_notes = crop_gated(estimator, trials, names)
        notes += gate_notes
    check_information(trials)
    check_memory(estimator, trials, names)
    if ensemble is not None:
        from jointbench.core.ensemble import Ensemble

        est = fit(estimator, Ensemble(tuple(trials), name=ensemble), names)
    else:
        est = fit(estimator, trials, names)
    frame = est.to_frame()
    response = est.response_frame()
    bad = [c for c in frame.columns if frame[c].dtype.kind == "f" and not np.all(np.isfinite(frame[c]))]
    if bad:
        raise InputError(f"{estimator.name}: the fit gave non-finite values in {', '.join(bad)}: the data do not "
                         f"determine them (constant or far too small/large signals, or too few samples)")
    predictions = [prediction_of(est, t, k) for k, t in enumerate(trials)]
    out = Fit(est, list(raw), trials, notes, predictions, frame, response, None)
    if plot is not None:
        out.figure = out.plot(fmt=Path(plot).suffix[1:].lower())
    return out


def fit(estimator, trials, names: Names = PYTHON):
    """``estimator.fit(trials)`` with numerical failures turned into one-line errors."""
    import numpy as np

    records = list(trials)
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
            return estimator.fit(trials)
    except InputError as exc:
        raise InputError(f"{exc}{gate_hint(estimator, records, names)}") from None
    except np.linalg.LinAlgError as exc:
        raise InputError(f"{estimator.name}: the fit is numerically singular ({exc}): the records do not "
                         f"determine the model (no perturbation, constant torque, or too few samples)"
                         f"{gate_hint(estimator, records, names)}") from None
    except MemoryError:
        n = sum(t.n for t in records)
        raise InputError(f"{estimator.name}: out of memory for {n} samples at {records[0].fs:g} Hz; decimate "
                         f"({names('decimate')}) or shorten the records ({names('window')})") from None


def prediction_of(est, trial, index: int):
    """:meth:`Estimate.prediction` of one record, its VAF checked to be computable."""
    try:
        p = est.prediction(trial, index)
    except InputError as exc:
        raise InputError(f"{trial.name}: {exc}") from None
    except (ValueError, ArithmeticError) as exc:
        raise InputError(f"{trial.name}: cannot predict the torque with the {est.estimator} estimate: "
                         f"{exc}") from None
    p.vaf()  # raises when the torque has no variance there
    return p


def prediction_vaf(est, trial, index: int = 0) -> float:
    """VAF (%) of record ``trial`` as defined by :meth:`Estimate.prediction` (``nan`` if not computable)."""
    try:
        return est.prediction(trial, index).vaf()
    except (NotImplementedError, ValueError, ArithmeticError):
        return float("nan")
