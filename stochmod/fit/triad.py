"""One model structure for the three axes of a sensor (Stebler et al. 2014, remark on Fig. 6).

The three gyroscopes (or accelerometers) of one chip share their physics, so they should share
one model *structure* while each axis keeps its own parameters. :func:`triad_select` takes the
per-axis selections of a triad (every candidate fitted on every axis, with one shared candidate
set) and

1. picks the structure with the smallest criterion summed over the axes, among the candidates
   identified on a majority of the axes (a structure may hold a component that one axis does
   not resolve, as one chip's axes differ; candidates identified on fewer axes are chosen only
   when none is identified on a majority, the most identified first);
2. checks each axis's fit of that structure for correlated components (those declaring a
   correlation time and a sigma, e.g. a GM) whose correlation time lies below the sampling
   interval (the component is then white noise for the data) or beyond the record (a random
   walk over the record);
3. for such a component, looks up the candidate whose structure replaces it by one of the kind
   it is equivalent to (white: a term whose physical unit is a noise density ``u*sqrt(s)``;
   random walk: ``u/sqrt(s)``), or drops it where the structure already has such a term; the
   simpler equivalent is preferred when the summed criterion cannot separate the two: when it
   exceeds the chosen one's by no more than the chosen one's extra optimism (the penalty of
   its extra parameters), i.e. when the richer fit's gain in objective is at most twice its
   penalty, the AIC's notion of "no better".

Nothing is refitted: every per-axis fit is the selection's own fit of that structure.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from typing import Any

import attrs

from stochmod.core.units import SENSORS, signal_unit, si_unit_of
from stochmod.fit.equivalence import WHITE_NOISE, correlation_time, equivalent_term
from stochmod.core.errors import InputError
from stochmod.fit.gmwm import GMWMResult
from stochmod.fit.selection import SelectionResult, model_terms
from stochmod.core.model import Model
from stochmod.core.tables import format_table
from stochmod.core.units import parse_unit

__all__ = ["TriadChoice", "Equivalence", "triad_select", "group_triads", "equivalences"]

_WHITE_KINDS = ("angle_random_walk", "velocity_random_walk")
_WALK_KINDS = ("rate_random_walk", "accel_random_walk")


@attrs.frozen
class Equivalence:
    """A correlated component of one axis's fit that is equivalent to a simpler term.

    Attributes
    ----------
    column : str
        Axis.
    component : str
        Its label in the model (``"GM2"``).
    tc : float
        Its correlation time, s.
    equivalent : str
        ``"white noise"`` (Tc below the sampling interval) or ``"random walk"`` (Tc beyond the
        record).
    """

    column: str
    component: str
    tc: float
    equivalent: str


@attrs.frozen(eq=False)
class TriadChoice:
    """The structure chosen for a triad (see :func:`triad_select`).

    Attributes
    ----------
    sensor : str
        ``"gyro"`` or ``"accel"``.
    columns : tuple of str
        The axes.
    structure : str
        Name of the chosen model structure.
    summed : dict of str to float
        Candidate name -> criterion summed over the axes (the table of the choice).
    identified : dict of str to int
        Candidate name -> number of axes on which its fit is identified.
    fits : dict of str to GMWMResult
        Axis -> its fit of the chosen structure.
    equivalences : tuple of Equivalence
        Correlated components of the summed-criterion choice that are equivalent to a simpler
        term (reported even where no simpler candidate was available).
    replaced : str or None
        The summed-criterion choice when a simpler equivalent replaced it.
    criterion : str
        Name of the criterion.
    """

    sensor: str
    columns: tuple[str, ...]
    structure: str
    summed: dict[str, float]
    identified: dict[str, int]
    fits: dict[str, GMWMResult]
    equivalences: tuple[Equivalence, ...]
    replaced: str | None
    criterion: str

    def summary(self) -> str:
        """The summed-criterion table, the choice and the equivalences found."""
        order = sorted(self.summed, key=lambda m: (-self.identified[m], self.summed[m]))
        rows = [[m, self.summed[m], f"{self.identified[m]}/{len(self.columns)}",
                 "<-" if m == self.structure else ""] for m in order]
        title = (f"Triad {self.sensor} ({', '.join(self.columns)}): one structure on the summed "
                 f"{self.criterion}: {self.structure}")
        lines = [format_table(["model", f"summed {self.criterion}", "identified", "chosen"], rows,
                              title=title)]
        if self.replaced:
            lines.append(f"{self.replaced} has a component equivalent to a simpler term and the "
                         f"criterion cannot separate them: {self.structure} is preferred")
        for e in self.equivalences:
            lines.append(f"{e.column}: {e.component} (Tc = {e.tc:.4g} s) is a {e.equivalent}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe content."""
        return {"sensor": self.sensor, "columns": list(self.columns), "structure": self.structure,
                "summed": dict(self.summed), "identified": dict(self.identified),
                "equivalences": [attrs.asdict(e) for e in self.equivalences],
                "replaced": self.replaced, "criterion": self.criterion}


