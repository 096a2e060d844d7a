"""The checked fit of recorded (or simulated) angle and torque: every decision and every step that can fail,
in order, before anything is written. :func:`jointbench.api.fit` is this :func:`fit`, and ``jointbench
estimate`` calls :func:`jointbench.api.fit`: a notebook fit and the command give the same numbers on the same
record, because there is one path.

:func:`fit`: the estimator and its settings (a scheduling variable added), the records (:mod:`.inputs`), whether
several records are one ensemble (:func:`ensemble_name`: the one place this is decided), then the steps of
:func:`prepare` (the data's magnitudes, the torque's sign, decimation, the crop: ``window``, or the perturbed
part of a gated multisine for the multisine methods; information; memory), the fit (numerical failures
turned into one-line errors), then the output gate (:func:`gate`: the estimate is refused when its own
prediction of a record it was fitted on is worse than a constant, a value or a bound is not finite, or an
interval has zero width), which gives each record's prediction and VAF (:func:`score`), and the hints
(:mod:`.hints`). Every record is
fitted and scored as an impedance, torque from angle (:func:`impedance`), also when the torque was imposed.
Errors name the arguments as the caller knows them (:func:`jointbench.core.errors.argument`).
"""
from __future__ import annotations

import dataclasses
import io as _io
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

from jointbench.core.ensemble import Ensemble
from jointbench.core.arguments import whole
from jointbench.core.errors import ConfigError, InputError, Refused, argument
from jointbench.core.schema import boolean
from jointbench.fitting import checks, inputs

if TYPE_CHECKING:  # pragma: no cover
    from jointbench.core.estimate import Estimate, Prediction


@dataclasses.dataclass
class Fit:
    """A checked fit: the estimate and everything it was computed from and on.

    Attributes
    ----------
    estimator : Estimator
        What was fitted, with its settings (``estimator.settings``).
    estimate : Estimate
        The fitted model (:class:`jointbench.core.estimate.Estimate`: ``stiffness(t)``, ``to_frame()``, ...).
    raw, trials : list of Trial
        The records as given, and as fitted (torque sign, decimation and crop applied).
    notes : list of str
        What the pipeline did that the caller did not ask for (a gated multisine cropped to its periods).
    predictions : list of Prediction
        Each fitted record's torque prediction (:meth:`Estimate.prediction`), on which its VAF is computed.
    frame, response : DataFrame
        ``estimate.to_frame()`` (parameters over time, with intervals) and ``estimate.response_frame()``
        (the IRF or FRF, or None).
    hints : list of str
        What the data say about the fit the user probably wants (:mod:`jointbench.fitting.hints`: a negative
        stiffness -> the torque's sign; torque that a reflex pathway would explain -> ``parallel_cascade``),
        one line each; the estimate is as fitted either way.
    """

    estimator: object
    estimate: "Estimate"
    raw: list
    trials: list
    notes: list[str]
    predictions: list
    frame: object
    response: object
    hints: list[str] = dataclasses.field(default_factory=list)

    @property
    def vaf(self) -> list[float]:
        """VAF (%) of each fitted record's predicted torque, in the order of :attr:`trials` (the definition:
        ``predictions[i].definition``)."""
        return [p.vaf() for p in self.predictions]

    def parameters(self) -> dict:
        """The estimate's parameters (``I``, ``B``, ``K``, arrays when time-varying; or the stiffness)."""
        import numpy as np

        params = self.estimate.parameters()
        return params or {"stiffness": np.atleast_1d(self.estimate.stiffness(self.estimate.time))}

    def plot(self, path: str | Path | None = None, fmt: str = "png") -> bytes:
        """Draw the estimate (with the fitted records) and return the image; written to ``path`` when given
        (its suffix is the format: .png, .pdf or .svg)."""
        from jointbench.fitting.plots import plot_estimate

        fmt = Path(path).suffix[1:].lower() if path else fmt
        buf = _io.BytesIO()
        plot_estimate(self.estimate, buf, trials=self.trials, fmt=fmt)
        if path is not None:
            Path(path).write_bytes(buf.getvalue())
        return buf.getvalue()


