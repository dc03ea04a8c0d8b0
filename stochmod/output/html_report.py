"""A self-contained HTML calibration report (``stochmod calibrate --report``).

One file, no external resources (figures are PNGs embedded as base64), laid out answer first:

1. the **summary across axes** (``<table id="summary">``): per axis the final model, the
   white-noise density, bias instability and its tau, random walk and each correlated
   component's correlation time and sigma in datasheet units
   (:mod:`stochmod.output.datasheet`), the verdict (:func:`stochmod.fit.verdict.verdict`),
   what the final model replaced (:func:`stochmod.fit.equivalence.replace_equivalents`) and
   the exported white density N and random walk K (:func:`stochmod.output.exports.noise_terms`);
2. the exported files verbatim, collapsed;
3. the **Allan deviations in datasheet units**, one panel per axis
   (:func:`stochmod.output.plots.allan_figure`): the data with their 95 % interval, the final
   model's curve, and the exports' bound ``N^2/tau + K^2 tau/3``;
4. with ``stochmod calibrate --drift``, the **predicted drift** of a loosely-coupled INS/GNSS
   filter with the final models over a GNSS outage, with its band from the parameters'
   uncertainty (:func:`stochmod.nav.drift.predicted_drift`);
5. the triad tables and, per axis, the figure of the wavelet variance and the Allan deviation
   (:func:`axis_figure`: the data with their 95 % interval inside the model's 95 % band, the
   band the verdict counts levels in), the datasheet, the parameters and the selection's
   ranking.

Tables longer than :data:`SHOWN_ROWS` rows show their first rows, the rest in a
``<details>`` element. Figures need matplotlib (``pip install "stochmod[plots]"``).
"""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np

from stochmod.core.tables import format_number
from stochmod.core.units import BI_FACTOR, convert
from stochmod.fit.equivalence import FinalFit
from stochmod.fit.selection import SelectionResult
from stochmod.fit.validation import ValidationBands
from stochmod.fit.verdict import Verdict, model_band, verdict
from stochmod.output.datasheet import Datasheet
from stochmod.output.exports import AxisNoise

if TYPE_CHECKING:
    from stochmod.nav.drift import DriftPrediction

__all__ = ["SHOWN_ROWS", "ReportAxis", "allan_overview", "allan_overview_png", "axis_figure",
           "axis_figure_png", "drift_figure", "render_report", "summary_rows", "write_report"]

#: Rows of a long table shown before the ``<details>`` that holds the rest.
SHOWN_ROWS = 5

_STYLE = """
body{font-family:sans-serif;max-width:1150px;margin:1.5em auto;color:#222}
h1{font-size:1.35em}
table{border-collapse:collapse;margin:0.5em 0 1em}
td,th{border:1px solid #bbb;padding:2px 8px;text-align:right;font-size:90%}
th{background:#eee} td.l,th.l{text-align:left}
table#summary td,table#summary th{font-size:82%;vertical-align:top;padding:2px 5px}
table#summary td.w{text-align:left;font-size:78%}
.u{color:#666;font-size:85%;white-space:nowrap} .ok{color:#060} .bad{color:#a00}
details{margin:0.3em 0 1em} summary{cursor:pointer;color:#035}
pre{background:#f6f6f6;padding:0.7em;font-size:85%;overflow-x:auto}
img{max-width:100%} h2{border-bottom:2px solid #ccc;margin-top:1.5em}
p.note{font-size:85%;color:#444;margin:0.2em 0}
"""


