"""Ready classical pipelines that end in a composite model, and their comparison on equal terms.

Each pipeline runs one classical method of Quinchia et al. (2013, Section 5) on a static error
signal and returns a frozen result with the composite ``model`` (built from the reading's
coefficients through the registry, :mod:`stochmod.fit.classical.build`) and the intermediate
readings:

==========================  =====================================  ==============================
pipeline                    method (Quinchia 2013)                 model
==========================  =====================================  ==============================
:func:`av_model`            AV slope reading (5.5, "15AV"/"18AV")  WN(N) + GM(B, Tc) + RW(K)
:func:`avwd_model`          AV + wavelet de-noising (5.6, 18AVWD)  the same, plus the de-noising
:func:`denoised_ar_model`   de-noise, then Burg AR(p) (5.3)        AR(p) of the de-noised signal
:func:`psd_model`           PSD slope reading (5.4)                WN(N) + GM(B, Tc from AV) + RW
:func:`acf_gm_model`        autocorrelation 1/e decay (5.2)        GM(Tc, sigma)
==========================  =====================================  ==============================

:func:`compare_models` scores any set of models, whatever method made them, by the GMWM
objective (Stebler et al. 2014, eq. 20) of their theoretical Haar wavelet variance against the
data's empirical one, with the diagonal weighting ``stochmod.gmwm`` uses by default: the
criterion a GMWM fit minimises, so a GMWM fit of a structure is the best that structure can do
on it, and every other model's distance from that optimum is on the same scale.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.checks import as_signal, check_freq, check_positive_int
from stochmod.fit.classical.build import acf_model, allan_model, ar_model, psd_reading_model
from stochmod.core.errors import EstimationError, InputError, SpecError
from stochmod.fit.weighting import chi2_variance
from stochmod.core.model import Model, as_model
from stochmod.plugin.spec import model_from_spec
from stochmod.core.process import Process
from stochmod.core.tables import format_number, format_table
from stochmod.empirical.acf import GMAcfFit, fit_gm_acf
from stochmod.empirical.allan_reading import AllanReading, allan_reading
from stochmod.empirical.ar_fit import ARFit, fit_ar
from stochmod.empirical.denoise import DenoisedAllan, WaveletDenoising, denoised_allan, wavelet_denoise
from stochmod.empirical.psd import PSDReading, psd_reading
from stochmod.empirical.wavelet_variance import WaveletVariance, wvar

__all__ = [
    "AVModel",
    "AVWDModel",
    "DenoisedARModel",
    "PSDModel",
    "ACFGMModel",
    "ModelScore",
    "ModelComparison",
    "av_model",
    "avwd_model",
    "denoised_ar_model",
    "psd_model",
    "acf_gm_model",
    "compare_models",
]

#: Terms of the "18AV" model (Quinchia Table 8): white noise, bias instability, random walk.
AV_TERMS = ("N", "B", "K")
#: De-noising settings a pipeline passes on (Quinchia Sections 5.2-5.6: db4, soft SURE).
_DENOISE_KEYS = ("wavelet", "rule", "mode", "noise")


def _denoise_options(options: Mapping[str, Any] | None) -> dict[str, Any]:
    """Checked keyword options for :func:`stochmod.empirical.denoise.wavelet_denoise`."""
    options = dict(options or {})
    unknown = sorted(set(options) - set(_DENOISE_KEYS))
    if unknown:
        raise InputError(f"denoise options {unknown} are unknown; use {list(_DENOISE_KEYS)}")
    return options


def _join(*parts: str) -> str:
    return "\n\n".join(p for p in parts if p)


# ----------------------------------------------------------------------------- AV ("18AV")


@attrs.frozen
class AVModel:
    """The "18AV" pipeline: Allan slope reading turned into WN + GM + RW.

    Attributes
    ----------
    model : Model
        WN(N) + GM(B, Tc) + RW(K) of the identified terms, at `freq`.
    reading : AllanReading
        The slope reading (coefficients with intervals, Tc, the Allan variance).
    freq : float
        Sampling frequency, Hz.
    """

    model: Model
    reading: AllanReading
    freq: float

    def summary(self) -> str:
        """The reading and the model it gives."""
        return _join(self.reading.summary(), self.model.summary())


def av_model(
    x: ArrayLike,
    freq: float,
    *,
    terms: Sequence[str] = AV_TERMS,
    gm: str = "quinchia",
    unit: str | None = None,
    **reading_kwargs: Any,
) -> AVModel:
    """Allan-variance model in the style of Quinchia's 15AV / 18AV (Sections 5.5-6, Table 8).

    Parameters
    ----------
    x : array_like, shape (n,)
        Static error signal (rad/s, m/s^2 ...), turn-on bias included or not.
    freq : float
        Sampling frequency, Hz.
    terms : sequence of str
        Coefficients the reading looks for (default N, B, K: the 18AV structure; add "Q", "R"
        for quantization and rate ramp).
    gm : {"quinchia", "matched"}
        GM built from B and Tc (:func:`stochmod.fit.classical.allan_model`): Quinchia's
        ``beta = 1/Tc, sigma = 0.664 B`` or the GM whose Allan peak sits on the floor.
    unit : str, optional
        Signal unit, for the datasheet columns of the summary.
    **reading_kwargs
        Passed to :func:`stochmod.empirical.allan_reading.allan_reading`.

    Returns
    -------
    AVModel
        Only the identified terms enter the model (a gyro without a K region gets WN + GM,
        Quinchia's 15-state gyro model).

    Raises
    ------
    EstimationError
        The reading identified none of `terms`.
    """
    freq = check_freq(freq)
    reading = allan_reading(x, freq, terms=terms, gm=gm, unit=unit, **reading_kwargs)
    return AVModel(model=allan_model(reading, freq), reading=reading, freq=freq)


# ----------------------------------------------------------------------------- AVWD ("18AVWD")


@attrs.frozen
class AVWDModel:
    """The "18AVWD" pipeline: the Allan model, used with wavelet de-noising of the input.

    Attributes
    ----------
    model : Model
        WN(N) + GM(B, Tc) + RW(K) of the raw signal's Allan reading (the 18AV model).
    reading : AllanReading
        That reading (Quinchia Section 5.5, Tables 4-5).
    denoised : DenoisedAllan
        The de-noising (``denoised.denoising``: levels, thresholds, the de-noised signal) that
        the navigation filter's input goes through before the mechanisation (Quinchia Fig. 3,
        Table 7), and the octave Allan variances before and after it (Fig. 17).
    freq : float
        Sampling frequency, Hz.
    """

    model: Model
    reading: AllanReading
    denoised: DenoisedAllan = attrs.field(repr=False)
    freq: float

    @property
    def level(self) -> int:
        """Levels of decomposition (LOD)."""
        return self.denoised.level

    @property
    def band_limit(self) -> float:
        """Upper frequency of the kept band, ``freq / 2^(level+1)`` Hz."""
        return self.denoised.band_limit

    @property
    def tau_limit(self) -> float:
        """``2^(level+1) / freq`` s: above it the de-noised AV should follow the raw one."""
        return self.denoised.tau_limit

    def long_term_check(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Fig. 17's check, at the octave taus >= `tau_limit`.

        Returns
        -------
        tau : ndarray
            Averaging times, s.
        ratio : ndarray
            De-noised AV / raw AV.
        inside : ndarray of bool
            Whether the de-noised AV lies inside the raw AV's confidence interval: the
            long-term noise the model's B, Tc, K describe is still in the de-noised input.
        """
        raw, den = self.denoised.raw, self.denoised.denoised
        keep = raw.tau >= self.tau_limit * (1 - 1e-9)
        ratio = den.avar[keep] / raw.avar[keep]
        inside = (den.avar[keep] >= raw.ci_low[keep]) & (den.avar[keep] <= raw.ci_high[keep])
        return raw.tau[keep], ratio, inside

    def summary(self) -> str:
        """The reading, the de-noising, Fig. 17's check and the model."""
        den = self.denoised.denoising
        tau, ratio, inside = self.long_term_check()
        check = format_table(
            ["tau [s]", "AV de-noised / raw", "inside raw CI"],
            [[t, r, "yes" if i else "NO"] for t, r, i in zip(tau, ratio, inside)],
            title=(f"18AVWD: de-noising {self.level} levels ({den.wavelet}, {den.rule}, "
                   f"{den.mode}) keeps 0-{format_number(self.band_limit, 4)} Hz; the long-term "
                   f"noise should be intact above tau = {format_number(self.tau_limit, 4)} s"),
            digits=4,
        )
        return _join(self.reading.summary(), check, self.model.summary())


