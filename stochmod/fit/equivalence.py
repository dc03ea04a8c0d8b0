"""Correlated components that are simpler terms on a record: the one home of the rule.

A correlated component (one that declares a correlation time ``Tc`` and a sigma in a rate or
acceleration unit, e.g. a first-order Gauss-Markov process) cannot be told from a simpler term
when its correlation time lies outside what the record resolves:

- ``Tc`` below the sampling interval ``1/fs``: successive samples are uncorrelated, the
  component is **white noise** for the data;
- ``Tc`` beyond the record length ``T``: over the record the autocovariance ``sigma^2
  exp(-t/Tc)`` never decays, only the increments are seen, and the component is the **random
  walk** its driving noise makes, of coefficient ``K^2 = q = 2 sigma^2 / Tc`` (u^2/s per
  second). Its stationary variance ``sigma^2 = q Tc / 2`` is not identified by the record (a
  degenerate fit can return ``Tc`` = 7e13 s with ``sigma`` = 32 rad/s); what the record
  supports is the spread the walk reaches over it, ``q T``.

:func:`stochmod.fit.triad.triad_select` replaces such components by the simpler candidate,
:func:`stochmod.output.exports.noise_terms` exports a correlated component's drift as a random walk
(``K_eq^2 = 2 sigma^2 (1 - exp(-H/Tc)) / H``, which is ``q`` to first order in ``H/Tc``), and
the navigation filter (:class:`stochmod.nav.LooselyCoupledFilter`, ``record=``) augments a
component beyond the record as that random walk, started with variance ``q T``.

:func:`replace_equivalents` makes the final model of a calibration: each such component is
replaced by its simpler term, so that what is printed, exported and used is one model.
"""

from __future__ import annotations

from typing import Any

import attrs
import numpy as np

from stochmod.core.model import Model
from stochmod.core.process import Process, psd_of
from stochmod.core.units import parse_unit, si_unit_of
from stochmod.fit.engine import canonical
from stochmod.fit.results import GMWMResult
from stochmod.plugin.registry import get_process

__all__ = [
    "RANDOM_WALK",
    "REPORTED_LEVELS",
    "WHITE_NOISE",
    "FinalFit",
    "Replacement",
    "beyond_record",
    "correlation_time",
    "equivalent_term",
    "replace_equivalents",
]

WHITE_NOISE = "white noise"
RANDOM_WALK = "random walk"


def correlation_time(proc: Any, freq: float, unit: str) -> float | None:
    """The correlation time (s) of a correlated component, or None when `proc` is not one.

    Parameters
    ----------
    proc : Process
        A bound-able process (its ``physical(freq)`` is read).
    freq : float
        Sampling frequency, Hz.
    unit : str
        The signal's unit (e.g. ``"rad/s"``), to read the kinds of the physical parameters.

    Returns
    -------
    float or None
        The single physical parameter of kind time, when the component also has one in a
        rate or acceleration unit; None otherwise.
    """
    phys = proc.physical(freq)
    kinds = {name: parse_unit(si_unit_of(pv.unit, unit)).kind for name, pv in phys.items()}
    times = [phys[n].value for n, k in kinds.items() if k == "time"]
    if len(times) != 1 or not ({"rate", "acceleration"} & set(kinds.values())):
        return None
    return float(times[0])


def equivalent_term(tc: float, freq: float, record: float) -> str | None:
    """What a correlated component of correlation time `tc` (s) is on a record of `record` s
    sampled at `freq` Hz: :data:`WHITE_NOISE` (``tc < 1/freq``), :data:`RANDOM_WALK`
    (``tc > record``) or None (resolved by the record)."""
    if tc < 1.0 / freq:
        return WHITE_NOISE
    if tc > record:
        return RANDOM_WALK
    return None


def beyond_record(model: Any, unit: str, record: float) -> list[tuple[int, float]]:
    """``(index, Tc)`` of each component of `model` (a Model bound to its frequency, signal
    unit `unit`) that is a :data:`RANDOM_WALK` over a record of `record` s: the components the
    navigation filter augments, and its outage studies emulate, as random walks."""
    freq = float(model.freq)
    out = []
    for k, proc in enumerate(model.processes):
        tc = correlation_time(proc, freq, unit)
        if tc is not None and equivalent_term(tc, freq, record) == RANDOM_WALK:
            out.append((k, tc))
    return out


#: Levels at which :class:`Replacement` reports the change of the model's wavelet variance.
REPORTED_LEVELS = 3
_FAMILY = {WHITE_NOISE: "WN", RANDOM_WALK: "RW"}