@attrs.frozen(eq=False)
class ReportAxis:
    """What the report shows for one axis.

    Attributes
    ----------
    column : str
        Axis name.
    selection : SelectionResult
        Its model selection (ranking table); ``best`` is the final fit.
    datasheet : Datasheet
        Its datasheet summary (with the Allan reading of the data).
    bands : ValidationBands, optional
        The data against simulations of the reported fit (:func:`stochmod.validate`), drawn
        beside the model's band when given.
    note : str
        A line under the heading (e.g. the triad's structure).
    final : FinalFit, optional
        The final fit and what it replaced of the fit as selected.
    noise : AxisNoise, optional
        The exported white density and random walk (when exports were written).
    verdict : Verdict, optional
        The verdict of the final fit, when made already (else the report makes it).
    figure : bytes, optional
        The PNG of :func:`axis_figure`, when drawn already (else the report draws it).
    """

    column: str
    selection: SelectionResult
    datasheet: Datasheet
    bands: ValidationBands | None = None
    note: str = ""
    final: FinalFit | None = None
    noise: AxisNoise | None = None
    verdict: Verdict | None = None
    figure: bytes | None = None

    def for_figures(self) -> ReportAxis:
        """A copy with what :func:`axis_figure` and :func:`allan_overview` draw: the selection
        without the fits of its other candidates (about 95 % of a pickled axis), as a figure
        task sends it to a worker process."""
        return attrs.evolve(self, selection=attrs.evolve(self.selection, fits={}))


def _cell(value: Any, i: int) -> str:
    return f"<td{' class=l' if i == 0 else ''}>{html.escape(format_number(value, 5))}</td>"


def _table(headers: Sequence[str], rows: Sequence[Sequence[Any]], cls: str = "") -> str:
    head = "".join(f"<th{' class=l' if i == 0 else ''}>{html.escape(h)}</th>"
                   for i, h in enumerate(headers))
    body = "".join("<tr>" + "".join(_cell(c, i) for i, c in enumerate(row)) + "</tr>"
                   for row in rows)
    return f'<table class="{cls}"><tr>{head}</tr>{body}</table>'


def _long_table(headers: Sequence[str], rows: Sequence[Sequence[Any]], cls: str,
                what: str = "rows") -> str:
    """The first :data:`SHOWN_ROWS` rows; the others in a ``<details>`` (same columns)."""
    if len(rows) <= SHOWN_ROWS:
        return _table(headers, rows, cls)
    rest = len(rows) - SHOWN_ROWS
    return (_table(headers, rows[:SHOWN_ROWS], cls)
            + f"<details><summary>{rest} more {html.escape(what)}</summary>"
            + _table(headers, rows[SHOWN_ROWS:], f"{cls} rest") + "</details>")


def _png(fig: Any, dpi: int) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def _img(png: bytes, alt: str) -> str:
    data = base64.b64encode(png).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


# --- the Allan deviations -------------------------------------------------------------------

def _allan_curves(axis: ReportAxis, *, band: bool) -> Any:
    """The axis's Allan panel (:class:`stochmod.output.plots.AllanCurves`, SI): the data's
    reading, the final model at every dyadic tau of the wavelet variance, its minimum, the
    export's N and K, and (with `band`) the model's 95 % band at the fitted levels
    (:func:`stochmod.fit.verdict.model_band`; the Allan variance is twice the Haar WV)."""
    from stochmod.output.plots import AllanCurves

    fit, ds = axis.selection.best, axis.datasheet
    emp = fit.empirical
    tau_m = np.asarray(emp.tau, dtype=float)
    adev_m = np.sqrt(2.0 * fit.model.wv(tau_m.size))
    data: dict[str, Any] = {}
    if ds.reading is not None:
        av = ds.reading.avar
        data = {"tau": av.tau, "adev": np.sqrt(av.avar), "low": np.sqrt(av.ci_low),
                "high": np.sqrt(av.ci_high)}
    bi = ds.row("bias instability")
    minimum = None
    if bi.tau is not None and bi.model is not None:
        minimum = (bi.tau, float(convert(bi.model * BI_FACTOR, bi.unit, ds.unit)))
    extra: dict[str, Any] = {}
    if band:
        low, high = model_band(fit)
        extra = {"band_tau": tau_m[: fit.levels], "band_low": np.sqrt(2.0 * low),
                 "band_high": np.sqrt(2.0 * high), "band_label": "model's 95% band"}
    noise = axis.noise
    return AllanCurves(axis.column, ds.unit, model_tau=tau_m, model_adev=adev_m,
                       model_name=fit.model.name, minimum=minimum,
                       noise_density=None if noise is None else noise.noise_density,
                       random_walk=None if noise is None else noise.random_walk,
                       horizon=None if noise is None else noise.horizon,
                       **data, **extra)