def avwd_model(
    x: ArrayLike,
    freq: float,
    *,
    level: int | None = None,
    f_limit: float | None = None,
    denoise: Mapping[str, Any] | None = None,
    terms: Sequence[str] = AV_TERMS,
    gm: str = "quinchia",
    unit: str | None = None,
    **reading_kwargs: Any,
) -> AVWDModel:
    """Quinchia's 18AVWD: the Allan model plus wavelet de-noising of the input (Section 5.6).

    Which signal each part comes from, in the paper (Sections 5.5, 5.6, 6 and 7): every model
    parameter (N, B and Tc, K) is the Allan-variance one of Section 5.5, read on the *raw*
    static record (Tables 4 and 5): "having selected the LOD for wavelet de-noising, the
    long-term noises are modeled and compensated by the AV parameters obtained in Section
    5.5", and 18AVWD "corresponds to the case of EKF with 18 states", the 18AV model (Table
    8), with the measurements de-noised before the mechanisation. The de-noised signal's Allan
    variance (Fig. 17) serves to choose the LOD and to show that the long-term noise is left
    intact above the cluster time ``2^(LOD+1) / freq`` while the short-term noise below it is
    removed; no coefficient is read off it (N could not be: the white noise is gone below the
    limit, and above it the curve is the raw one, so B, Tc and K would be the same numbers).

    This function does the same: the model is :func:`av_model`'s on the raw signal; the
    result adds the de-noising and the two Allan variances, and
    :meth:`AVWDModel.long_term_check` compares them above the limit.

    Parameters
    ----------
    x : array_like, shape (n,)
        Static error signal.
    freq : float
        Sampling frequency, Hz.
    level, f_limit : int or float
        Levels of decomposition, or the band to keep in Hz (exactly one; Quinchia Table 7:
        7 LOD / 0.39 Hz for the gyros and Acc X, 6 LOD / 0.78 Hz for Acc Y and Z at 100 Hz).
    denoise : mapping, optional
        Other de-noising settings: `wavelet`, `rule`, `mode`, `noise` of
        :func:`stochmod.empirical.denoise.denoise` (default db4, soft SURE, as the paper).
    terms, gm, unit, **reading_kwargs
        As for :func:`av_model`.

    Returns
    -------
    AVWDModel

    Raises
    ------
    InputError
        Neither or both of `level` and `f_limit`.
    EstimationError
        The reading identified none of `terms`.
    """
    freq = check_freq(freq)
    if (level is None) == (f_limit is None):
        raise InputError("give exactly one of level (levels of decomposition) or f_limit (Hz)")
    x = as_signal(x, name="x", min_length=8)
    av = av_model(x, freq, terms=terms, gm=gm, unit=unit, **reading_kwargs)
    den = denoised_allan(x, freq, level=level, f_limit=f_limit, **_denoise_options(denoise))
    return AVWDModel(model=av.model, reading=av.reading, denoised=den, freq=freq)


