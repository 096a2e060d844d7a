"""FSEWLS: frequency separation and exponentially weighted least squares (Xu & Hollerbach 1998).

Time-varying ``I``, ``B``, ``K`` of ``tau = I theta'' + B theta' + K theta``: zero-phase high-pass
(eq. 3), state-variable filter (eq. 4), continuous-time EWLS integrated by RK4 (eqs. 5-6).
"""
from __future__ import annotations

import dataclasses
from typing import ClassVar, Literal

import numpy as np
import pandas as pd

from jointbench.estimators import Estimator, register
from jointbench.estimators._band import band_of_trials, welch_of_trials
from jointbench.estimators._ewls_band import forgetting_table, pointwise_bands
from jointbench.estimators._fsewls_kernels import (  # noqa: F401 - ewls_regression: public here, for controls
    ewls, ewls_regression, ewls_start, highpass, highpass_time_constant, svf, svf_pole)
from jointbench.core.band import MIN_RUN, chance, excited_share, input_band
from jointbench.core.errors import InputError
from jointbench.core.estimate import Intervals, ParametricEstimate, Prediction
from jointbench.core.intervals import LEVEL
from jointbench.core.schema import Tune, param
from jointbench.core.scores import vaf
from jointbench.core.types import Trial



# ------------------------------------------------------------------------------------------ estimate
def record_digest(trial) -> str:
    """SHA-1 of a record's angle and torque samples (which record an estimate was fitted on)."""
    import hashlib

    h = hashlib.sha1(np.ascontiguousarray(trial.angle, float).tobytes())
    h.update(np.ascontiguousarray(trial.torque, float).tobytes())
    return h.hexdigest()