def allan_overview(axes: Sequence[ReportAxis]) -> Any:
    """The report's Allan figure: one panel per axis in datasheet units (deg/h, ug or mg),
    the data with their 95 % interval, the final model, the export's white + random-walk
    bound (a matplotlib Figure, :func:`stochmod.output.plots.allan_figure`)."""
    from stochmod.output.plots import allan_figure

    return allan_figure([_allan_curves(a, band=False) for a in axes])


def allan_overview_png(axes: Sequence[ReportAxis], dpi: int = 95) -> bytes:
    """PNG of :func:`allan_overview`."""
    return _png(allan_overview(axes), dpi)


def axis_figure(axis: ReportAxis) -> Any:
    """The axis's two panels (a matplotlib Figure): the Haar WV in the signal unit and the
    Allan deviation in datasheet units; the data with their 95 % interval, the fitted model
    and its 95 % band (:func:`stochmod.fit.verdict.model_band`, the band of the verdict), and
    the band of the simulations of :attr:`ReportAxis.bands` when there are some."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise ImportError('the report figures need matplotlib: pip install "stochmod[plots]"') from None
    from stochmod.core.plotting import log_grid
    from stochmod.output.plots import plot_allan

    fit, unit = axis.selection.best, axis.datasheet.unit
    emp, J = fit.empirical, fit.levels
    tau = emp.tau[:J]
    low, high = model_band(fit)
    fig = Figure(figsize=(10.0, 3.8))
    ax1, ax2 = fig.subplots(1, 2)
    b = axis.bands
    if b is not None:
        ax1.fill_between(b.tau, b.band_low, b.band_high, color="0.8",
                         label=f"95% of {b.R} simulations")
    ax1.fill_between(tau, low, high, color="C3", alpha=0.15, label="model's 95% band")
    ax1.fill_between(tau, emp.ci_low[:J], emp.ci_high[:J], color="C0", alpha=0.3,
                     label="data 95% CI")
    ax1.loglog(tau, emp.wv[:J], "o", color="C0", ms=3, label="data WV")
    ax1.loglog(tau, fit.model_wv(), "-", color="C3", label=f"model {fit.model.name}")
    ax1.set_ylabel(f"Haar wavelet variance [({unit})^2]")
    ax1.set_xlabel("averaging time tau [s]")
    log_grid(ax1)
    ax1.legend(fontsize="x-small")
    ax1.set_title("wavelet variance", fontsize="medium", y=1.0)
    plot_allan(attrs.evolve(_allan_curves(axis, band=True), noise_density=None,
                            random_walk=None, horizon=None), ax2)
    ax2.set_title("Allan deviation", fontsize="medium", y=1.0)
    fig.suptitle(f"{axis.column}: {fit.model.name}")
    # fixed margins (tight_layout measures every text first: a second layout pass)
    fig.subplots_adjust(left=0.08, right=0.985, bottom=0.14, top=0.86, wspace=0.28)
    return fig


def axis_figure_png(axis: ReportAxis, dpi: int = 90) -> bytes:
    """PNG of :func:`axis_figure`."""
    return _png(axis_figure(axis), dpi)


def drift_figure(drift: DriftPrediction) -> Any:
    """The predicted 1-sigma horizontal drift against the time since the last fix, with the
    5-95 % band of the parameter draws (a matplotlib Figure, :meth:`DriftPrediction.plot`)."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise ImportError('the report figures need matplotlib: pip install "stochmod[plots]"') from None
    fig = Figure(figsize=(6.5, 3.8))
    drift.plot(fig.subplots())
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.14, top=0.95)
    return fig