# ----------------------------------------------------------------------------- de-noise + AR


@attrs.frozen
class DenoisedARModel:
    """De-noise, then AR(p) by Burg (Quinchia Section 5.3, Table 2; the 15AR / 27AR models).

    Attributes
    ----------
    model : Model
        The AR(p) of the de-noised signal.
    ar : ARFit
        The AR fit (coefficients, innovation variance, order table).
    denoising : WaveletDenoising
        The de-noising that preceded it.
    freq : float
        Sampling frequency, Hz.
    """

    model: Model
    ar: ARFit
    denoising: WaveletDenoising = attrs.field(repr=False)
    freq: float

    def summary(self) -> str:
        """De-noising thresholds, the AR fit and the model."""
        return _join(self.denoising.summary(), self.ar.summary(), self.model.summary())


def denoised_ar_model(
    x: ArrayLike,
    freq: float,
    order: int | None = 3,
    *,
    level: int | None = 6,
    f_limit: float | None = None,
    denoise: Mapping[str, Any] | None = None,
    method: str = "burg",
    max_order: int = 10,
    criterion: str = "bic",
) -> DenoisedARModel:
    """AR(p) of the wavelet de-noised signal (Quinchia Section 5.3).

    Parameters
    ----------
    x : array_like, shape (n,)
        Static error signal.
    freq : float
        Sampling frequency, Hz.
    order : int or None
        AR order (the paper: 1 and 3, its 15AR and 27AR models); None chooses it by `criterion`.
    level, f_limit
        Levels of decomposition (default 6, the paper's Section 5.2-5.3 setting) or the band to
        keep in Hz (`f_limit` given overrides `level`).
    denoise : mapping, optional
        Other de-noising settings (`wavelet`, `rule`, `mode`, `noise`; db4, soft SURE as in the
        paper).
    method, max_order, criterion
        Passed to :func:`stochmod.empirical.ar_fit.fit_ar` (Burg by default, as the paper).

    Returns
    -------
    DenoisedARModel
        Its model describes the de-noised signal: the white noise above the kept band is gone
        from it (docs/comparison.md shows what that costs against the raw signal).
    """
    freq = check_freq(freq)
    if f_limit is not None:
        level = None
    den = wavelet_denoise(x, level=level, freq=freq, f_limit=f_limit, **_denoise_options(denoise))
    ar = fit_ar(den.signal, freq, order, max_order=max_order, method=method, criterion=criterion)
    return DenoisedARModel(model=ar_model(ar, freq), ar=ar, denoising=den, freq=freq)