def group_triads(columns: Sequence[str], units: Mapping[str, str]) -> dict[str, list[str]]:
    """Columns grouped by sensor (``{"gyro": [...], "accel": [...]}``; empty groups dropped)."""
    groups: dict[str, list[str]] = {k: [] for k in SENSORS}
    for col in columns:
        unit = units[col]
        groups[next(k for k, v in SENSORS.items() if v == unit)].append(col)
    return {k: v for k, v in groups.items() if v}


def _kinds(proc: Any, freq: float, unit: str) -> set[str]:
    return {parse_unit(si_unit_of(pv.unit, unit)).kind for pv in proc.physical(freq).values()}


def equivalences(fit: GMWMResult, column: str = "", unit: str | None = None) -> list[Equivalence]:
    """Correlated components of `fit` whose correlation time is below the sampling interval
    (equivalent to white noise) or beyond the record (equivalent to a random walk)."""
    unit = signal_unit(column) if unit is None else unit
    freq = float(fit.model.freq)
    record = fit.empirical.n / freq
    out = []
    for label, proc in zip(fit.model.labels, fit.model.processes):
        tc = correlation_time(proc, freq, unit)
        term = None if tc is None else equivalent_term(tc, freq, record)
        if term is not None:
            out.append(Equivalence(column, label, tc, term))
    return out


def _simpler(chosen: Model, label: str, kinds: tuple[str, ...], candidates: Mapping[str, Model],
             freq: float, unit: str) -> list[str]:
    """Candidates equal to `chosen` with component `label` replaced by a term of one of
    `kinds`, or dropped where `chosen` already holds such a term."""
    proc = chosen.processes[chosen.labels.index(label)]
    base = model_terms(chosen)
    removed = base - Counter([next(iter(model_terms(Model((proc,)))))])
    has_kind = any(_kinds(p, freq, unit) & set(kinds) for p in chosen.processes if p is not proc)
    out = []
    for name, model in candidates.items():
        terms = model_terms(model)
        if terms == removed and has_kind:
            out.append(name)
            continue
        added = terms - removed
        if sum(added.values()) == 1 and not (removed - terms):
            new = next(p for p in model.processes if model_terms(Model((p,))) == added)
            if _kinds(new, freq, unit) & set(kinds):
                out.append(name)
    return out


def triad_select(results: Sequence[SelectionResult], units: Mapping[str, str] | None = None
                 ) -> TriadChoice:
    """One structure for the axes of a sensor, on the criterion summed over them.

    Parameters
    ----------
    results : sequence of SelectionResult
        The per-axis selections (same candidates and criterion), e.g. ``select(x3, fs)``.
    units : mapping, optional
        Axis -> SI unit (rad/s or m/s^2); default from the column names.

    Returns
    -------
    TriadChoice

    Raises
    ------
    InputError
        No selection, axes of different sensors, or different candidate sets or criteria.
    """
    results = list(results)
    if not results:
        raise InputError("triad_select needs the selections of at least one axis")
    cols = [r.column for r in results]
    units = {c: signal_unit(c) for c in cols} if units is None else dict(units)
    if len({units[c] for c in cols}) != 1:
        raise InputError(f"a triad is the axes of one sensor; {cols} mix gyroscopes and "
                         "accelerometers")
    names = set(results[0].fits)
    if any(set(r.fits) != names for r in results) or len({r.criterion for r in results}) != 1:
        raise InputError("the axes of a triad must be selected among the same candidates with "
                         "the same criterion")
    summed = {m: 0.0 for m in names}
    optimism = {m: 0.0 for m in names}
    identified = {m: 0 for m in names}
    n_params = {}
    for r in results:
        for row in r.ranking:
            summed[row.model] += row.criterion
            optimism[row.model] += row.optimism
            identified[row.model] += int(row.identified)
            n_params[row.model] = row.n_params
    majority = len(results) // 2 + 1
    order = sorted(names, key=lambda m: (identified[m] < majority, -min(identified[m], majority),
                                         summed[m], m))
    best = order[0]
    unit = units[cols[0]]
    freq = float(results[0].fits[best].model.freq)
    eqs = [e for r in results for e in equivalences(r.fits[best], r.column, unit)]
    replaced = None
    candidates = {m: results[0].fits[m].model for m in names}
    for e in eqs:
        kinds = _WHITE_KINDS if e.equivalent == WHITE_NOISE else _WALK_KINDS
        for alt in _simpler(results[0].fits[best].model, e.component, kinds, candidates, freq, unit):
            tie = max(optimism[best] - optimism[alt], optimism[best] / max(n_params[best], 1))
            if identified[alt] >= min(identified[best], majority) and summed[alt] - summed[best] <= tie:
                replaced, best = best, alt
                break
        if replaced:
            break
    return TriadChoice(sensor=next(k for k, v in SENSORS.items() if v == unit), columns=tuple(cols),
                       structure=best, summed=summed, identified=identified,
                       fits={r.column: r.fits[best] for r in results}, equivalences=tuple(eqs),
                       replaced=replaced, criterion=results[0].criterion)