def _drift_html(drift: DriftPrediction, figures: bool) -> str:
    low, high = drift.band()
    c = drift.conditions
    parts = ['<h2 id="drift">Predicted drift over a GNSS outage</h2>',
             f'<p>After {c.settle:g} s of fixes, a {c.outage:g} s outage: predicted 1-sigma '
             f"horizontal drift <b>{drift.end_sigma:.4g} m</b> with the calibrated models; "
             f"{low:.4g} to {high:.4g} m (5-95 %) over the parameter draws.</p>"]
    if figures:
        parts.append(_img(_png(drift_figure(drift), 90), "predicted drift over the outage"))
    parts.append(f"<pre>{html.escape(drift.summary())}</pre>")
    return "\n".join(parts)


# --- the summary ----------------------------------------------------------------------------

def _value(v: float | None, unit: str, digits: int = 4) -> str:
    if v is None:
        return "-"
    return f'{html.escape(format_number(v, digits))} <span class="u">{html.escape(unit)}</span>'


def _lines(items: Sequence[str]) -> str:
    return "<br>".join(items) if items else "-"


_SI_EXPORT_UNITS = {"gyro": ("rad/s/sqrt(Hz)", "rad/s^2/sqrt(Hz)"),
                    "accel": ("m/s^2/sqrt(Hz)", "m/s^3/sqrt(Hz)")}


def summary_rows(axes: Sequence[ReportAxis]) -> tuple[list[str], list[list[str]]]:
    """Headers and cells (HTML) of the summary across axes: one row per axis."""
    exports = any(a.noise is not None for a in axes)
    headers = ["axis", "final model", "white noise density", "bias instability", "BI tau [s]",
               "random walk", "correlated terms (Tc, sigma)", "verdict", "replaced"]
    if exports:
        headers += ["exported N", "exported K"]
    rows = []
    for a in axes:
        ds, sel = a.datasheet, a.selection
        white = [_value(r.model, r.unit) for r in ds.rows if r.quantity.startswith("white noise")]
        bi = ds.row("bias instability")
        bi_cell = _value(bi.model, bi.unit) + ("*" if bi.note else "")
        walk = next(r for r in ds.rows if r.quantity.endswith("random walk"))
        terms = []
        for r in ds.rows:
            if r.quantity.endswith(" correlation time"):
                label = r.quantity[: -len(" correlation time")]
                sigma = ds.row(f"{label} sigma")
                terms.append(f"{html.escape(label)}: Tc = {_value(r.model, 's')}, "
                             f"sigma = {_value(sigma.model, sigma.unit)}")
        v = a.verdict if a.verdict is not None else verdict(sel.best, candidates=sel.ranking)
        if v.pvalue is None:
            word = "not tested"
        else:
            cls = "ok" if v.accepted else "bad"
            word = (f'<span class="{cls}">{"accepted" if v.accepted else "rejected"}</span> '
                    f"(p = {v.pvalue:.3g})")
        verdict_cell = f"{word}, {100 * v.inside:.0f} % of levels in band"
        if v.every_candidate_rejected:
            verdict_cell += "<br>every candidate rejected"
        replaced = "-"
        if a.final is not None and a.final.replacements:
            replaced = (f"fitted {html.escape(a.final.fitted.model.name)}: "
                        + "<br>".join(html.escape(r.summary()) for r in a.final.replacements))
        row = [html.escape(a.column), html.escape(sel.best.model.name), _lines(white), bi_cell,
               html.escape(format_number(bi.tau, 4)) if bi.tau is not None else "-",
               _value(walk.model, walk.unit), _lines(terms), verdict_cell, replaced]
        if exports:
            n = a.noise
            units = _SI_EXPORT_UNITS.get(ds.sensor, (ds.unit, ds.unit))
            row += ["-" if n is None else _value(n.noise_density, units[0]),
                    "-" if n is None else _value(n.random_walk, units[1])]
        rows.append(row)
    return headers, rows