@dataclasses.dataclass(eq=False, kw_only=True)
class FSEWLSEstimate(ParametricEstimate):
    """Time-varying ``I``, ``B``, ``K`` (arrays on :attr:`time`, the first record's) from FSEWLS.

    Attributes
    ----------
    filtered_torque : ndarray, shape (n_records, n)
        ``y = L H tau``, the output of the regression (eqs. 3-5).
    predicted_filtered_torque : ndarray, shape (n_records, n)
        ``Phi^T Theta`` with the parameters at each sample.
    transient : float
        Seconds at each end affected by the filters and the EWLS start (:meth:`FSEWLS.transient`).
    highpassed : ndarray, shape (2, n_records, n)
        Angle and torque after the high-pass ``H`` (eq. 3; as measured when it is off), means kept.

    :attr:`valid` = :meth:`steady` (read by :func:`jointbench.core.ensemble.valid_mask`). :meth:`predict` and
    :meth:`frequency_response` give torque from angle (impedance), whichever signal the trial imposed.

    References
    ----------
    Xu & Hollerbach (1998), eqs. 2-6.
    """

    filtered_torque: np.ndarray
    predicted_filtered_torque: np.ndarray
    transient: float
    highpassed: np.ndarray | None = None
    #: a digest of each fitted record's angle and torque (:func:`record_digest`): :meth:`prediction` holds only
    #: for those records (it is the regression's own output)
    fitted: tuple[str, ...] = ()

    def steady(self) -> np.ndarray:
        """Boolean mask of the samples at least :attr:`transient` seconds from both ends."""
        t = self.time
        return (t - t[0] >= self.transient) & (t[-1] - t >= self.transient)

    valid = property(steady)

    def damping_ratio(self) -> np.ndarray:
        """``B / (2 sqrt(K I))`` on :attr:`time`; NaN where ``K I <= 0`` (possible in transients).

        References
        ----------
        Xu & Hollerbach (1998), Sec. V-B (damping ratio, Figs. 8-9).
        """
        ki = self.K * self.I
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(ki > 0, self.B / (2.0 * np.sqrt(np.abs(ki))), np.nan)

    def output_vaf(self, steady_only: bool = True) -> float:
        """VAF (%) of the predicted filtered torque (:func:`jointbench.core.scores.vaf`), pooled over
        the records, on the :meth:`steady` samples unless ``steady_only=False``.

        References
        ----------
        Xu & Hollerbach (1998), Sec. III-B and Fig. 2 ("VAF of the output prediction").
        """
        keep = self.steady() if steady_only else np.ones(len(self.time), bool)
        return vaf(self.filtered_torque[:, keep], self.predicted_filtered_torque[:, keep])

    def prediction(self, trial, index: int = 0) -> Prediction:
        """What FSEWLS predicts: the filtered torque ``y = L H tau`` of record ``index`` and
        ``Phi^T Theta(t)``, on the :meth:`steady` samples (its :meth:`output_vaf` for that record).

        :meth:`predict` instead differentiates the angle twice, which amplifies its noise: a VAF on it
        says little about the fit (even the true parameters can score far below zero).
        """
        if self.fitted and (index >= len(self.fitted) or record_digest(trial) != self.fitted[index]):
            raise InputError(f"{self.estimator}: its prediction is the filtered torque of the records it was fitted "
                             f"on (the regression's output, eqs. 3-5), and this record is not record {index + 1} of "
                             f"them: fit this record to score it (a held-out score needs a refit)")
        return Prediction(self.filtered_torque[index], self.predicted_filtered_torque[index], self.steady(),
                          "the filtered torque L H tau (the regression's output, eqs. 3-5) against Phi^T "
                          f"Theta(t), on the samples {self.transient:.3g} s or more from either end")

    def frequency_response(self, f: np.ndarray, t=None) -> np.ndarray:
        """Frozen impedance ``K(t) + j w B(t) - I(t) w^2`` at times ``t`` (s), frequencies ``f`` (Hz)."""
        if t is None:
            raise ValueError("fsewls: the estimate varies in time; give the time(s) t")
        w = 2 * np.pi * np.asarray(f, float)
        ts = np.asarray(t, float)
        p = {k: self._on(getattr(self, k), np.atleast_1d(ts))[:, None] for k in ("I", "B", "K")}
        H = p["K"] + 1j * w * p["B"] - p["I"] * w ** 2
        return H[0] if ts.ndim == 0 else H

    def to_frame(self) -> pd.DataFrame:
        """``time``, ``I``, ``B``, ``K``, ``stiffness`` (with their limits), the fitted band, ``steady``, then
        per record ``filtered_torque`` and ``predicted_filtered_torque`` (suffixed ``_1``, ``_2`` ... from the
        second record on)."""
        frame = super().to_frame()
        frame["steady"] = self.steady()
        for k, (y, yhat) in enumerate(zip(self.filtered_torque, self.predicted_filtered_torque)):
            frame[f"filtered_torque{f'_{k}' if k else ''}"] = y
            frame[f"predicted_filtered_torque{f'_{k}' if k else ''}"] = yhat
        return frame

    def summary(self):
        out = {**super().summary(), "transient_s": float(self.transient)}
        return {**out, "output_vaf": self.output_vaf()} if self.steady().sum() > 1 else out


