"""Skirt decomposition: a nonparametric time-varying FRF from one sparse-multisine record.

The system function is expanded on ``N_p + 1`` fixed basis functions of time (eq. 4),
``G(jw, t) = sum_p G_p(jw) b_p(t)``, so that the output is ``y(t) = sum_p b_p(t) G_p{u}(t)``
(eq. 5). For a periodic input whose lines lie on the DFT grid of the record, the output DFT is
linear in the LTI blocks ``G_p`` at the excited lines (eq. 7): each line ``k_e`` spreads into a
"skirt" ``G_p(k_e) U(k_e) B_p(k - k_e) / N`` around it. The ``G_p`` are estimated by linear least
squares in a band around three successive lines (eq. A.1, with the transient polynomial eq. A.2),
band by band (a sliding frequency window).

References
----------
van de Ruit, M., Cavallo, G., Lataire, J., van der Helm, F. C. T., Mugge, W., van Wingerden, J. W. &
Schouten, A. C. (2018). Revealing time-varying joint impedance with kernel-based regression and
nonparametric decomposition. IEEE Trans. Control Syst. Technol. 28(1), 224-237,
doi:10.1109/TCST.2018.2881664, Sec. II (eqs. 4-8), eq. 14 and Appendix A (eqs. A.1, A.2).

Lataire, J., Pintelon, R. & Louarroudi, E. (2012). Non-parametric estimate of the system function
of a time-varying system. Automatica 48(4), 666-672.
"""
from __future__ import annotations

import dataclasses
from typing import ClassVar, Literal

import numpy as np
import pandas as pd

from jointbench.estimators import Estimator, register
from jointbench.estimators._multisine_lines import multisine_bins
from jointbench.core.errors import InputError
from jointbench.core.estimate import Estimate, Intervals, Prediction
from jointbench.core.intervals import LEVEL, PINV_RCOND, psd_pinv, z_quantile
from jointbench.core.schema import Tune, param
from jointbench.core.types import Trial


