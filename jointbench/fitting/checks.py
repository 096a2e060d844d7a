"""Steps on the records of ``jointbench estimate`` before a fit: decimation, ``--window``, the crop of a
gated multisine, and the checks that turn hopeless inputs into one-line errors (magnitudes outside
double precision's comfortable range, constant signals, a fit that would not fit in memory).

Every function raises :class:`~jointbench.core.errors.InputError` or :class:`~jointbench.core.errors.ConfigError`
with a message naming the record or the argument; nothing here writes files. The arguments are named as
the caller knows them (:func:`jointbench.core.errors.argument`): the Python API's keywords (``window=``,
``decimate=``) by default, the command line's flags (``--window``, ``--decimate``) for ``jointbench
estimate``. numpy and the estimators are imported inside the functions (``jointbench estimate --list`` must
start quickly).
"""
from __future__ import annotations

import dataclasses
import re

from jointbench.core.errors import ConfigError, InputError, argument

#: data whose largest magnitude lies outside this range cannot be squared, multiplied and inverted safely
#: in double precision (variances of 1e-160 underflow, of 1e300 overflow); such values mean wrong units
MAGNITUDE_RANGE = (1e-50, 1e50)
#: the memory an estimator may plan to use, as a fraction of the memory available
MEMORY_FRACTION = 0.5


