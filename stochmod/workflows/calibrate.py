"""The main job as a library: a static recording in, its :class:`~stochmod.io.calibration.
Calibration` out.

:func:`calibrate` selects a model per column (:func:`stochmod.select`), optionally one
structure per sensor triad (:func:`stochmod.fit.triad.triad_select`), replaces the components
that are simpler terms on the record (:func:`stochmod.fit.equivalence.replace_equivalents`),
judges each axis (:func:`stochmod.fit.verdict.verdict`) and reads its datasheet
(:func:`stochmod.output.datasheet.datasheet`). ``stochmod calibrate`` and its fleet call the
steps below and hold no logic of their own: :func:`prepare` (units declared and checked),
:func:`select_column` (one column's selection: a fleet's task), :func:`assemble` (everything
after the selections).
"""

from __future__ import annotations

import concurrent.futures
from collections.abc import Mapping, Sequence
from typing import Any

import attrs

from stochmod.core.errors import EstimationError, InputError
from stochmod.core.units import SENSORS, parse_unit
from stochmod.empirical.allan_reading import AllanReading
from stochmod.empirical.wv_covariance import default_workers
from stochmod.fit.equivalence import FinalFit, replace_equivalents
from stochmod.fit.selection import SelectionResult, refit, select
from stochmod.fit.verdict import Verdict, verdict
from stochmod.io.calibration import AxisCalibration, Calibration
from stochmod.io.recording import Recording, column_replicates, longest_segment
from stochmod.io.sensors import check_static_magnitudes, declare_units
from stochmod.output.datasheet import Datasheet, datasheet, datasheet_reading

__all__ = ["CalibrationRun", "assemble", "calibrate", "calibration_run", "column_unit",
           "prepare", "select_column", "select_columns"]


@attrs.frozen
class CalibrationRun:
    """A calibration with the results it was made from (for figures and reports).

    Attributes
    ----------
    calibration : Calibration
    selections : tuple of SelectionResult
        Per column; ``best`` is the final fit (:attr:`FinalFit.final`).
    finals : tuple of FinalFit
        Per column: the final fit, the fit as selected and the replacements.
    triads : tuple of TriadChoice
        The per-sensor structure choices (empty without ``triad``).
    datasheets : dict of str to Datasheet
        Per gyro or accelerometer column.
    record : Recording
        The longest gap-free segment (the data of the datasheet's Allan reading).
    verdicts : tuple of Verdict
        Per column, of the final fit against the selection's candidates.
    """

    calibration: Calibration
    selections: tuple[SelectionResult, ...]
    finals: tuple[FinalFit, ...]
    triads: tuple[Any, ...]
    datasheets: dict[str, Datasheet]
    record: Recording
    verdicts: tuple[Verdict, ...]


def column_unit(rec: Recording, k: int) -> str | None:
    """The SI unit of column `k`'s signal: the sensor's for a gyro or accelerometer, the SI
    form of the declared unit otherwise (None when unknown)."""
    declared = rec.declared[k] if rec.declared is not None else None
    if declared is not None and declared.kind in SENSORS:
        return SENSORS[declared.kind]
    unit = declared.unit if declared is not None else (rec.units or (None,) * len(rec.columns))[k]
    return None if unit is None else parse_unit(unit).si


def prepare(recording: Recording | Sequence[Recording], *, assume_si: bool = False
            ) -> list[Recording]:
    """The recording's gap-free segments with every column's kind and unit declared, in SI,
    the static magnitudes checked.

    Parameters
    ----------
    recording : Recording or sequence of Recording
        A recording (its gap-free segments are taken, :meth:`Recording.segments`), or the
        segments themselves (same columns). Units come from its ``declared`` units, else from
        its ``units`` and ``kinds`` (:func:`stochmod.io.sensors.declare_units`).
    assume_si : bool
        Take SI for a gyro or accelerometer column of unknown unit (recorded as "assumed").

    Raises
    ------
    InputError
        A gyro or accelerometer column without a unit, a unit that contradicts the column's
        kind, magnitudes that betray a wrong unit (:func:`~stochmod.io.sensors.
        check_static_magnitudes`), segments that do not share their columns.
    """
    segments = (recording.segments() if isinstance(recording, Recording) else list(recording))
    if not segments:
        raise InputError("calibrate needs a recording (no segments given)")
    columns = segments[0].columns
    out = []
    for seg in segments:
        if seg.columns != columns:
            raise InputError(f"segments with columns {list(seg.columns)} and {list(columns)}: "
                             "the segments of a recording share their columns")
        if seg.declared is None:
            declared = declare_units(seg.columns, seg.units, seg.kinds, assume_si=assume_si)
            seg = attrs.evolve(seg, units=tuple(c.unit for c in declared), declared=declared)
        # `units` are the samples' units now (a declared recording may be in SI already)
        if any(u is not None and parse_unit(u).si != u for u in seg.units or ()):
            seg = seg.to_si()
        check_static_magnitudes(seg.data, seg.declared)
        out.append(seg)
    return out