# ----------------------------------------------------------------------------------------- estimator
@register("fsewls", tags=("ltv", "parametric", "recursive"))
class FSEWLS(Estimator):
    """Time-varying I, B, K by frequency separation and exponentially weighted least squares.

    1. ``H``: zero-phase Chebyshev type I high-pass of angle and torque (:func:`highpass`, eq. 3).
    2. ``L(s) = s^(n-2) a^n / (s + a)^n``: ``Phi = [s^2 L, s L, L] theta~``, ``y = L tau~``
       (:func:`svf`, eq. 4); zero phase unless ``svf_causal``.
    3. EWLS ``Theta' = P Phi (y - Phi^T Theta)``, ``P' = -P Phi Phi^T P + lam P`` (eq. 6) by classical
       RK4 at the sampling period, mid-points by linear interpolation (:func:`ewls`). ``Theta(0)`` is
       the ordinary least-squares fit to the first ``init_window`` seconds and
       ``P(0) = (sum of Phi Phi^T dt over that window)^-1``, the inverse of the information the window
       holds on the time scale of eq. 6.

    The impedance (torque from angle) is fitted whichever signal the trial imposed; means are removed
    before L. Aligned records of equal length are pooled instant by instant (their ``Phi Phi^T`` and
    ``Phi y`` add in eq. 6). Each end loses ``transient = 3 T_hp + 10/a + 7/forgetting`` seconds
    (:meth:`transient`; ``T_hp`` is the slowest time constant of the high-pass, 0.97 s at 1 Hz), and a
    record shorter than ``2 transient + init_window`` is refused.

    Parameters
    ----------
    settings : Settings
        ``highpass_cutoff`` (Hz, 1; none = off), ``highpass_order`` (4), ``highpass_ripple`` (dB, 0.5,
        not in the paper), ``svf_order`` (3), ``svf_cutoff`` (Hz, 3.2), ``svf_cutoff_means`` ('-3dB'),
        ``svf_causal`` (false), ``forgetting`` (1/s, 20), ``init_window`` (s, 0.5).

    Notes
    -----
    Readings (study sheet A): H is "zero-phase-shift acausal"; for L the paper does not say. A causal L
    lags the estimates by about ``n/a`` (76 ms at a = 39.4 rad/s, 149 ms at 2 pi 3.2 rad/s) on top of
    the EWLS lag ``1/lam``, too much for the paper's Fig. 2: the default is zero phase with ``|L|``
    kept. "Cutoff frequency" is read as the -3 dB point of ``a^n / (s + a)^n``.

    References
    ----------
    Xu, Y. & Hollerbach, J. M. (1998). Identification of human joint mechanical properties from single
    trial data. IEEE Trans. Biomed. Eng., eqs. 3-6 and Sec. III-B.
    """

    accepts = frozenset({"trial", "pooled"})      # every record given enters the fit

    @dataclasses.dataclass(frozen=True)
    class Settings:
        highpass_cutoff: float | None = param(1.0, unit="Hz", gt=0, doc="edge of the high-pass H (eq. 3); none = off")
        highpass_order: int = param(4, ge=1, doc="order of the Chebyshev type I high-pass (run both ways)")
        highpass_ripple: float = param(0.5, unit="dB", gt=0, doc="pass-band ripple of the high-pass")
        svf_order: int = param(3, ge=2, doc="order n of L(s) = s^(n-2) a^n / (s + a)^n (eq. 4)")
        svf_cutoff: float = param(3.2, unit="Hz", gt=0, doc="cutoff of the state-variable filter L")
        svf_cutoff_means: Literal["-3dB", "a"] = param("-3dB", doc="-3 dB point of a^n/(s+a)^n, or 'a' (2 pi cutoff)")
        svf_causal: bool = param(False, doc="true: causal L (lags ~ n/a); false: zero phase, |L| kept")
        svf_form: Literal["printed", "lowpass"] = param("printed", doc="L = s^(n-2) a^n/(s+a)^n as printed, or "
                                                                       "a^n/(s+a)^n")
        forgetting: float | Literal["auto"] = param(20.0, unit="1/s", gt=0, doc="forgetting rate lambda of the EWLS "
                                                    "(eq. 6); auto = the held-out prediction's best", tune=Tune())
        init_window: float = param(0.5, unit="s", gt=0, doc="first seconds fitted for Theta(0) and P(0)")

    #: the setting ``--set auto=true`` chooses from the data (:meth:`choose_forgetting`)
    AUTO: ClassVar[tuple[str, ...]] = ("forgetting",)
    #: forgetting rates (1/s) tried by :meth:`choose_forgetting`
    FORGETTING_GRID: ClassVar[tuple[float, ...]] = (5.0, 7.0, 10.0, 14.0, 20.0, 30.0, 45.0, 70.0, 100.0, 150.0)
    #: confidence level of the pointwise bands

    def pole(self) -> float:
        """Pole ``a`` (rad/s) of the state-variable filter."""
        s = self.settings
        return svf_pole(s.svf_cutoff, s.svf_order, s.svf_cutoff_means)

    def transient(self) -> float:
        """Seconds discarded at each end: ``3 T_hp + 10/a + 7/forgetting`` (``T_hp = 0`` without H)."""
        s = self.settings
        hp = 0.0 if s.highpass_cutoff is None else 3.0 * highpass_time_constant(
            s.highpass_cutoff, s.highpass_order, s.highpass_ripple)
        return hp + 10.0 / self.pole() + 7.0 / s.forgetting

    def _check(self, trials: list[Trial]) -> None:
        s, first = self.settings, trials[0]
        fs, where = first.fs, f"{self.name}: trial '{first.name}'"
        if any(t.n != first.n for t in trials):
            raise InputError(f"{self.name}: pooled records must be aligned and of equal length, got "
                             f"{sorted({t.n for t in trials})} samples")
        for t in trials:  # Trial rejects non-finite data; guard against arrays changed afterwards
            if not (np.isfinite(t.angle).all() and np.isfinite(t.torque).all()):
                raise InputError(f"{self.name}: trial '{t.name}' has non-finite angle or torque (NaN or inf)")
        if s.highpass_cutoff is not None and not s.highpass_cutoff < fs / 2:
            raise InputError(f"{where}: highpass_cutoff = {s.highpass_cutoff:g} Hz must be below the "
                             f"Nyquist frequency {fs / 2:g} Hz")
        a = self.pole()
        if a > 2 * np.pi * fs / 10:
            raise InputError(f"{where}: the state-variable filter's pole a = {a:.4g} rad/s ({a / (2 * np.pi):.4g}"
                             f" Hz, from svf_cutoff = {s.svf_cutoff:g} Hz, svf_cutoff_means = "
                             f"{s.svf_cutoff_means!r}) must be at most fs/10 = {fs / 10:g} Hz")
        if s.forgetting / fs > 0.5:
            raise InputError(f"{where}: forgetting = {s.forgetting:g} 1/s is too fast for {fs:g} Hz: the RK4 "
                             f"step needs forgetting / fs <= 0.5")
        need = 2 * self.transient() + s.init_window
        if first.duration < need:
            raise InputError(f"{where}: {first.n} samples ({first.duration:.3g} s) are too short: FSEWLS "
                             f"needs 2 x {self.transient():.3g} s of transients (from highpass_cutoff, "
                             f"svf_cutoff and forgetting) + init_window {s.init_window:g} s = {need:.3g} s")

    #: the refusal's threshold: the probability that the fitted band's count of coherent frequencies arises by
    #: chance (no input there) above which the fit is refused (1 in 1000: a rare false refusal)
    REFUSE_CHANCE: ClassVar[float] = 1e-3
    #: upper edge of the band checked, in svf_cutoff: L's stiffness regressor (a^n s^(n-2) / (s + a)^n) is down
    #: 40 dB at 10 svf_cutoff; its inertia regressor is not, so the band is not [highpass, svf_cutoff]
    CHECKED_UP_TO: ClassVar[float] = 10.0

    def _input_band(self, trials: list[Trial], highpassed: np.ndarray) -> str:
        """The input's band against the fitted one (issue 20), as the summary's ``band`` line; a refusal when
        the fitted band holds too little of the input.

        The band is that of the high-passed angle and torque (what the regression sees; eq. 3), on the samples
        ``3 T_hp`` or more from either end (the high-pass's edge transients are coherent in both signals). The
        fit is refused when, from ``highpass_cutoff`` to :data:`CHECKED_UP_TO` ``svf_cutoff``, they are
        coherent (:func:`estimators._band.excited_share`) at no more frequencies than chance explains
        (:func:`estimators._band.chance` above :data:`REFUSE_CHANCE`) and in no run of
        :data:`estimators._band.MIN_RUN` adjacent frequencies (a narrow band, e.g. 0.1 ... 0.4 Hz with the
        high-pass off, is a run; the count of a narrow band in a wide one is not beyond chance): a
        perturbation below the high-pass. A
        share of the imposed signal's variance passing H cannot tell that: a voluntary movement below the
        cutoff dominates the variance by design (frequency separation; the lpv study's slow movement),
        whereas coherence is per frequency. The band checked is wider than ``highpass ... svf_cutoff``: a
        movement (or a fast variation of K) there makes the LTI coherence fall at its frequencies while the
        perturbation above still informs the fit (xu1998's movement at f_v = 1.5 Hz).

        Raises
        ------
        InputError
            The fitted band holds too little of the input (one line: the share, the input's band, the
            settings to change).
        """
        s, fs = self.settings, trials[0].fs
        hp = 0.0 if s.highpass_cutoff is None else float(s.highpass_cutoff)
        m = 0 if s.highpass_cutoff is None else int(np.ceil(3.0 * highpass_time_constant(
            s.highpass_cutoff, s.highpass_order, s.highpass_ripple) * fs))
        hp_trials = [Trial.from_arrays(highpassed[0, r, m:highpassed.shape[-1] - m],
                                       highpassed[1, r, m:highpassed.shape[-1] - m], fs, imposed=t.imposed,
                                       name=t.name) for r, t in enumerate(trials)]
        frf = welch_of_trials(self.name, hp_trials)
        band = None if frf is None else input_band(frf)
        fitted = (f"fitted {hp:g} Hz (high-pass) ... state-variable filter cutoff {s.svf_cutoff:g} Hz "
                  f"({s.svf_cutoff_means})")
        if frf is not None:
            top = min(self.CHECKED_UP_TO * s.svf_cutoff, fs / 2)
            excited, powered = excited_share(frf, hp, top)
            p = chance(excited, powered)
            if p > self.REFUSE_CHANCE and input_band(frf, hp, top) is None:
                raw = band_of_trials(self.name, trials, segment=8.0 / max(hp, 0.25))
                raise InputError(
                    f"{self.name}: trial '{trials[0].name}': the {fitted} holds no measurable input: from "
                    f"{hp:g} to {top:g} Hz the high-passed angle and torque are coherent (95 %) at {excited} of "
                    f"{powered} frequencies, as chance would be (p = {p:.2g}), in no run of {MIN_RUN} adjacent "
                    f"ones (the input's band {'unknown' if raw is None else raw.text()}); lower highpass_cutoff "
                    f"below the perturbation's band")
        text = "unknown" if band is None else band.text()
        return f"{fitted}; the high-passed input's band {text}"

    def _fit(self, trials: list[Trial]) -> FSEWLSEstimate:
        if self.settings.forgetting == "auto":
            lam, table = self.choose_forgetting(trials)
            est = type(self)(dataclasses.replace(self.settings, forgetting=lam))._fit(trials)
            est.fit_info = {**est.fit_info, "forgetting": f"{lam:g} 1/s chosen (auto: held-out prediction VAF "
                            f"{table[lam]:.2f} %; tried " + ", ".join(f"{k:g}" for k in table) + " 1/s)"}
            return est
        Phi, y, R0, r0, highpassed = self._regression(trials)
        band = self._input_band(trials, highpassed)
        s, fs = self.settings, trials[0].fs
        try:
            Theta = ewls(Phi, y, 1.0 / fs, s.forgetting, R0, r0)
        except np.linalg.LinAlgError:
            raise InputError(f"{self.name}: trial '{trials[0].name}': the EWLS information matrix became "
                             f"singular (no perturbation for much longer than 1/forgetting?)") from None
        est = FSEWLSEstimate(I=Theta[:, 0], B=Theta[:, 1], K=Theta[:, 2], fs=fs, time=trials[0].time,
                             estimator=self.name, filtered_torque=y,
                             predicted_filtered_torque=np.einsum("rni,ni->rn", Phi, Theta),
                             transient=self.transient(), highpassed=highpassed,
                             fitted=tuple(record_digest(t) for t in trials))
        est.fit_info = {**est.fit_info, "band": band}
        # the fitted band as the CSV's band_lo_hz, band_hi_hz (the summary's band line)
        est.band_hz = (0.0 if s.highpass_cutoff is None else float(s.highpass_cutoff), float(s.svf_cutoff))
        return est.with_intervals(lambda: self.bands(Phi, y, Theta, est.steady(), fs, R0))   # on first use

    def holdout_delay(self, fs: float) -> int:
        """Samples between an estimate and the sample it predicts when held out: ``2/a`` (the
        state-variable filter's memory, beyond which the noise has decorrelated)."""
        return max(1, int(round(2.0 / self.pole() * fs)))

    def bands(self, Phi: np.ndarray, y: np.ndarray, Theta: np.ndarray, steady: np.ndarray, fs: float,
              R0: np.ndarray) -> Intervals:
        """Pointwise 95 % bands of I(t), B(t), K(t) (:func:`estimators._ewls_band.pointwise_bands`), the EWLS
        started from ``R0`` (:func:`estimators._fsewls_kernels.ewls_start`)."""
        m0 = max(int(round(self.settings.init_window * fs)), 3)
        return pointwise_bands(Phi, y, Theta, 1.0 / fs, float(self.settings.forgetting), self.holdout_delay(fs),
                               steady, LEVEL, R0, m0)

    def choose_forgetting(self, trials: list[Trial]) -> tuple[float, dict[float, float]]:
        """The forgetting rate of :data:`FORGETTING_GRID` whose estimate best predicts held-out samples
        (:func:`estimators._ewls_band.forgetting_table`); returns it and ``{rate: VAF}``. Rates the
        record is too short for, or too fast for the RK4 step, are skipped."""
        fs = trials[0].fs
        grid = []
        for lam in self.FORGETTING_GRID:
            candidate = type(self)(dataclasses.replace(self.settings, forgetting=lam))
            try:
                candidate._check(trials)
            except InputError:
                continue
            grid.append((lam, candidate))
        if not grid:
            raise InputError(f"{self.name}: forgetting = auto: the record ({trials[0].duration:.3g} s at {fs:g} Hz) is "
                             f"too short or too slowly sampled for every rate tried "
                             f"({', '.join(f'{v:g}' for v in self.FORGETTING_GRID)} 1/s)")
        Phi, y, R0, r0, _ = grid[0][1]._regression(trials)
        tr = max(e.transient() for _, e in grid)
        t = trials[0].time
        keep = (t - t[0] >= tr) & (t[-1] - t >= tr)
        table = forgetting_table(Phi, y, R0, r0, 1.0 / fs, [lam for lam, _ in grid], self.holdout_delay(fs), keep,
                                 ewls)
        return max(table, key=table.get), table

    def _regression(self, trials: list[Trial]) -> tuple[np.ndarray, ...]:
        """Checked records -> ``Phi``, ``y`` (eqs. 3-5), the initial ``R0``, ``r0`` of the EWLS and the
        high-passed angle and torque (eq. 3)."""
        self._check(trials)
        s, fs = self.settings, trials[0].fs
        x = np.stack([[t.angle for t in trials], [t.torque for t in trials]])
        size = np.abs(x[0]).max(axis=-1)
        if s.highpass_cutoff is not None:
            x = highpass(x, fs, s.highpass_cutoff, s.highpass_order, s.highpass_ripple)
        highpassed, (theta, tau) = x, x - x.mean(axis=-1, keepdims=True)
        Phi, y = svf(theta, tau, fs, self.pole(), s.svf_order, s.svf_causal, s.svf_form)
        R0, r0 = ewls_start(Phi, y, fs, s.init_window)
        scale = np.sqrt(np.diag(R0))
        if (np.any(np.std(theta, axis=-1) <= 1e-10 * size) or not np.all(scale > 0)
                or np.linalg.cond(R0 / np.multiply.outer(scale, scale)) > 1e12):
            raise InputError(f"{self.name}: trial '{trials[0].name}': the filtered angle cannot separate I, "
                             f"B and K in the first init_window = {s.init_window:g} s (constant angle or "
                             f"no perturbation?)")
        return Phi, y, R0, r0, highpassed