def basis(n_p: int, t: np.ndarray, duration: float) -> np.ndarray:
    """Basis functions ``b_0 ... b_{N_p}`` at times ``t`` (s from the start of the record).

    ``b_0 = 1``, ``b_1 = 2 t / T - 1``, then ``b_p = cos(w_{p/2} t)`` for even ``p >= 2`` and
    ``b_p = sin(w_{(p-1)/2} t)`` for odd ``p >= 3``, with ``w_m = 2 pi m / T``, ``T = duration``.

    Returns
    -------
    ndarray
        Shape ``(N_p + 1, len(t))``.

    References
    ----------
    van de Ruit et al. (2018), eq. 14.
    """
    t = np.asarray(t, float)
    rows = [np.ones_like(t)]
    if n_p >= 1:
        rows.append(2 * t / duration - 1)
    for p in range(2, n_p + 1):
        w = 2 * np.pi * (p // 2) / duration
        rows.append(np.cos(w * t) if p % 2 == 0 else np.sin(w * t))
    return np.array(rows)


def basis_names(n_p: int) -> list[str]:
    """Labels of :func:`basis` rows: ``'1'``, ``'ramp'``, ``'cos1'``, ``'sin1'``, ``'cos2'`` ..."""
    return (["1", "ramp"] + [f"{'cos' if p % 2 == 0 else 'sin'}{p // 2}" for p in range(2, n_p + 1)])[:n_p + 1]


def skirt_halfwidth(n_p: int) -> int:
    """``M``: bins on each side of a line reached by the (co)sines of eq. 14 (``floor(N_p / 2)``, 0 if ``N_p < 2``)."""
    return n_p // 2 if n_p >= 2 else 0


@dataclasses.dataclass(eq=False)
class SkirtEstimate(Estimate):
    """LTI blocks ``G_p`` at the excited lines and the time-varying FRF they define.

    ``G(jw, t) = sum_p G_p(jw) b_p(t)`` with the basis of :func:`basis` on the fitted record
    (``t`` measured from ``time[0]``, ``T = duration``). ``G_p`` is known at :attr:`lines_hz` only;
    between lines it is interpolated linearly (real and imaginary parts separately) and outside
    ``[lines_hz[0], lines_hz[-1]]`` held at the end value, as :class:`~jointbench.core.estimate.FRFEstimate`
    does. Outside the record the basis is extrapolated (the ramp keeps rising, the (co)sines repeat).

    Attributes
    ----------
    lines_hz : ndarray
        Excited frequencies (Hz), increasing.
    Gp : ndarray of complex
        ``G_p(j w_l)``, shape ``(N_p + 1, len(lines_hz))``.
    fs : float
        Sampling rate (Hz) of the fitted record.
    time : ndarray
        Time base of the (first) fitted record.
    duration : float
        Record length ``T`` (s) on which the basis is defined.

    References
    ----------
    van de Ruit et al. (2018), eqs. 4, 5 and 14.
    """

    lines_hz: np.ndarray
    Gp: np.ndarray
    fs: float
    time: np.ndarray
    duration: float
    estimator: str = "skirt"

    @property
    def n_p(self) -> int:
        return self.Gp.shape[0] - 1

    def basis_at(self, t: np.ndarray | float) -> np.ndarray:
        """``b_p(t)`` for times ``t`` on the record's time base, shape ``(N_p + 1, t.size)``."""
        return basis(self.n_p, np.ravel(np.asarray(t, float)) - self.time[0], self.duration)

    def gp_at(self, f: np.ndarray) -> np.ndarray:
        """``G_p`` at frequencies ``f`` (Hz), interpolated between lines; shape ``(N_p + 1, f.size)``."""
        f = np.ravel(np.asarray(f, float))
        return np.array([np.interp(f, self.lines_hz, g.real) + 1j * np.interp(f, self.lines_hz, g.imag)
                         for g in self.Gp])

    def frequency_response(self, f: np.ndarray, t: np.ndarray | float | None = None) -> np.ndarray:
        """Frozen TV-FRF ``G(j 2 pi f, t) = sum_p G_p(j 2 pi f) b_p(t)``.

        Exact estimates at the excited lines, interpolated between them (see the class notes).
        Shape ``(len(t), len(f))`` for an array ``t``, ``(len(f),)`` for a scalar ``t``.
        """
        if t is None:
            raise ValueError(f"{self.estimator}: the estimate varies in time; give the time(s) t")
        ts = np.asarray(t, float)
        G = self.basis_at(ts).T @ self.gp_at(f)
        return G[0] if ts.ndim == 0 else G

    def stiffness(self, t: np.ndarray | float) -> np.ndarray:
        """``|G(j w_1, t)|`` at the lowest excited line ``w_1``.

        References
        ----------
        van de Ruit et al. (2018), Sec. IV-E: "the magnitude of the FRF at the lowest frequency".
        """
        ts = np.asarray(t, float)
        return np.abs(self.Gp[:, 0] @ self.basis_at(ts)).reshape(ts.shape)

    def predict(self, u: np.ndarray) -> np.ndarray:
        """``y(t) = sum_p b_p(t) (G_p u)(t)`` for an input ``u`` sampled at :attr:`fs`.

        ``u`` is taken to start at ``time[0]`` (the basis is evaluated at ``n / fs``). Each ``G_p``
        is applied in the frequency domain over the whole of ``u`` (circularly, i.e. as to one period
        of a periodic signal), interpolated between the lines, held outside them, and at DC its real
        part at the lowest line is used. For a periodic input on the identified lines (e.g. the
        validation trial of the study) this is the model's steady-state output; other inputs see
        wrap-around at the ends and an extrapolated response outside the excited band.

        References
        ----------
        van de Ruit et al. (2018), eq. 5 and Sec. IV-E (VAF of the predicted torque).
        """
        u = np.asarray(u, float)
        n = len(u)
        G = self.gp_at(np.fft.rfftfreq(n, 1.0 / self.fs))
        G[:, 0] = G[:, 0].real
        g = np.fft.irfft(G * np.fft.rfft(u), n, axis=1)
        return np.sum(basis(self.n_p, np.arange(n) / self.fs, self.duration) * g, axis=0)

    def prediction(self, trial, index: int = 0) -> Prediction:
        """:meth:`predict` and the torque (means removed) both kept to the band the lines excite: DFT bins
        up to the last line plus its skirt (``floor(N_p/2)`` bins); above it ``G_p`` is only held, not
        estimated."""
        y = trial.output - np.mean(trial.output)
        n = len(y)
        yhat = self.predict(trial.input - np.mean(trial.input))
        top = int(round(self.lines_hz[-1] * n / self.fs)) + skirt_halfwidth(self.n_p)
        keep = np.arange(n // 2 + 1) <= top
        band = lambda x: np.fft.irfft(np.fft.rfft(x) * keep, n)  # noqa: E731
        return Prediction(band(y), band(yhat), np.ones(n, bool), "torque and its prediction (means removed) up "
                          f"to the last excited line and its skirt ({(top * self.fs / n):.4g} Hz), every sample")

    def response_frame(self) -> pd.DataFrame:
        """Tidy ``G_p``: one row per basis function and line.

        Columns ``p``, ``basis`` (see :func:`basis_names`), ``freq_hz``, ``re``, ``im``, ``mag``, ``phase_rad``.
        """
        n_l = len(self.lines_hz)
        g = self.Gp.ravel()
        return pd.DataFrame({"p": np.repeat(np.arange(self.n_p + 1), n_l),
                             "basis": np.repeat(basis_names(self.n_p), n_l),
                             "freq_hz": np.tile(self.lines_hz, self.n_p + 1),
                             "re": g.real, "im": g.imag, "mag": np.abs(g), "phase_rad": np.angle(g)})

    def summary(self):
        out = super().summary()
        out["n_p"] = self.n_p
        out["lines"] = f"{len(self.lines_hz)} lines, {self.lines_hz[0]:g} ... {self.lines_hz[-1]:g} Hz"
        return out


@register("skirt", tags=("ltv", "nonparametric", "frf", "multisine", "ensemble"))
class Skirt(Estimator):
    """Skirt decomposition of the output spectrum of a sparse-multisine experiment.

    Model (eq. 7, written for real signals): with ``U``, ``Y``, ``B_p`` the DFTs of the input, the
    output and the basis functions (:func:`basis`, eq. 14) on the ``N``-sample record,

    ``Y(k) = (1/N) sum_p sum_l [G_p(l) U(l) B_p(k - l) + conj(G_p(l) U(l)) B_p(k + l)] + I_Y(k)``.

    The second term is the negative-frequency image of line ``l``; paper eq. 7 leaves it out. It
    reaches positive bins only through the ramp ``b_1`` (the (co)sines move a line by at most
    ``M = floor(N_p/2)`` bins and lines start above bin ``M``) and matters for the lowest band,
    where the image of line ``k_e^-`` is only ``2 k_e^-`` bins away. The unknowns enter with their
    conjugates, so each band is solved as a real least-squares problem in the real and imaginary
    parts. The triplet's own lines are then modelled exactly; the lines outside the band reach it
    only through the ``1/(k - l)`` tails of the ramp, which ``I_Y`` absorbs approximately.

    For every excited line ``k_e`` but the first and last, the triplet ``(k_e^-, k_e, k_e^+)`` of
    successive lines is fitted on bins ``k_e^- - D ... k_e^+ + D`` (clipped to ``1 ... (N-1)//2``)
    with unknowns ``G_p`` at each of the three lines (``3 (N_p + 1)`` complex; eq. A.1 gives
    every line its own ``G_p``, with no smoothness over frequency) and the transient polynomial
    ``I_Y(k) = sum_n r_n x^n``, ``x`` the bin scaled to [-1, 1] over the band (eq. A.2, order
    ``N_r``). Only the estimate at the centre line is kept; the first (last) line is taken from the
    first (last) band. Several records of one condition share the ``G_p`` (same length, same lines)
    and each has its own transient polynomial. Given an :class:`~jointbench.core.ensemble.Ensemble`, the
    skirt fits the ensemble average (ensemble mode, van de Ruit et al. 2018, Table II).

    Lines are detected from the input's DFT (bins more than ``threshold_db`` above the median bin
    power and above both neighbours, on a regular grid with empty bins between them, with at most 1 %
    of the power off them: the rule of every multisine estimator,
    :func:`estimators._multisine_lines.multisine_bins`) or given as ``lines_hz``. Requirements
    (each an :class:`~jointbench.core.errors.InputError` otherwise): at least three lines; successive
    lines at least ``2M + 1`` bins apart, so that the skirts (``+-M`` bins) of neighbouring lines
    never share a bin (each (co)sine pair is equivalent to one unknown at ``k_e - m`` and one at
    ``k_e + m``: a shared bin makes two unknowns inseparable); lowest line above bin ``M``, highest
    at most bin ``(N-1)//2 - M``; ``M <= D <= d - M - 1`` for the smallest spacing ``d`` (the band
    must hold the outer skirts of the triplet but not reach the skirt of a line outside it); and at
    least as many bins in each band as unknowns.

    Parameters
    ----------
    settings : Settings
        ``n_p`` (N_p, default 7); ``band_halfwidth`` (D in bins, default half the smallest line
        spacing); ``transient_order`` (N_r, default 0; none = no transient term); ``lines_hz``
        (default: detect); ``threshold_db`` (detection, default 20 dB).

    Notes
    -----
    Default ``D``: App. A calls ``D`` "the distance between two excited frequencies"; taken
    literally the band would end on the next lines outside the triplet (whose lines and skirts
    eq. A.1 does not model). Half the spacing ends the band midway to the next lines, so every bin in
    it is closer to a line of the triplet than to any other (8 ... 28 bins gave the same accuracy in
    our simulations of the study).
    Default ``N_r = 0``: the paper gives no order. A constant absorbs the local level of the leakage
    of the lines outside the band and of the transient; when the perturbation starts with the window
    (as in the study) the transient is mostly a torque spike at the first samples, whose DFT is flat.
    Higher orders must be extrapolated to the skirt of the lowest line, which sits at the band edge,
    and multiply the noise in the stiffness (our simulation of the study's 20 s sine at 10 dB SNR:
    RMSE_k about 1.05 N m/rad for N_r = 0, 1.4 for 1, 2.2 for 2) for no measurable gain without noise.

    References
    ----------
    van de Ruit et al. (2018), eqs. 4-8, 14, A.1, A.2 (module references). Lataire, Pintelon &
    Louarroudi (2012), Automatica 48(4).
    """

    perturbations = ("multisine",)   # it decomposes the skirts around the lines of a sparse multisine
    accepts = frozenset({"trial", "pooled", "ensemble"})

    @dataclasses.dataclass(frozen=True)
    class Settings:
        n_p: int | Literal["auto"] = param(7, ge=0, doc="order N_p of the time variation: basis b_0 ... b_Np (eq. 14); "
                                                        "auto = the order of least GCV", tune=Tune())
        band_halfwidth: int | None = param(None, ge=0, doc="D (bins): a triplet's band reaches D bins beyond "
                                                           "its outer lines; none = half the smallest spacing")
        transient_order: int | None = param(0, ge=0, doc="order N_r of the transient polynomial I_Y (eq. A.2); "
                                                         "none = no transient term")
        lines_hz: tuple[float, ...] | None = param(None, unit="Hz", gt=0,
                                                   doc="excited lines; none = detect them from the input's DFT")
        threshold_db: float = param(20.0, unit="dB", gt=0,
                                    doc="detection: excited bins stand this far above the median bin power")

        def __post_init__(self):
            if self.lines_hz is not None:
                if len(self.lines_hz) < 3:
                    raise ValueError(f"lines_hz: needs at least 3 lines for a band of three, got {len(self.lines_hz)}")
                if len(set(self.lines_hz)) != len(self.lines_hz):
                    raise ValueError("lines_hz: lines must be distinct")

    #: the setting ``--set auto=true`` chooses from the data (:meth:`choose_order`)
    AUTO: ClassVar[tuple[str, ...]] = ("n_p",)
    #: highest order tried by ``n_p = auto``
    MAX_AUTO_ORDER: ClassVar[int] = 15
    #: confidence level of the stiffness band

    def choose_order(self, trials: list[Trial]) -> tuple[SkirtEstimate, dict[int, float]]:
        """The estimate of the order ``N_p`` with the least generalised cross-validation score.

        ``GCV(N_p) = n RSS / (n - p)^2`` over the records' samples, ``RSS`` the squared residual of the
        predicted torque (:meth:`SkirtEstimate.predict`, means removed) and ``p`` the real parameters:
        ``2 (N_p + 1)`` per excited line plus each band's transient polynomial. Orders the line
        spacing or the band cannot hold are skipped. Returns the estimate and ``{N_p: GCV}``.

        Notes
        -----
        On the study's wrist (K between 4.7 and 6.5 N m/rad, two cycles in 40 s) it picks N_p = 4, the
        lowest order holding the variation, without noise (stiffness VAF 100 %), and N_p = 0 (time
        invariant) at a noise variance of 0.11 of the torque's, where no order tracks K reliably.
        """
        table, fits = {}, {}
        for n_p in range(self.MAX_AUTO_ORDER + 1):
            try:
                est = type(self)(dataclasses.replace(self.settings, n_p=n_p))._fit(trials)
            except InputError:
                continue
            nl = len(est.lines_hz)
            n_r = self.settings.transient_order
            p = 2 * (n_p + 1) * nl + (0 if n_r is None else 2 * (n_r + 1) * (nl - 2) * len(trials))
            n, rss = 0, 0.0
            for t in trials:
                r = (t.output - t.output.mean()) - est.predict(t.input - t.input.mean())
                n, rss = n + len(r), rss + float(r @ r)
            if n > p:
                table[n_p], fits[n_p] = n * rss / (n - p) ** 2, est
        if not table:
            raise InputError(f"{self.name}: n_p = auto: no order 0 ... {self.MAX_AUTO_ORDER} fits these lines and "
                             f"records")
        best = min(table, key=table.get)
        return fits[best], table

    def _fit(self, trials: list[Trial]) -> SkirtEstimate:
        if self.settings.n_p == "auto":
            est, table = self.choose_order(trials)
            est.fit_info = {**est.fit_info, "n_p": f"{est.n_p} chosen (auto: least GCV of the predicted torque; "
                            f"tried {', '.join(map(str, table))})"}
            return est
        s = self.settings
        n, fs = trials[0].n, trials[0].fs
        if any(t.n != n for t in trials):
            raise InputError(f"{self.name}: pooled records must have the same length (one basis on one window); "
                             f"got {sorted({t.n for t in trials})} samples")
        bins = self._lines(trials)
        T = n / fs
        M = skirt_halfwidth(s.n_p)
        top = (n - 1) // 2
        if len(bins) < 3:
            raise InputError(f"{self.name}: needs at least 3 excited lines for a band of three, found "
                             f"{len(bins)} ({', '.join(f'{k / T:g}' for k in bins)} Hz)")
        d = int(np.diff(bins).min())
        if d < 2 * M + 1:
            raise InputError(f"{self.name}: excited lines {d} bins ({d / T:g} Hz) apart are too close for n_p = "
                             f"{s.n_p}: the skirts reach +-{M} bins, so lines must be at least 2*{M}+1 = "
                             f"{2 * M + 1} bins apart; lower n_p or use a sparser multisine / longer record")
        if bins[0] <= M or bins[-1] > top - M:
            raise InputError(f"{self.name}: the skirts (+-{M} bins) of the lines at {bins[0] / T:g} and "
                             f"{bins[-1] / T:g} Hz must stay within bins 1 ... {top} ({1 / T:g} ... {top / T:g} Hz)")
        D = d // 2 if s.band_halfwidth is None else s.band_halfwidth
        if not M <= D <= d - M - 1:
            raise InputError(f"{self.name}: band_halfwidth = {D} bins must cover the outer skirts of a triplet "
                             f"(+-{M} bins for n_p = {s.n_p}) without reaching the skirts of the lines outside it "
                             f"(smallest spacing {d} bins): use {M} ... {d - M - 1} bins")
        Gp, cov0 = solve_bands([t.input for t in trials], [t.output for t in trials], bins, s.n_p, D,
                               s.transient_order, fs, self.name, return_cov=True)
        est = SkirtEstimate(lines_hz=bins / T, Gp=Gp, fs=fs, time=trials[0].time, duration=T,
                            estimator=self.name)
        return est.with_intervals(lambda: stiffness_band(est, cov0, LEVEL))   # on first use

    def _lines(self, trials: list[Trial]) -> np.ndarray:
        """Excited bins, detected or given, the same in every record."""
        s = self.settings
        found = [multisine_bins(f"{self.name}: record '{t.name}'", t.input, t.fs, s.threshold_db, s.lines_hz)
                 for t in trials]
        for t, b in zip(trials[1:], found[1:]):
            if not np.array_equal(b, found[0]):
                raise InputError(f"{self.name}: record '{t.name}' is excited at other lines than record "
                                 f"'{trials[0].name}'; pooled records need the same multisine lines")
        return found[0]


def stiffness_band(est: SkirtEstimate, cov0: np.ndarray, level: float) -> Intervals:
    """Pointwise band of the stiffness ``|G(j w_1, t)|`` from the covariance of ``G_p`` at the lowest line.

    ``cov0`` is that of ``[Re G_p, Im G_p]`` (:func:`solve_bands`); ``|g(t)|``, ``g = sum_p G_p b_p(t)``,
    is linearised: ``d|g| = (Re g d(Re g) + Im g d(Im g)) / |g|``. Normal quantiles.
    """

    b = est.basis_at(est.time).T                                    # (n, P)
    g = b @ est.Gp[:, 0]
    mag = np.maximum(np.abs(g), 1e-300)
    J = np.hstack([b * (g.real / mag)[:, None], b * (g.imag / mag)[:, None]])
    se = np.sqrt(np.maximum(np.sum((J @ cov0) * J, axis=1), 0.0))
    z = z_quantile(level)
    return Intervals(level=level, method="least-squares covariance of the lowest band (residual variance of its "
                                         "bins), linearised",
                     bounds={"stiffness": (np.abs(g) - z * se, np.abs(g) + z * se)})


def solve_bands(inputs: list[np.ndarray], outputs: list[np.ndarray], bins: np.ndarray, n_p: int, D: int,
                n_r: int | None, fs: float, name: str = "skirt", return_cov: bool = False):
    """``G_p`` at ``bins`` by least squares in sliding bands of three lines (eq. A.1 with images).

    Parameters
    ----------
    inputs, outputs : list of ndarray
        Records of equal length ``N`` (input ``u``, output ``y``).
    bins : ndarray of int
        Excited DFT bins, increasing, at least three.
    n_p : int
        Order ``N_p`` of the time variation.
    D : int
        Band half-width beyond the outer lines of a triplet (bins).
    n_r : int or None
        Order of the transient polynomial of each record; ``None`` = no transient term.
    fs : float
        Sampling rate (Hz), for the messages.
    name : str
        Prefix of the error messages.

    return_cov : bool
        Also return the covariance of ``[Re G_p, Im G_p]`` at the lowest line (from the first band:
        its residual variance times the inverse normal matrix).

    Returns
    -------
    ndarray of complex
        Shape ``(N_p + 1, len(bins))``; with ``return_cov`` also the ``2 (N_p + 1)`` square covariance.

    References
    ----------
    van de Ruit et al. (2018), eqs. 7, A.1 and A.2.
    """
    N = len(inputs[0])
    B = np.fft.fft(basis(n_p, np.arange(N), N), axis=1) / N    # exact DFTs of b_p (b_1 is no periodic signal)
    U = np.array([np.fft.fft(u) for u in inputs])
    Y = np.array([np.fft.fft(y) for y in outputs])
    P, n_l, n_t = n_p + 1, len(bins), len(inputs)
    n_poly = 0 if n_r is None else n_r + 1
    n_g, n_unknown = 3 * P, 3 * P + n_t * n_poly
    top = (N - 1) // 2
    bands = [np.arange(max(1, bins[c - 1] - D), min(top, bins[c + 1] + D) + 1) for c in range(1, n_l - 1)]
    rows = n_t * max(len(k) for k in bands)
    A = np.zeros((len(bands), 2 * rows, 2 * n_unknown))      # zero rows pad the shorter bands
    b = np.zeros((len(bands), 2 * rows))
    for i, k in enumerate(bands):
        trip, nb = bins[i:i + 3], len(k)
        if n_t * nb < n_unknown:
            raise InputError(f"{name}: the band around {trip[1] * fs / N:g} Hz has {nb} bins per record for "
                             f"{n_unknown} unknowns; lower n_p or transient_order, or widen band_halfwidth")
        # columns (line, p), then each record's polynomial; rows (record, bin)
        direct = B[:, (k[:, None] - trip[None, :]) % N].transpose(1, 2, 0)   # (nb, 3, P): B_p(k - l) / N
        image = B[:, (k[:, None] + trip[None, :]) % N].transpose(1, 2, 0)    # (nb, 3, P): B_p(k + l) / N
        Ul = U[:, trip][:, None, :, None]
        Ad = np.zeros((n_t, nb, n_unknown), complex)
        Ac = np.zeros((n_t, nb, n_unknown), complex)
        Ad[:, :, :n_g] = (Ul * direct).reshape(n_t, nb, n_g)
        Ac[:, :, :n_g] = (np.conj(Ul) * image).reshape(n_t, nb, n_g)
        x = (2 * k - (k[0] + k[-1])) / max(k[-1] - k[0], 1)
        for r in range(n_t):
            Ad[r, :, n_g + r * n_poly:n_g + (r + 1) * n_poly] = x[:, None] ** np.arange(n_poly)
        # Y = Ad z + Ac conj(z) with z = a + j b is  Y = (Ad + Ac) a + j (Ad - Ac) b
        plus, minus = (Ad + Ac).reshape(-1, n_unknown), (Ad - Ac).reshape(-1, n_unknown)
        m = n_t * nb
        A[i, :m] = np.hstack([plus.real, -minus.imag])
        A[i, rows:rows + m] = np.hstack([plus.imag, minus.real])
        yk = Y[:, k].ravel()
        b[i, :m], b[i, rows:rows + m] = yk.real, yk.imag
    sol = _batched_lstsq(A, b, [bins[i + 1] * fs / N for i in range(len(bands))], name)
    z = (sol[:, :n_g] + 1j * sol[:, n_unknown:n_unknown + n_g]).reshape(len(bands), 3, P)
    Gp = np.concatenate([z[:1, 0], z[:, 1], z[-1:, 2]]).T
    if not return_cov:
        return Gp
    m = 2 * n_t * len(bands[0])                        # real equations of the first band
    res = A[0] @ sol[0] - b[0]
    s2 = float(res @ res) / max(m - 2 * n_unknown, 1)
    cov = s2 * psd_pinv(A[0].T @ A[0], PINV_RCOND)
    idx = np.concatenate([np.arange(P), n_unknown + np.arange(P)])     # Re, Im of G_p at the lowest line
    return Gp, cov[np.ix_(idx, idx)]


def _batched_lstsq(A: np.ndarray, b: np.ndarray, where_hz: list[float], name: str) -> np.ndarray:
    """Least squares ``A[i] x[i] ~ b[i]`` for a stack of small full-rank problems.

    Normal equations on unit-norm columns, solved for all bands in one batched call, with one step
    of iterative refinement; far cheaper than a loop of SVD-based solvers for these 50-column
    problems. Raises :class:`InputError` when a band's matrix is (numerically) rank-deficient.
    """
    scale = np.linalg.norm(A, axis=1, keepdims=True)
    scale[scale == 0] = 1.0
    As = A / scale
    At = As.transpose(0, 2, 1)
    gram = At @ As
    ev = np.linalg.eigvalsh(gram)
    bad = ev[:, 0] <= 1e-12 * ev[:, -1]
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"{name}: the band around {where_hz[i]:g} Hz does not determine all unknowns (rank-deficient "
                         f"least squares); lower n_p or transient_order, or widen band_halfwidth")
    x = np.linalg.solve(gram, (At @ b[..., None]))
    x += np.linalg.solve(gram, At @ (b[..., None] - As @ x))
    return x[..., 0] / scale[:, 0, :]
