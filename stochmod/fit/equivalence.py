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
"""

from __future__ import annotations

from typing import Any

from stochmod.core.units import si_unit_of
from stochmod.core.units import parse_unit

__all__ = ["beyond_record", "correlation_time", "equivalent_term", "WHITE_NOISE", "RANDOM_WALK"]

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