def select_column(segments: Sequence[Recording], freq: float, k: int, *,
                  executor: Any = None, **selection: Any) -> SelectionResult:
    """Column `k`'s selection (the segments' pooled wavelet variance when several): equal to
    that column's in a selection of every column (each column's fits are seeded by the
    candidate only)."""
    return select(column_replicates(segments, k), freq, names=[segments[0].columns[k]],
                  executor=executor, **selection)


def select_columns(segments: Sequence[Recording], freq: float, *, executor: Any = None,
                   **selection: Any) -> list[SelectionResult]:
    """One selection per column of the gap-free `segments` (their pooled wavelet variance when
    there are several)."""
    if len(segments) == 1:
        return list(select(segments[0].data, freq, names=list(segments[0].columns),
                           executor=executor, **selection))
    return [select_column(segments, freq, k, executor=executor, **selection)
            for k in range(len(segments[0].columns))]


def _safe(fn: Any) -> Any:
    """Value of an inference accessor, or None where the fit is not identified."""
    try:
        return fn()
    except EstimationError:
        return None


def _details(sel: SelectionResult, final: FinalFit, judged: Verdict) -> dict[str, Any]:
    """The JSON-safe results of one column (:attr:`AxisCalibration.details`)."""
    best = final.final
    params, phys, jt = _safe(best.parameters), _safe(best.physical), best.jtest
    return {
        "objective": best.objective,
        "fitted_objective": final.fitted.objective,
        "parameters": None if params is None else [attrs.asdict(e) for e in params],
        "physical": None if phys is None else [attrs.asdict(e) for e in phys],
        "jtest": None if jt is None else attrs.asdict(jt),
        "criterion": sel.criterion,
        "weighting": sel.weighting,
        "final_weighting": sel.final_weighting,
        "ranking": [attrs.asdict(r) for r in sel.ranking],
        "robust": sel.empirical.robust_info(),
        "verdict": judged.to_dict(),
    }


def _kind(rec: Recording, k: int) -> str:
    return rec.declared[k].kind if rec.declared is not None else "other"


def _readings(rec: Recording, freq: float, units: Mapping[str, str | None],
              given: Sequence[AllanReading | None] | None) -> dict[int, AllanReading]:
    """The datasheet reading of each gyro and accelerometer column of `rec` (by index), those
    not `given` made on :func:`~stochmod.empirical.wv_covariance.default_workers` threads:
    their passes over the data release the GIL, and each holds one phase array of the
    column's size."""
    sensors = [k for k in range(len(rec.columns)) if _kind(rec, k) in SENSORS]
    made = {k: given[k] for k in sensors if given is not None and given[k] is not None}
    todo = [k for k in sensors if k not in made]

    def read(k: int) -> AllanReading:
        return datasheet_reading(rec.data[:, k], freq, units[rec.columns[k]])

    workers = min(default_workers(), len(todo))
    if workers > 1:
        with concurrent.futures.ThreadPoolExecutor(workers) as pool:
            made.update(zip(todo, pool.map(read, todo)))
    else:
        made.update((k, read(k)) for k in todo)
    return made