def parse_window(text: str) -> tuple[float | None, float | None]:
    """``START:END`` in seconds (``s`` or ``ms`` suffix allowed; either side may be left empty)."""
    w = argument("window")
    m = re.fullmatch(r"\s*([^:]*):([^:]*)\s*", text)
    if not m:
        raise ConfigError(f"{w}: expected START:END in seconds (e.g. 5s:45s), got {text!r}")

    def value(part: str) -> float | None:
        part = part.strip()
        if not part:
            return None
        v = re.fullmatch(r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(s|ms)?", part)
        if not v:
            raise ConfigError(f"{w}: {part!r} is not a time in s or ms (e.g. 5s, 500ms, 5.5)")
        x = float(v.group(1)) * (1e-3 if v.group(2) == "ms" else 1.0)
        if not (x >= 0 and x < float("inf")):
            raise ConfigError(f"{w}: times must be finite and >= 0 s, got {part!r}")
        return x

    start, end = value(m.group(1)), value(m.group(2))
    if start is None and end is None:
        raise ConfigError(f"{w}: give a start, an end or both (START:END)")
    if start is not None and end is not None and not end > start:
        raise ConfigError(f"{w}: the end ({end:g} s) must come after the start ({start:g} s)")
    return start, end


def _slice(trial, i0: int, i1: int):
    from jointbench.core.types import Trial

    return Trial(time=trial.time[i0:i1], angle=trial.angle[i0:i1], torque=trial.torque[i0:i1], fs=trial.fs,
                 imposed=trial.imposed, name=trial.name,
                 channels={k: v[i0:i1] for k, v in getattr(trial, "channels", {}).items()})


def as_window(value) -> tuple[float | None, float | None]:
    """A window from ``"START:END"`` text (:func:`parse_window`) or a ``(start, end)`` pair of seconds (either
    may be None), checked alike."""
    if isinstance(value, str):
        return parse_window(value)
    w = argument("window")
    try:
        start, end = value
    except (TypeError, ValueError):
        raise ConfigError(f"{w}: expected (start, end) in seconds or 'START:END', got {value!r}") from None
    for x in (start, end):
        if x is not None and (isinstance(x, bool) or not isinstance(x, (int, float)) or not 0 <= x < float("inf")):
            raise ConfigError(f"{w}: times must be finite numbers >= 0 s (or None), got {value!r}")
    if start is None and end is None:
        raise ConfigError(f"{w}: give a start, an end or both")
    if start is not None and end is not None and not end > start:
        raise ConfigError(f"{w}: the end ({end:g} s) must come after the start ({start:g} s)")
    return (None if start is None else float(start), None if end is None else float(end))


def crop_window(trial, window: tuple[float | None, float | None]):
    """The samples ``start <= t - t0 < end`` of ``trial`` (``t0`` its first sample's time)."""
    start, end = window
    w = argument("window")
    fs = trial.fs
    i0 = 0 if start is None else int(round(start * fs))
    i1 = trial.n if end is None else int(round(end * fs))
    if end is not None and i1 > trial.n:
        raise InputError(f"{w}: record '{trial.name}' is {trial.duration:g} s long; it has no samples "
                         f"up to {end:g} s")
    if i1 - i0 < 2:
        raise InputError(f"{w}: keeps {max(i1 - i0, 0)} sample(s) of record '{trial.name}' "
                         f"({trial.duration:g} s at {fs:g} Hz); need at least 2")
    return _slice(trial, i0, i1)


def crop_gated(estimator, trials: list) -> tuple[list, list[str]]:
    """For the multisine methods: crop a gated multisine (quiet at the start or end) to its whole periods.

    Returns the trials and a note per cropped record. Other estimators get the records unchanged.
    """
    from jointbench import estimators

    if "multisine" not in estimators.REGISTRY.tags(estimator.name):
        return trials, []
    from jointbench.core.signal import find_gate

    out, notes = [], []
    for t in trials:
        g = find_gate(t.input, t.fs)
        if g is None:
            out.append(t)
            continue
        t0 = t.time[0]
        text = (f"{t.name}: gated multisine: the angle is perturbed from {t.time[g.on] - t0:.3f} s to "
                f"{(t.time[g.off - 1] - t0) + 1 / t.fs:.3f} s only")
        if g.period:
            text += (f"; fitted on {t.time[g.start] - t0:.3f} ... {t.time[g.stop - 1] - t0 + 1 / t.fs:.3f} s "
                     f"({g.periods} whole period{'s' if g.periods > 1 else ''} of {g.period / t.fs:g} s); "
                     f"{argument('window')} chooses another part")
        else:
            text += f"; fitted on that part (no repeating period found); {argument('window')} chooses another part"
        notes.append(text)
        out.append(_slice(t, g.start, g.stop))
    return out, notes


def gate_hint(estimator, trials: list) -> str:
    """``"; ... gated ..."`` when a record's perturbation is on for part of it only (for error messages)."""
    try:
        from jointbench.core.signal import find_gate

        for t in trials:
            g = find_gate(t.input, t.fs)
            if g is not None:
                t0 = t.time[0]
                a, b = t.time[g.on] - t0, t.time[g.off - 1] - t0 + 1 / t.fs
                return (f" (record '{t.name}' is perturbed from {a:.3f} s to {b:.3f} s only: fit that part with "
                        f"{argument('window', (a, b))})")
    except Exception:  # noqa: BLE001 - a hint must never hide the error it decorates
        return ""
    return ""


def check_magnitudes(trials: list) -> None:
    """Refuse data whose magnitude is outside :data:`MAGNITUDE_RANGE` (wrong units or corrupt values)."""
    import numpy as np

    lo, hi = MAGNITUDE_RANGE
    for t in trials:
        for what, x in (("angle", t.angle), ("torque", t.torque)):
            peak = float(np.max(np.abs(x)))
            if peak == 0:
                continue
            if not lo <= peak <= hi:
                raise InputError(f"{t.name}: the {what} reaches {peak:.3g} at most: values outside {lo:g} ... "
                                 f"{hi:g} cannot be handled in double precision (their variances under- or "
                                 f"overflow); check the units (rad, N m) and rescale")


def check_information(trials: list) -> None:
    """Refuse records whose angle or torque is constant (zero variance): nothing to identify."""
    import numpy as np

    for t in trials:
        for what, x in (("angle", t.angle), ("torque", t.torque)):
            scale = float(np.max(np.abs(x)))
            if not np.std(x) > 1e-12 * scale or scale == 0:
                raise InputError(f"{t.name}: the {what} is constant ({x[0]:.6g} on all {t.n} samples fitted); "
                                 f"nothing to identify")


def _gib(b: float) -> str:
    return f"{b / 2 ** 30:.3g} GiB" if b >= 2 ** 29 else f"{b / 2 ** 20:.3g} MiB"


def check_memory(estimator, trials: list) -> None:
    """Refuse a fit whose planned memory (``estimator.memory_bytes(trials)``) exceeds what is available.

    The message names the decimation that would fit. Estimators without ``memory_bytes`` are not checked.
    """
    plan = getattr(estimator, "memory_bytes", None)
    if plan is None:
        return
    need = plan(trials)
    from jointbench.fitting.read_limits import available_memory

    budget = MEMORY_FRACTION * available_memory()
    if need <= budget:
        return
    fs = trials[0].fs
    n = sum(t.n for t in trials)
    for q in range(2, 1001):
        if trials[0].n // q < 16:
            break
        shapes = [_Shape(t.n // q, t.fs / q, t) for t in trials]
        if plan(shapes) <= budget:
            raise InputError(f"{estimator.name}: the fit and its prediction need about {_gib(need)} for {n} samples at "
                             f"{fs:g} Hz, more than half the memory available ({_gib(2 * budget)}); at "
                             f"{fs / q:g} Hz ({argument('decimate', q)}) they need {_gib(plan(shapes))}")
    raise InputError(f"{estimator.name}: the fit needs about {_gib(need)} for {n} samples at {fs:g} Hz, more than "
                     f"half the memory available ({_gib(2 * budget)}), at any decimation; shorten the records "
                     f"({argument('window')})")


@dataclasses.dataclass(frozen=True)
class _Shape:
    """What ``memory_bytes`` may read of a record decimated by a factor: its length, rate and name."""

    n: int
    fs: float
    of: object

    @property
    def name(self) -> str:
        return self.of.name

    @property
    def duration(self) -> float:
        return self.n / self.fs


def decimate_trial(trial, q: int, filter: str = "fir"):
    """Decimate ``trial`` by the whole factor ``q`` with :func:`jointbench.core.signal.resample_trial` (its
    anti-alias ``filter``; the angle's velocity before decimation kept as a channel)."""
    if q == 1:
        return trial
    from jointbench.core.signal import resample_trial

    try:
        return resample_trial(trial, trial.fs / q, filter=filter)
    except InputError as exc:
        raise InputError(f"{argument('decimate', q)}: {exc}") from None