def make_estimator(estimator, settings: Mapping[str, Any] | None = None, schedule: str | None = None):
    """The estimator to fit: a registered name with ``settings`` parsed strictly (units allowed: ``"40 ms"``;
    ``auto=True`` sets each of the estimator's :attr:`AUTO` keys to 'auto'; ``schedule`` added as its
    scheduling variable), or an estimator object as it is."""
    from jointbench import estimators
    from jointbench.fitting.schedule import check_schedulable

    if isinstance(estimator, estimators.Estimator):
        if settings or schedule is not None:
            raise ConfigError(f"{argument('settings')}: applies to an estimator given by name; this one is built "
                              f"already (give it its settings, schedule included, when you build it)")
        return estimator
    if not isinstance(estimator, str):
        raise ConfigError(f"{argument('estimator')}: must be a registered name or an Estimator, got "
                          f"{type(estimator).__name__}")
    settings = dict(settings or {})
    if schedule is not None:
        check_schedulable(estimator)
        settings["schedule"] = schedule
    cls = estimators.REGISTRY.get(estimator)
    where = f"{argument('settings')} (estimator '{estimator}')"
    if "auto" in settings:
        auto = boolean(settings.pop("auto"), where, "auto")
        keys = getattr(cls, "AUTO", ())
        if not keys:
            raise ConfigError(f"{where}: key 'auto': {estimator} has no smoothing or regularisation parameter to "
                              f"choose from the data (the time-varying methods do)")
        for k in keys if auto else ():
            settings.setdefault(k, "auto")
    return estimators.make(estimator, settings, where=argument("settings"))


def ensemble_name(estimator, records, ensemble: bool | None) -> str | None:
    """The one rule for fitting records as an ensemble (realizations of one time-varying condition): the name
    of the ensemble to fit, or None to fit the records one by one or pooled.

    An :class:`~jointbench.core.ensemble.Ensemble` given (or read from one file) is one unless
    ``ensemble=False``; a list of records is one with ``ensemble=True``, or by default when there are several
    and the estimator takes ensembles only."""
    if isinstance(records, Ensemble):
        return None if ensemble is False else records.name
    if ensemble is None:
        ensemble = len(records) > 1 and "ensemble" in estimator.accepts and not {"trial", "pooled"} & estimator.accepts
    if not ensemble:
        return None
    return f"{len(records)} records" if len(records) > 1 else records[0].name


def checked_torque_sign(torque_sign) -> int:
    """``torque_sign`` when it is 1 or -1; one line naming the argument otherwise."""
    if isinstance(torque_sign, bool) or torque_sign not in (1, -1):
        raise ConfigError(f"{argument('torque_sign')}: must be 1 or -1, got {torque_sign!r}")
    return torque_sign


def signed(records: list, torque_sign: int) -> list:
    """The records with their torque negated when ``torque_sign`` is -1 (recordings whose torque is positive
    opposite to the angle)."""
    return [t.replace(torque=-t.torque) for t in records] if checked_torque_sign(torque_sign) == -1 else records


def prepare(estimator, raw: list, *, torque_sign: int = 1, decimate: int = 1,
            window: tuple[float | None, float | None] | None = None,
            decimate_filter: str = "fir") -> tuple[list, list[str]]:
    """The records as they are fitted, and notes on what was done unasked: magnitudes checked, the torque's
    sign, the records as impedances (:func:`impedance`), decimation, the crop (``window``, or a gated
    multisine's whole periods), then information and memory checked."""
    sign = checked_torque_sign(torque_sign)
    decimate = whole(decimate, "decimate", minimum=1)
    checks.check_magnitudes(raw)
    raw = signed(raw, sign)
    trials = [checks.decimate_trial(impedance(t), decimate, decimate_filter) for t in raw]
    notes: list[str] = []
    if window is not None:
        trials = [checks.crop_window(t, window) for t in trials]
    else:
        trials, notes = checks.crop_gated(estimator, trials)
    checks.check_information(trials)
    checks.check_memory(estimator, trials)
    return trials, notes