def assemble(segments: Sequence[Recording], freq: float, selections: Sequence[SelectionResult],
             *, dt: float | None = None, triad: bool = False, replace: bool = True,
             readings: Sequence[AllanReading | None] | None = None,
             extra: Mapping[str, Any] | None = None) -> CalibrationRun:
    """Everything after the selections: triads, final models, verdicts, datasheets.

    Parameters
    ----------
    segments : sequence of Recording
        The prepared segments (:func:`prepare`) the `selections` were made on.
    freq : float
        Sampling frequency, Hz.
    selections : sequence of SelectionResult
        One per column, in column order.
    dt : float, optional
        Filter step of the augmentation, s (default ``1/freq``).
    triad : bool
        One structure per sensor (gyro x/y/z, accel x/y/z), on the criterion summed over its
        axes.
    replace : bool
        Replace components equivalent to simpler terms on the record (the default; False
        keeps the fits as selected).
    readings : sequence of (AllanReading or None), optional
        The columns' datasheet readings when made already (a fleet's column tasks).
    extra : mapping, optional
        Further JSON-safe content of the calibration (``scale``, ``replicates`` ...).
    """
    rec = longest_segment(segments)
    dt = 1.0 / freq if dt is None else float(dt)
    if not dt > 0:
        raise InputError(f"the filter step dt must be a positive number of seconds, got {dt!r}")
    units = {c: column_unit(rec, k) for k, c in enumerate(rec.columns)}
    selections = list(selections)
    triads: list[Any] = []
    if triad:
        from stochmod.fit.triad import group_triads, triad_select

        sensors = {c: u for c, u in units.items() if u in SENSORS.values()}
        if not sensors:
            raise InputError("triad: no gyro or accelerometer columns (declare their units)")
        by_col = {s.column: s for s in selections}
        for cols in group_triads(list(sensors), sensors).values():
            choice = triad_select([by_col[c] for c in cols], sensors)
            triads.append(choice)
            for c in cols:
                sel, chosen = by_col[c], choice.fits[c]
                if sel.final_weighting is None:
                    by_col[c] = attrs.evolve(sel, best=chosen)
                elif chosen is not sel.fits[sel.ranking[0].model]:  # else refitted already
                    by_col[c] = refit(sel, sel.final_weighting, best=chosen)
        selections = [by_col[s.column] for s in selections]
    finals = [replace_equivalents(s.best, units[s.column]) if replace
              else FinalFit(s.best, s.best, ()) for s in selections]
    selections = [attrs.evolve(s, best=f.final) for s, f in zip(selections, finals)]
    made = _readings(rec, freq, units, readings)
    sheets = {sel.column: datasheet(sel.best, units[sel.column], column=sel.column,
                                    reading=made[k])
              for k, sel in enumerate(selections) if k in made}
    verdicts = tuple(verdict(s.best, candidates=s.ranking) for s in selections)
    axes = []
    for k, (sel, fin, judged) in enumerate(zip(selections, finals, verdicts)):
        details = _details(sel, fin, judged)
        if sel.column in sheets:
            details["datasheet"] = sheets[sel.column].to_dict()
        axes.append(AxisCalibration(sel.column, _kind(rec, k), units[sel.column],
                                    fin.final.model, fin.fitted.model,
                                    tuple(attrs.asdict(r) for r in fin.replacements), details))
    sizes = tuple(int(s.data.shape[0]) for s in segments)
    content = {"units": {"signal": units, "declared": None if rec.declared is None else
                         {c.column: c.to_dict() for c in rec.declared},
                         "note": "parameters: canonical per-sample values in the signal unit "
                                 "u (see physical for SI, datasheet for datasheet units)"},
               "datasheet": {c: d.to_dict() for c, d in sheets.items()},
               "triads": [t.to_dict() for t in triads], **(extra or {})}
    if len(segments) > 1 and all(s.time is not None for s in segments):
        content["segments"] = [{"start": float(s.time[0]), "n": int(s.data.shape[0])}
                               for s in segments]
    calibration = Calibration(axes, float(freq), dt, sum(sizes), rec.path, sizes, content)
    return CalibrationRun(calibration, tuple(selections), tuple(finals), tuple(triads), sheets,
                          rec, verdicts)


def calibrate(recording: Recording | Sequence[Recording], *, freq: float | None = None,
              dt: float | None = None, triad: bool = False, replace: bool = True,
              assume_si: bool = False, executor: Any = None, **selection: Any) -> Calibration:
    """Calibrate a static recording: the final noise model of each column.

    Parameters
    ----------
    recording : Recording or sequence of Recording
        The recording (or its gap-free segments, pooled as replicates), each column's unit
        declared or known from the file (:func:`prepare`).
    freq : float, optional
        Sampling frequency, Hz (default the recording's).
    dt : float, optional
        Filter step of the augmentation, s (default ``1/freq``).
    triad : bool
        One model structure per sensor triad.
    replace : bool
        Replace components that are simpler terms on the record (default True).
    assume_si : bool
        Take SI for a gyro or accelerometer column of unknown unit.
    executor : concurrent.futures.Executor, optional
        Runs the selection's fits.
    **selection
        Options of :func:`stochmod.select` (``criterion``, ``weighting``, ``families``,
        ``robust``, ``rng``, ``final_weighting`` ...).

    Returns
    -------
    Calibration

    Examples
    --------
    >>> import stochmod
    >>> from stochmod.data.examples import xsens_mtig
    >>> cal = stochmod.calibrate(xsens_mtig(n=2**14).select(["gyro_x"]))  # doctest: +SKIP
    >>> cal.models["gyro_x"].name  # doctest: +SKIP
    'GM+WN'
    """
    return calibration_run(recording, freq=freq, dt=dt, triad=triad, replace=replace,
                           assume_si=assume_si, executor=executor, **selection).calibration


def calibration_run(recording: Recording | Sequence[Recording], *, freq: float | None = None,
                    dt: float | None = None, triad: bool = False, replace: bool = True,
                    assume_si: bool = False, executor: Any = None,
                    extra: Mapping[str, Any] | None = None, **selection: Any) -> CalibrationRun:
    """:func:`calibrate`, keeping the selections, final fits, triads and datasheets."""
    segments = prepare(recording, assume_si=assume_si)
    freq = segments[0].freq if freq is None else freq
    if freq is None:
        raise InputError(f"{segments[0].path or 'the recording'} does not record its sampling "
                         "frequency: give freq")
    selections = select_columns(segments, float(freq), executor=executor, **selection)
    return assemble(segments, float(freq), selections, dt=dt, triad=triad, replace=replace,
                    extra=extra)