def _summary_html(axes: Sequence[ReportAxis]) -> str:
    headers, rows = summary_rows(axes)
    wide = {"correlated terms (Tc, sigma)", "verdict", "replaced"}
    head = "".join(f"<th{' class=l' if i == 0 else ''}>{html.escape(h)}</th>"
                   for i, h in enumerate(headers))
    body = []
    for row in rows:
        cells = "".join(f"<td{' class=l' if i == 0 else (' class=w' if headers[i] in wide else '')}>"
                        f"{c}</td>" for i, c in enumerate(row))
        body.append(f"<tr>{cells}</tr>")
    return f'<table id="summary" class="summary"><tr>{head}</tr>{"".join(body)}</table>'


def _summary_notes(axes: Sequence[ReportAxis]) -> str:
    sel = axes[0].selection
    notes = [(f"Final models selected by {html.escape(sel.criterion)} "
             f"({html.escape(sel.weighting)} weighting), values in datasheet units from the final "
             "model. Verdict: the J-test at 5 % and the share of wavelet-variance levels inside "
             "the model's 95 % band. Replaced: a correlated component whose correlation time is "
             "below the sample interval is white noise on the record, one beyond the record a "
             "random walk.")]
    if any(a.datasheet.row("bias instability").note for a in axes):
        notes.append("* the model's Allan minimum lies at the edge of the fitted averaging "
                     "times: the value bounds the bias instability, it does not measure it.")
    noise = [a.noise for a in axes if a.noise is not None]
    if noise:
        horizons = ", ".join(format_number(h, 4) for h in sorted({n.horizon for n in noise}))
        notes.append("Exported: each axis as white noise N plus a random-walk bias K (Kalibr's "
                     "model, SI), per axis as the export computes them (Kalibr and OpenVINS take "
                     "the largest over a sensor's axes); their Allan deviation is dashed in the "
                     f"figure below, up to the horizon H = {horizons} s of the export.")
    return "".join(f'<p class="note">{n}</p>' for n in notes)


# --- the rest -------------------------------------------------------------------------------

def _triad_html(triad: Any) -> str:
    order = sorted(triad.summed, key=lambda m: (-triad.identified[m], triad.summed[m]))
    rows = [[m, triad.summed[m], f"{triad.identified[m]}/{len(triad.columns)}",
             "<-" if m == triad.structure else ""] for m in order]
    parts = [(f"<h3>Triad {html.escape(triad.sensor)} ({html.escape(', '.join(triad.columns))}): "
             f"{html.escape(triad.structure)}</h3>"),
             _long_table(["model", f"summed {triad.criterion}", "identified", "chosen"], rows,
                         "triad", "structures")]
    if triad.replaced:
        parts.append(f"<p>{html.escape(triad.replaced)} has a component equivalent to a simpler "
                     f"term and the criterion cannot separate them: "
                     f"{html.escape(triad.structure)} is preferred</p>")
    for e in triad.equivalences:
        parts.append(f"<p>{html.escape(e.column)}: {html.escape(e.component)} "
                     f"(Tc = {e.tc:.4g} s) is a {html.escape(e.equivalent)}</p>")
    return "\n".join(parts)


def _axis_html(axis: ReportAxis, figures: bool) -> str:
    sel, ds = axis.selection, axis.datasheet
    parts = [(f'<h2 id="{html.escape(axis.column)}">{html.escape(axis.column)}: '
             f"{html.escape(ds.model)}</h2>")]
    if axis.note:
        parts.append(f"<p>{html.escape(axis.note)}</p>")
    if figures:
        parts.append(_img(axis_figure_png(axis) if axis.figure is None else axis.figure,
                          f"{axis.column} wavelet variance and Allan deviation"))
    judged = axis.verdict if axis.verdict is not None else verdict(sel.best, candidates=sel.ranking)
    inside = f"Data inside the model's 95% band at {100 * judged.inside:.0f}% of the levels"
    if axis.bands is not None:
        inside += (f", inside the 95% band of {axis.bands.R} simulations at "
                   f"{100 * axis.bands.coverage:.0f}%")
    parts.append(f"<p>{inside}.</p>")
    parts.append("<h3>Datasheet</h3>")
    parts.append(_table(*ds.summary_table(), "datasheet"))
    prow = [[p.name, p.si, p.si_low, p.si_high, p.si_unit] for p in ds.parameters]
    parts.append(_long_table(["parameter", "SI", "95% low", "95% high", "SI unit"], prow,
                             "parameters", "parameters"))
    parts.append(f"<h3>Selection ({html.escape(sel.criterion)}, {html.escape(sel.weighting)} "
                 "weighting)</h3>")
    srow = [[r.model, r.n_params, r.objective, r.criterion,
             "n/a" if r.jtest_pvalue is None else r.jtest_pvalue, "yes" if r.identified else "no"]
            for r in sel.ranking]
    parts.append(_long_table(["model", "params", "objective", sel.criterion, "J-test p",
                              "identified"], srow, "selection", "candidates"))
    return "\n".join(parts)


