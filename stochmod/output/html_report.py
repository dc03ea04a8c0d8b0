"""A self-contained HTML calibration report (``stochmod calibrate --report``).

One file, no external resources: per axis a figure (PNG embedded as base64) with the Haar
wavelet variance and the Allan deviation of the data with their 95 % intervals, the fitted
model and the band of series simulated from it (:func:`stochmod.validate`); the selection
table; the datasheet summary (:mod:`stochmod.output.datasheet`); and the exported configurations.
Figures need matplotlib (``pip install "stochmod[plots]"``); tables are plain HTML.
"""

from __future__ import annotations

import base64
import html
import io
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from stochmod.output.datasheet import Datasheet
from stochmod.fit.selection import SelectionResult
from stochmod.fit.validation import ValidationBands
from stochmod.core.tables import format_number

__all__ = ["ReportAxis", "axis_figure_png", "render_report", "write_report"]

_STYLE = """
body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}
table{border-collapse:collapse;margin:0.5em 0 1.5em}
td,th{border:1px solid #bbb;padding:2px 8px;text-align:right;font-size:90%}
th{background:#eee} td.l,th.l{text-align:left}
pre{background:#f6f6f6;padding:0.7em;font-size:85%;overflow-x:auto}
img{max-width:100%} h2{border-bottom:2px solid #ccc;margin-top:2em}
"""


@attrs.frozen(eq=False)
class ReportAxis:
    """What the report shows for one axis.

    Attributes
    ----------
    column : str
        Axis name.
    selection : SelectionResult
        Its model selection (ranking table).
    datasheet : Datasheet
        Its datasheet summary (with the Allan reading of the data).
    bands : ValidationBands
        The data against simulations of the reported fit.
    note : str
        A line under the heading (e.g. the triad's structure).
    """

    column: str
    selection: SelectionResult
    datasheet: Datasheet
    bands: ValidationBands
    note: str = ""


def _table(headers: Sequence[str], rows: Sequence[Sequence[Any]], cls: str = "") -> str:
    head = "".join(f"<th{' class=l' if i == 0 else ''}>{html.escape(h)}</th>"
                   for i, h in enumerate(headers))
    body = []
    for row in rows:
        cells = "".join(f"<td{' class=l' if i == 0 else ''}>{html.escape(format_number(c, 5))}</td>"
                        for i, c in enumerate(row))
        body.append(f"<tr>{cells}</tr>")
    return f'<table class="{cls}"><tr>{head}</tr>{"".join(body)}</table>'


def axis_figure_png(axis: ReportAxis, dpi: int = 90) -> bytes:
    """PNG of the axis's two panels: WV and Allan deviation, data (95 % CI), model, band."""
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise ImportError('the report figures need matplotlib: pip install "stochmod[plots]"') from None
    b = axis.bands
    unit = axis.datasheet.unit
    fig = Figure(figsize=(10.0, 3.8))
    ax1, ax2 = fig.subplots(1, 2)
    ax1.fill_between(b.tau, b.band_low, b.band_high, color="0.8", label=f"95% of {b.R} simulations")
    ax1.fill_between(b.tau, b.ci_low, b.ci_high, color="C0", alpha=0.3, label="data 95% CI")
    ax1.loglog(b.tau, b.wv, "o", color="C0", ms=3, label="data WV")
    ax1.loglog(b.tau, b.model_wv, "-", color="C3", label=f"model {b.model.name}")
    ax1.set_ylabel(f"Haar wavelet variance [({unit})^2]")
    reading = axis.datasheet.reading
    if reading is not None:
        av = reading.avar
        ax2.fill_between(av.tau, np.sqrt(av.ci_low), np.sqrt(av.ci_high), color="C0", alpha=0.3,
                         label="data 95% CI")
        ax2.loglog(av.tau, np.sqrt(av.avar), ".", color="C0", ms=3, label="data ADEV")
    ax2.fill_between(b.tau, np.sqrt(2 * b.band_low), np.sqrt(2 * b.band_high), color="0.8",
                     label="simulations (95%)")
    ax2.loglog(b.tau, np.sqrt(2 * b.model_wv), "-", color="C3", label="model")
    ax2.set_ylabel(f"Allan deviation [{unit}]")
    for ax in (ax1, ax2):
        ax.set_xlabel("averaging time tau [s]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="x-small")
    fig.suptitle(f"{axis.column}: {b.model.name}")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def _axis_html(axis: ReportAxis, figures: bool) -> str:
    sel, ds = axis.selection, axis.datasheet
    parts = [f'<h2 id="{html.escape(axis.column)}">{html.escape(axis.column)}: '
             f"{html.escape(ds.model)}</h2>"]
    if axis.note:
        parts.append(f"<p>{html.escape(axis.note)}</p>")
    if figures:
        data = base64.b64encode(axis_figure_png(axis)).decode("ascii")
        parts.append(f'<img alt="{html.escape(axis.column)} wavelet variance and Allan deviation" '
                     f'src="data:image/png;base64,{data}">')
    parts.append(f"<p>Data inside the 95% band of the simulations at "
                 f"{100 * axis.bands.coverage:.0f}% of the levels.</p>")
    parts.append("<h3>Datasheet summary</h3>")
    parts.append(_table(*ds.summary_table(), "datasheet"))
    prow = [[p.name, p.si, p.si_low, p.si_high, p.si_unit] for p in ds.parameters]
    parts.append(_table(["parameter", "SI", "95% low", "95% high", "SI unit"], prow, "parameters"))
    parts.append(f"<h3>Selection ({html.escape(sel.criterion)}, {html.escape(sel.weighting)} "
                 "weighting)</h3>")
    srow = [[r.model, r.n_params, r.objective, r.criterion,
             "n/a" if r.jtest_pvalue is None else r.jtest_pvalue, "yes" if r.identified else "no"]
            for r in sel.ranking]
    parts.append(_table(["model", "params", "objective", sel.criterion, "J-test p", "identified"],
                        srow, "selection"))
    return "\n".join(parts)


def render_report(axes: Sequence[ReportAxis], *, title: str,
                  exports: Mapping[str, str] | None = None, extra: Sequence[str] = (),
                  figures: bool = True) -> str:
    """The report as one HTML string (see :func:`write_report`)."""
    toc = " | ".join(f'<a href="#{html.escape(a.column)}">{html.escape(a.column)}</a>' for a in axes)
    body = [f"<h1>{html.escape(title)}</h1>", f"<p>{toc}</p>"]
    body += [f"<pre>{html.escape(text)}</pre>" for text in extra]
    body += [_axis_html(a, figures) for a in axes]
    if exports:
        body.append('<h2 id="exports">Exports</h2>')
        for name, text in exports.items():
            body.append(f"<h3>{html.escape(name)}</h3><pre>{html.escape(text)}</pre>")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title><style>{_STYLE}</style></head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")


def write_report(path: str | Path, axes: Sequence[ReportAxis], *, title: str,
                 exports: Mapping[str, str] | None = None, extra: Sequence[str] = ()) -> Path:
    """Write the self-contained HTML report to `path`.

    Parameters
    ----------
    path : str or Path
        Output file (``OUT/report.html``).
    axes : sequence of ReportAxis
        One section per axis.
    title : str
        Page title.
    exports : mapping of str to str, optional
        File name -> content of each exported configuration, shown verbatim.
    extra : sequence of str
        Preformatted blocks shown under the title (e.g. the triad tables).
    """
    path = Path(path)
    path.write_text(render_report(axes, title=title, exports=exports, extra=extra),
                    encoding="utf-8")
    return path