def fit(estimator, data=None, *, angle=None, torque=None, fs: float | None = None, array: str | None = None,
        settings: Mapping[str, Any] | None = None, decimate: int = 1, window=None, torque_sign: int = 1,
        ensemble: bool | None = None, schedule: str | None = None, decimate_filter: str = "fir") -> Fit:
    """Every decision and every step that can fail, in order, without writing anything (the module
    docstring); the arguments are :func:`jointbench.api.fit`'s."""
    est = make_estimator(estimator, settings, schedule)
    given = inputs.records(data, angle=angle, torque=torque, fs=fs, array=array, schedule=schedule)
    name = ensemble_name(est, given, ensemble)
    raw = list(given)
    trials, notes = prepare(est, raw, torque_sign=torque_sign, decimate=decimate,
                            window=None if window is None else checks.as_window(window),
                            decimate_filter=decimate_filter)
    estimate = fit_checked(est, Ensemble(tuple(trials), name=name) if name is not None else trials)
    predictions = gate(est, estimate, trials)
    from jointbench.fitting.hints import hints

    return Fit(est, estimate, raw, trials, notes, predictions, estimate.to_frame(), estimate.response_frame(),
               hints(est, estimate, trials, predictions, torque_sign))


def impedance(trial):
    """``trial`` as every estimator is given it and every estimate is scored on: the impedance, torque from
    angle (``imposed='angle'``), also when the apparatus imposed the torque (Xu's torque drive): the
    direction every method's stiffness and prediction refer to (FSEWLS fits torque from angle whatever was
    imposed; Westwick & Perreault's two-sided IRFs exist to identify the impedance of torque-driven joints;
    the comparison grids give every method this). An estimate's prediction is the torque from the angle;
    scored against the angle (the output of a torque-driven record) its VAF means nothing. Records read
    from files carry no ``imposed`` and are fitted this way already: a simulated torque-driven trial gives
    the numbers its CSV gives."""
    return trial if trial.imposed == "angle" else trial.replace(imposed="angle")


def gate(estimator, estimate: "Estimate", records) -> list["Prediction"]:
    """The output gate: each record's prediction (:func:`score`) when ``estimate``, fitted to ``records`` (a
    trial, a list of them or an Ensemble), can be returned as a result; :class:`Refused` otherwise.

    Refused, in this order: a parameter, the stiffness or an interval bound that is not finite
    (``reason="non_finite"``); a record whose own prediction is worse than a constant, VAF < 0 on the
    samples and in the band the estimate's prediction defines (``"negative_vaf"``); an interval of zero
    width (to rounding) or of non-finite width from an estimator that gives intervals
    (``"degenerate_interval"``), unless the estimate explains every record exactly (VAF above
    :data:`EXACT_VAF`: noise-free data, where a zero width is the right answer). The one gate of
    ``jointbench estimate``, :func:`jointbench.api.fit` and the harness's study cases: a fit the command
    refuses is ``refused`` in a study too. The message is one line naming the cause and the settings to
    change (:func:`remedy`); ``Refused.diagnostics`` holds the numbers.
    """
    from jointbench.core.estimate import degenerate_intervals, non_finite

    name = getattr(estimator, "name", estimate.estimator)
    trials = list(records.realizations if isinstance(records, Ensemble) else
                  records if isinstance(records, (list, tuple)) else [records])
    bad = non_finite(estimate)
    if bad:
        raise Refused(f"{name}: the fit gave non-finite values in {', '.join(bad)}: the data do not determine "
                      f"them; {remedy(estimator)}", reason="non_finite",
                      diagnostics={"estimator": name, "columns": bad})
    predictions = score(estimate, trials)
    vafs = [p.vaf() for p in predictions]
    worse = [(t.name, v) for t, v in zip(trials, vafs) if v < 0]
    if worse:
        shown = ", ".join(f"'{n}' {v:.4g} %" for n, v in worse[:3]) + (" ..." if len(worse) > 3 else "")
        raise Refused(f"{name}: the estimate predicts the torque of the record it was fitted on worse than a "
                      f"constant (VAF {shown}); {remedy(estimator)}", reason="negative_vaf",
                      diagnostics={"estimator": name, "vaf": vafs, "record": [t.name for t in trials],
                                   "definition": predictions[0].definition})
    flat = degenerate_intervals(estimate)
    if flat and not (min(vafs) >= EXACT_VAF and exact_everywhere(estimate)):
        what = ", ".join(f"{k} (width {w:.3g})" for k, w in flat.items())
        raise Refused(f"{name}: its confidence intervals of {what} have zero or non-finite width, which no "
                      f"estimate from noisy data has; {remedy(estimator)}", reason="degenerate_interval",
                      diagnostics={"estimator": name, "width": flat, "vaf": vafs})
    return predictions