# ----------------------------------------------------------------------------- PSD


@attrs.frozen
class PSDModel:
    """The PSD slope reading turned into WN + GM + RW (Quinchia Section 5.4, Table 3).

    Attributes
    ----------
    model : Model
        WN(N) + GM(B, Tc) + RW(K) of the terms found (or BI(B, fc) with ``bias="bi"``).
    reading : PSDReading
        The slope reading of the log-binned Welch PSD.
    allan : AllanReading or None
        The Allan reading that supplied the GM's correlation time (the PSD gives none; the
        paper takes Tc from the AV, Table 5), when it was needed.
    bias_tc : float or None
        Correlation time (s) used for the GM of B.
    freq : float
        Sampling frequency, Hz.
    """

    model: Model
    reading: PSDReading
    allan: AllanReading | None
    bias_tc: float | None
    freq: float

    def summary(self) -> str:
        """The PSD reading, the Tc used and the model."""
        tc = "" if self.bias_tc is None else (
            f"GM correlation time of B: {format_number(self.bias_tc)} s"
            + (" (from the Allan reading)" if self.allan is not None else ""))
        return _join(self.reading.summary(), tc, self.model.summary())


def psd_model(
    x: ArrayLike,
    freq: float,
    *,
    bias: str | None = "gm",
    bias_tc: float | None = None,
    bias_fc: float | None = None,
    **psd_kwargs: Any,
) -> PSDModel:
    """PSD slope reading -> composite model (Quinchia Section 5.4; same model family as AV).

    Parameters
    ----------
    x : array_like, shape (n,)
        Static error signal.
    freq : float
        Sampling frequency, Hz.
    bias : {"gm", "bi", None}
        How a bias instability B enters (:func:`stochmod.fit.classical.psd_reading_model`).
    bias_tc : float, optional
        Correlation time (s) of the GM of B. Default: the Allan reading's Tc of the same
        signal, as the paper does (Table 5 serves both readings).
    bias_fc : float, optional
        Corner frequency (Hz) for ``bias="bi"``.
    **psd_kwargs
        Passed to :func:`stochmod.empirical.psd.psd_reading`.

    Raises
    ------
    EstimationError
        No term found; or B found with ``bias="gm"``, no `bias_tc` and no flat Allan region to
        take Tc from.
    """
    freq = check_freq(freq)
    x = as_signal(x, name="x", min_length=8)
    reading = psd_reading(x, freq, **psd_kwargs)
    allan = None
    if reading.B is not None and bias == "gm" and bias_tc is None:
        allan = allan_reading(x, freq)
        if allan.Tc is None:
            raise EstimationError(
                "the PSD shows a bias instability B but the Allan variance has no flat region "
                "to take its correlation time from: pass bias_tc (s), or bias='bi' or None")
        bias_tc = allan.Tc
    model = psd_reading_model(reading, freq, bias=bias, bias_tc=bias_tc, bias_fc=bias_fc)
    used_tc = bias_tc if reading.B is not None and bias == "gm" else None
    return PSDModel(model=model, reading=reading, allan=allan, bias_tc=used_tc, freq=freq)