@attrs.frozen
class Replacement:
    """One component of a fit replaced by the simpler term it is on the record.

    Attributes
    ----------
    component : str
        The replaced component's label (``"GM1"``).
    tc : float
        Its correlation time, s.
    term : str
        :data:`WHITE_NOISE` or :data:`RANDOM_WALK`.
    sigma2 : float
        The per-sample variance of the term it adds (``WN.sigma2`` or ``RW.sigma2``), u^2.
    wv_change : tuple of float
        Relative change of the model's wavelet variance at levels 1..:data:`REPORTED_LEVELS`
        (final / fitted - 1).
    """

    component: str
    tc: float
    term: str
    sigma2: float
    wv_change: tuple[float, ...]

    def summary(self) -> str:
        """One line: what was replaced, by what, and what it changes."""
        change = ", ".join(f"{100 * c:+.3g} %" for c in self.wv_change)
        return (f"{self.component} (Tc = {self.tc:.4g} s) is a {self.term} on the record: "
                f"replaced by {_FAMILY[self.term]}(sigma2 = {self.sigma2:.4g}); WV at levels "
                f"1-{len(self.wv_change)} {change}")


@attrs.frozen
class FinalFit:
    """The final model of a fit and how it was made.

    Attributes
    ----------
    final : GMWMResult
        The fit with every equivalent component replaced (the fit itself when none is), its
        inference evaluated at the replaced values with the GMWM's covariance (eqs. 22-23).
    fitted : GMWMResult
        The fit as estimated.
    replacements : tuple of Replacement
    """

    final: GMWMResult
    fitted: GMWMResult
    replacements: tuple[Replacement, ...]


def _equivalent_sigma2(proc: Process, term: str, freq: float) -> float:
    """Per-sample variance of the simpler term of a stationary component.

    White noise of the same low-frequency density: ``sigma2_WN = S(0) freq`` with the
    two-sided PSD ``S`` (u^2/Hz; for a GM ``sigma2 (1 + phi) / (1 - phi)``, what an
    integrating filter sees, the Allan variance at ``tau >> Tc``). Random walk of the same
    increments: ``sigma2_RW = 2 (gamma(0) - gamma(1))``, the variance of a one-sample
    difference (``2 sigma2 (1 - e^{-1/(Tc freq)})``, i.e. ``q / freq`` with ``q = 2 sigma^2 /
    Tc`` to first order in ``1 / (Tc freq)``).
    """
    if term == WHITE_NOISE:
        return float(psd_of(proc, np.zeros(1), freq)[0]) * freq
    gamma = proc.autocovariance(np.array([0, 1]), freq)
    return float(2.0 * (gamma[0] - gamma[1]))


def _merged(processes: list[Process]) -> list[Process]:
    """`processes` with repeated WN and RW terms summed into their first occurrence."""
    out: list[Process] = []
    for proc in processes:
        same = next((k for k, q in enumerate(out) if q.family == proc.family
                     and proc.family in _FAMILY.values()), None)
        if same is None:
            out.append(proc)
        else:
            out[same] = out[same].with_values(sigma2=out[same].sigma2 + proc.sigma2)
    return out


def replace_equivalents(fit: GMWMResult, unit: str | None) -> FinalFit:
    """The final model of `fit`: each correlated component whose correlation time is below
    the sampling interval replaced by the white noise of the same low-frequency density, and
    each beyond the record by the random walk of the same increments
    (:func:`_equivalent_sigma2`), summed into the model's own WN or RW.

    Parameters
    ----------
    fit : GMWMResult
        An analytic fit (indirect fits and fits without a known `unit` are kept as they are).
    unit : str or None
        The signal's SI unit (``"rad/s"``, ``"m/s^2"``), to recognise correlated components.

    Returns
    -------
    FinalFit
        The final fit's objective (eq. 20) and inference are evaluated at the replaced model
        with every parameter free.
    """
    freq = float(fit.model.freq)
    record = fit.empirical.n / freq
    if unit is None or fit.binding is not None:
        return FinalFit(fit, fit, ())
    procs: list[Process] = []
    found: list[tuple[str, float, str, float]] = []
    for label, proc in zip(fit.model.labels, fit.model.processes):
        tc = correlation_time(proc, freq, unit)
        term = None if tc is None else equivalent_term(tc, freq, record)
        if term is None or not proc.stationary:
            procs.append(proc)
            continue
        sigma2 = _equivalent_sigma2(proc, term, freq)
        procs.append(get_process(_FAMILY[term])(sigma2=sigma2))
        found.append((label, tc, term, sigma2))
    if not found:
        return FinalFit(fit, fit, ())
    procs = _merged(procs)
    if all(type(p).lattice_rank > 0 for p in procs):
        procs.sort(key=lambda p: type(p).lattice_rank)
    model = canonical(Model(tuple(procs), freq=freq))
    J = fit.levels
    resid = fit.empirical.wv[:J] - model.wv(J)
    mask = np.ones(model.n_params, dtype=bool)
    final = attrs.evolve(fit, model=model, objective=float(resid @ fit.omega @ resid),
                         free_mask=mask, free_names=tuple(model.param_names),
                         null_covariance=None)
    k = min(REPORTED_LEVELS, J)
    change = tuple(float(c) for c in final.fitted_wv[:k] / fit.fitted_wv[:k] - 1.0)
    return FinalFit(final, fit, tuple(Replacement(label, tc, term, sigma2, change)
                                      for label, tc, term, sigma2 in found))