def render_report(axes: Sequence[ReportAxis], *, title: str,
                  exports: Mapping[str, str] | None = None, triads: Sequence[Any] = (),
                  extra: Sequence[str] = (), figures: bool = True,
                  overview: bytes | None = None, drift: DriftPrediction | None = None) -> str:
    """The report as one HTML string (see :func:`write_report`)."""
    body = [f"<h1>{html.escape(title)}</h1>"]
    if axes:
        body += [_summary_html(axes), _summary_notes(axes)]
    if exports:
        names = ", ".join(exports)
        body.append(f'<details id="exports"><summary>Exported files: {html.escape(names)}'
                    "</summary>")
        for name, text in exports.items():
            body.append(f"<h3>{html.escape(name)}</h3><pre>{html.escape(text)}</pre>")
        body.append("</details>")
    if axes and figures:
        body.append('<h2 id="allan">Allan deviation in datasheet units</h2>')
        body.append(_img(allan_overview_png(axes) if overview is None else overview,
                         "Allan deviation of every axis"))
        body.append('<p class="note">Dots and shading: the data\'s overlapping Allan deviation '
                    "and its 95% interval; red: the final model (triangle: its minimum, the "
                    "bias instability's point)"
                    + ("; dashed: the exported white noise plus random walk, "
                       "sqrt(N^2/tau + K^2 tau/3)" if any(a.noise for a in axes) else "")
                    + ".</p>")
    if drift is not None:
        body.append(_drift_html(drift, figures))
    toc = " | ".join(f'<a href="#{html.escape(a.column)}">{html.escape(a.column)}</a>' for a in axes)
    body.append(f"<p>Per axis: {toc}</p>")
    body += [f"<pre>{html.escape(text)}</pre>" for text in extra]
    if triads:
        body.append('<h2 id="triads">Triads</h2>')
        body += [_triad_html(t) for t in triads]
    body += [_axis_html(a, figures) for a in axes]
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")


def write_report(path: str | Path, axes: Sequence[ReportAxis], *, title: str,
                 exports: Mapping[str, str] | None = None, triads: Sequence[Any] = (),
                 extra: Sequence[str] = (), figures: bool = True,
                 overview: bytes | None = None, drift: DriftPrediction | None = None) -> Path:
    """Write the self-contained HTML report to `path`.

    Parameters
    ----------
    path : str or Path
        Output file (``OUT/report.html``).
    axes : sequence of ReportAxis
        One row of the summary and one section per axis.
    title : str
        Page title.
    exports : mapping of str to str, optional
        File name -> content of each exported configuration, shown verbatim.
    triads : sequence of TriadChoice
        The per-sensor structure choices (:func:`stochmod.fit.triad.triad_select`).
    extra : sequence of str
        Further preformatted blocks, shown before the per-axis sections.
    figures : bool
        Draw the figures (matplotlib); False gives the tables only.
    overview : bytes, optional
        The PNG of :func:`allan_overview_png` of the same `axes`, when drawn already.
    drift : DriftPrediction, optional
        The predicted drift over a GNSS outage (:func:`stochmod.nav.drift.predicted_drift`)
        with the calibration's models, shown after the Allan deviations.
    """
    path = Path(path)
    path.write_text(render_report(axes, title=title, exports=exports, triads=triads, extra=extra,
                                  figures=figures, overview=overview, drift=drift),
                    encoding="utf-8")
    return path