# ----------------------------------------------------------------------------- ACF


@attrs.frozen
class ACFGMModel:
    """First-order GM from the autocorrelation's 1/e decay (Quinchia Sections 4.1, 5.2).

    Attributes
    ----------
    model : Model
        GM(beta = 1/Tc, sigma2): the zero-lag variance (white noise included) or the
        least-squares amplitude (``use_ls``).
    fit : GMAcfFit
        The fit, with its caveats.
    denoising : WaveletDenoising or None
        The de-noising applied first, if any (the paper de-noises before the ACF, Sec. 5.2).
    freq : float
        Sampling frequency, Hz.
    """

    model: Model
    fit: GMAcfFit
    denoising: WaveletDenoising | None = attrs.field(repr=False)
    freq: float

    def summary(self) -> str:
        """The fit with its caveats and the model."""
        den = "" if self.denoising is None else self.denoising.summary()
        return _join(den, self.fit.summary(), self.model.summary())


def acf_gm_model(
    x: ArrayLike,
    freq: float,
    *,
    use_ls: bool = False,
    level: int | None = None,
    f_limit: float | None = None,
    denoise: Mapping[str, Any] | None = None,
    max_lag: int | None = None,
) -> ACFGMModel:
    """First-order GM read off the sample autocorrelation (Quinchia eq. 11).

    Parameters
    ----------
    x : array_like, shape (n,)
        Static error signal.
    freq : float
        Sampling frequency, Hz.
    use_ls : bool
        Take the least-squares exponential (rate and amplitude without the lag-0 white noise)
        instead of the 1/e crossing and the lag-0 variance.
    level, f_limit
        De-noise first with this many levels / keeping this band (Hz); neither: the raw signal.
    denoise : mapping, optional
        Other de-noising settings (`wavelet`, `rule`, `mode`, `noise`).
    max_lag : int, optional
        Largest lag computed, samples (default: the whole record).

    Raises
    ------
    EstimationError
        The ACF gives no usable GM (never reaches 1/e, or a non-decaying fit); the message
        lists the caveats.
    """
    freq = check_freq(freq)
    den = None
    if level is not None or f_limit is not None:
        den = wavelet_denoise(x, level=level, freq=freq, f_limit=f_limit,
                              **_denoise_options(denoise))
        x = den.signal
    fit = fit_gm_acf(x, freq, max_lag=max_lag)
    return ACFGMModel(model=acf_model(fit, freq, use_ls=use_ls), fit=fit, denoising=den, freq=freq)


# ----------------------------------------------------------------------------- comparison


@attrs.frozen
class ModelScore:
    """One model's distance from the data's wavelet variance.

    Attributes
    ----------
    name : str
        The label given to :func:`compare_models`.
    model : Model
        The model, bound to the data's frequency.
    objective : float
        ``(nu_hat - nu(model))^T Omega (nu_hat - nu(model))``, dimensionless.
    wv : ndarray, shape (J,)
        The model's theoretical Haar wavelet variance, unit^2.
    ratio : ndarray, shape (J,)
        ``wv / nu_hat`` per level.
    outside : ndarray of bool, shape (J,)
        Levels where the model's WV is outside the data's confidence interval.
    """

    name: str
    model: Model
    objective: float
    wv: np.ndarray = attrs.field(eq=False, repr=False)
    ratio: np.ndarray = attrs.field(eq=False, repr=False)
    outside: np.ndarray = attrs.field(eq=False, repr=False)