#: VAF (%) above which a fit whose every interval has zero width is taken as exact (noise-free simulated data: the
#: prediction's own ends and interpolation keep a time-varying estimate's VAF of exact data near 99.99 %): there,
#: and only there, zero widths are right; a non-finite width is refused always
EXACT_VAF = 99.9


def exact_everywhere(estimate) -> bool:
    """Every interval bound of ``estimate`` of zero width (to rounding) at every time: an estimate claiming an
    exact fit throughout, as on noise-free data (unlike a zero width at some samples or of one parameter only,
    beside finite others: the signature of a lost variance, issue 33)."""
    import numpy as np

    iv = estimate.intervals
    if iv is None or not iv.bounds:
        return False
    for lo, hi in iv.bounds.values():
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        if not np.all(np.isfinite(hi - lo)) or np.any(hi - lo > 1e-9 * np.maximum(np.abs(lo), np.abs(hi))):
            return False
    return True

#: settings that decide what a fit can resolve, as the estimators name them, in the order a remedy names them
TUNING_SETTINGS = ("lag_before", "lag_after", "bandlimit", "input_band", "window", "segment", "forgetting",
                   "pool", "n_basis", "sigma", "n_p", "lags")


def remedy(estimator) -> str:
    """What to change when an estimate is refused: the estimator's settings that decide what it resolves
    (its lags, band, window; worded as the caller gives settings: ``settings`` or ``--set``), or the
    perturbation (a record whose input excites the band the model needs)."""
    fields = [f.name for f in dataclasses.fields(estimator.settings)] \
        if dataclasses.is_dataclass(getattr(estimator, "settings", None)) else []
    keys = [k for k in TUNING_SETTINGS if k in fields]
    change = (f"change {' / '.join(keys)} ({argument('settings')})" if keys
              else f"change the estimator's settings ({argument('settings')}) or the estimator")
    return f"{change}, or record with a perturbation that excites a wider band"


def fit_checked(estimator, trials) -> "Estimate":
    """``estimator.fit(trials)`` with numerical failures turned into one-line errors."""
    import numpy as np

    records = list(trials)
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
            return estimator.fit(trials)
    except Refused:
        raise
    except InputError as exc:
        raise InputError(f"{exc}{checks.gate_hint(estimator, records)}") from None
    except np.linalg.LinAlgError as exc:
        raise InputError(f"{estimator.name}: the fit is numerically singular ({exc}): the records do not "
                         f"determine the model (no perturbation, constant torque, or too few samples)"
                         f"{checks.gate_hint(estimator, records)}") from None
    except MemoryError:
        n = sum(t.n for t in records)
        raise InputError(f"{estimator.name}: out of memory for {n} samples at {records[0].fs:g} Hz; decimate "
                         f"({argument('decimate')}) or shorten the records ({argument('window')})") from None


def score(estimate: "Estimate", trials: list) -> list["Prediction"]:
    """Each record's torque prediction from its angle (:meth:`Estimate.prediction` of :func:`impedance`: the
    torque is the scored output whichever signal was imposed), on which its VAF is computed; one line naming
    the record when it cannot be predicted or its torque has nothing to explain."""
    out = []
    for index, trial in enumerate(impedance(t) for t in trials):
        try:
            p = estimate.prediction(trial, index)
        except InputError as exc:
            raise InputError(f"{trial.name}: {exc}") from None
        except (ValueError, ArithmeticError) as exc:
            raise InputError(f"{trial.name}: cannot predict the torque with the {estimate.estimator} estimate: "
                             f"{exc}") from None
        try:
            p.vaf()
        except InputError as exc:
            raise InputError(f"{trial.name}: {exc}") from None
        out.append(p)
    return out