@attrs.frozen
class ModelComparison:
    """Models of one signal scored by the GMWM objective with one weighting.

    Attributes
    ----------
    empirical : WaveletVariance
        The data's Haar wavelet variance (levels 1..J used).
    weights : ndarray, shape (J,)
        The diagonal of Omega: ``1 / var(nu_hat_j)``, ``var = 2 nu_hat_j^2 / max(M_j / 2^j, 1)``
        (``stochmod.gmwm``'s default ``weighting="diagonal"``), unit^-4.
    levels : int
        J.
    scores : tuple of ModelScore
        In the order given.
    """

    empirical: WaveletVariance
    weights: np.ndarray = attrs.field(eq=False, repr=False)
    levels: int
    scores: tuple[ModelScore, ...]

    def __getitem__(self, name: str) -> ModelScore:
        for s in self.scores:
            if s.name == name:
                return s
        raise KeyError(name)

    @property
    def objectives(self) -> dict[str, float]:
        """Objective by name."""
        return {s.name: s.objective for s in self.scores}

    @property
    def best(self) -> ModelScore:
        """The model with the smallest objective."""
        return min(self.scores, key=lambda s: s.objective)

    def ranked(self) -> list[ModelScore]:
        """Scores from the smallest objective up."""
        return sorted(self.scores, key=lambda s: s.objective)

    def summary(self) -> str:
        """Objective table, best first, with the worst-fitted level of each model."""
        best = self.best.objective
        tau = self.empirical.tau[: self.levels]
        rows = []
        for rank, s in enumerate(self.ranked(), start=1):
            worst = int(np.argmax(np.abs(np.log(s.ratio))))
            rows.append([
                rank, s.name, s.model.name, s.objective,
                s.objective / best if best > 0 else math.inf,
                f"{int(s.outside.sum())}/{self.levels}", tau[worst], s.ratio[worst],
            ])
        return format_table(
            ["rank", "method", "model", "objective", "/ best", "levels outside CI",
             "worst tau [s]", "model/data"],
            rows, digits=4,
            title=(f"GMWM objective (eq. 20, diagonal Omega) of each model's Haar WV against the "
                   f"data's (J = {self.levels}, N = {self.empirical.n}, "
                   f"freq = {format_number(self.empirical.freq)} Hz)"),
        )

    def wv_table(self, digits: int = 3) -> str:
        """Per level: tau, the data's WV and interval, and each model's WV / data's WV
        (``*`` where the model's WV lies outside the interval)."""
        emp, J = self.empirical, self.levels
        rows = []
        for j in range(J):
            row: list[object] = [int(emp.levels[j]), emp.tau[j], emp.wv[j], emp.ci_low[j],
                                 emp.ci_high[j]]
            for s in self.scores:
                row.append(format_number(s.ratio[j], digits) + ("*" if s.outside[j] else ""))
            rows.append(row)
        return format_table(["j", "tau [s]", "WV data", "CI low", "CI high",
                             *(s.name for s in self.scores)], rows, digits=4,
                            title="model WV / data WV per level (* outside the data's 95% CI)")

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe: objectives, model specs and per-level ratios."""
        return {
            "levels": self.levels,
            "tau": [float(t) for t in self.empirical.tau[: self.levels]],
            "models": {
                s.name: {"objective": float(s.objective), "spec": s.model.to_spec(),
                         "ratio": [float(r) for r in s.ratio]}
                for s in self.scores
            },
        }


def _resolve(name: str, item: Any, freq: float) -> Model:
    """A bound, fully specified Model from a Model, Process, spec, or a result with `.model`."""
    if isinstance(item, (str, Mapping)):
        model = model_from_spec(item, freq)
    else:
        candidate = getattr(item, "model", item)
        if not isinstance(candidate, (Model, Process)):
            raise InputError(
                f"models[{name!r}] must be a Model, a Process, a spec or a result with a .model "
                f"(a pipeline result, a GMWMResult); got {type(item).__name__}")
        model = as_model(candidate)
    if model.freq is not None and not math.isclose(model.freq, freq, rel_tol=1e-12):
        raise InputError(
            f"models[{name!r}] is bound to {model.freq:g} Hz but the data are at {freq:g} Hz: its "
            "per-sample parameters would mean something else")
    model = model.bind(freq)
    if model.is_free:
        raise SpecError(f"models[{name!r}] ({model.name}) has free parameters: fit it first")
    return model


def compare_models(
    data: ArrayLike | WaveletVariance,
    freq: float | None,
    models: Mapping[str, Any],
    *,
    levels: int | None = None,
    wavelet: str = "haar",
) -> ModelComparison:
    """Score models by the GMWM objective of their wavelet variance against the data's.

    Every model gets ``(nu_hat - nu(theta))^T Omega (nu_hat - nu(theta))`` with the same
    ``nu_hat`` (the data's Haar WV at levels 1..J) and the same diagonal ``Omega``
    (``stochmod.gmwm(weighting="diagonal")``'s), so a GMWM fit's own objective is reproduced
    and the classical readings are measured on its scale (Stebler et al. 2014, Sec. II, point
    3: validate at observation level by the noise structure).

    Parameters
    ----------
    data : array_like or WaveletVariance
        The static error signal (unit u) or its empirical wavelet variance.
    freq : float
        Sampling frequency, Hz (may be None with a WaveletVariance).
    models : mapping of str to model
        Each a Model or Process with all values (bound to `freq` or unbound), a spec string or
        dict, or any result with a ``.model`` (pipeline results, ``GMWMResult``).
    levels : int, optional
        J (default: all the signal allows, as ``gmwm``).
    wavelet : str
        Wavelet of the empirical WV (Haar; the models' theory is computed for the same).

    Returns
    -------
    ModelComparison

    Raises
    ------
    InputError
        No models; a model bound to another frequency; bad data or levels.
    SpecError
        A model with free parameters.
    """
    if not isinstance(models, Mapping) or not models:
        raise InputError("models must be a non-empty mapping {name: model}")
    if isinstance(data, WaveletVariance):
        emp = data
        freq = emp.freq if freq is None else check_freq(freq)
        if not math.isclose(freq, emp.freq, rel_tol=1e-12):
            raise InputError(f"freq = {freq:g} Hz but the wavelet variance is at {emp.freq:g} Hz")
    else:
        if freq is None:
            raise InputError("freq (Hz) is required when data is a signal")
        freq = check_freq(freq)
        emp = wvar(as_signal(data, name="data", min_length=8), freq, wavelet=wavelet, levels=levels)
    J = emp.wv.size if levels is None else check_positive_int(levels, name="levels")
    if J > emp.wv.size:
        raise InputError(f"levels = {J} but the wavelet variance has {emp.wv.size} levels")
    nu = np.asarray(emp.wv[:J], float)
    if np.any(nu <= 0):
        raise InputError("the empirical wavelet variance has non-positive levels")
    weights = 1.0 / chi2_variance(nu, emp.n_coef[:J], emp.levels[:J])
    scores = []
    for name, item in models.items():
        model = _resolve(str(name), item, freq)
        theory = np.asarray(model.wv(J, emp.wavelet), float)
        if not np.all(np.isfinite(theory)):
            raise EstimationError(f"models[{name!r}] ({model.name}) has a non-finite wavelet variance")
        r = nu - theory
        outside = (theory < emp.ci_low[:J]) | (theory > emp.ci_high[:J])
        scores.append(ModelScore(
            name=str(name), model=model, objective=float(r @ (weights * r)), wv=theory,
            ratio=theory / nu, outside=outside,
        ))
    return ModelComparison(empirical=emp, weights=weights, levels=J, scores=tuple(scores))
