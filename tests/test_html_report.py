"""The calibration report opens with the answer: the summary across axes, then the Allan
deviations in datasheet units; long tables are collapsed (``stochmod.output.html_report``)."""

from __future__ import annotations

import argparse
import re
from html.parser import HTMLParser

import numpy as np
import pytest

from stochmod.cli._calibrate_outputs import write_report_for
from stochmod.data.examples import xsens_mtig
from stochmod.output import html_report
from stochmod.output.html_report import SHOWN_ROWS, allan_overview, render_report
from stochmod.output.plots import AllanCurves, allan_unit, plot_allan
from stochmod.workflows.calibrate import calibration_run

COLUMNS = ["gyro_x", "gyro_y", "accel_x"]
#: Enough candidates for the ranking to be longer than the rows a table shows.
CANDIDATES = ["WN", "WN+RW", "GM+WN", "GM+WN+RW", "QN+WN", "QN+WN+RW", "RW"]


@pytest.fixture(scope="module")
def run_():
    rec = xsens_mtig(n=2**12, seed=7).select(COLUMNS)
    return calibration_run(rec, candidates=CANDIDATES)


def _args(**kw):
    base = {"report": True, "n_sim": 3, "seed": 0, "export_horizon": None}
    return argparse.Namespace(**{**base, **kw})


@pytest.fixture(scope="module")
def report(run_, tmp_path_factory):
    """The report of `run_` with a Kalibr export, without figures' pixels (fast)."""
    out = tmp_path_factory.mktemp("rep")
    exported = out / "kalibr_imu.yaml"
    exported.write_text("gyroscope_noise_density: 1e-4\n")
    captured = {}

    def keep(path, axes, **kw):
        captured.update(kw, axes=axes)
        return path

    mp = pytest.MonkeyPatch()
    mp.setattr(html_report, "write_report", keep)
    try:
        assert write_report_for(_args(), run_, [exported], "title", out) == [out / "report.html"]
    finally:
        mp.undo()
    axes = captured.pop("axes")
    assert captured.pop("title") == "title"
    return axes, render_report(axes, title="calibration", figures=False, **captured)


class _Outline(HTMLParser):
    """The tags of the body in order, the summary's rows, and what each <details> holds."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict]] = []
        self.summary_rows: list[list[str]] = []
        self.details: list[list[str]] = []  # the table classes and tags inside each <details>
        self._in_summary = self._in_body = False
        self._depth = 0
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "body":
            self._in_body = True
            return
        if not self._in_body:
            return
        self.tags.append((tag, a))
        if tag == "details":
            self._depth += 1
            self.details.append([])
        elif self._depth:
            self.details[-1].append(f"{tag}.{a.get('class', '')}")
        if tag == "table" and a.get("id") == "summary":
            self._in_summary = True
        elif self._in_summary and tag == "tr":
            self.summary_rows.append([])
        elif self._in_summary and tag == "td":
            self._cell = []

    def handle_endtag(self, tag):
        if tag == "table":
            self._in_summary = False
        elif tag == "details":
            self._depth -= 1
        elif tag == "td" and self._cell is not None:
            self.summary_rows[-1].append(" ".join("".join(self._cell).split()))
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def test_the_summary_table_comes_first_one_row_per_axis(run_, report):
    axes, text = report
    page = _Outline()
    page.feed(text)
    tables = [a for t, a in page.tags if t == "table"]
    assert tables[0].get("id") == "summary"
    assert [t for t, _ in page.tags[:2]] == ["h1", "table"]  # nothing but the title before it
    rows = [r for r in page.summary_rows if r]  # the header row has no <td>
    assert [r[0] for r in rows] == COLUMNS
    assert [r[1] for r in rows] == [s.best.model.name for s in run_.selections]
    for row, ax in zip(rows, axes):
        ds = ax.datasheet
        assert ds.unit in ("rad/s", "m/s^2")
        assert ("deg/sqrt(h)" if ds.sensor == "gyro" else "ug/sqrt(Hz)") in row[2]
        assert ("deg/h" if ds.sensor == "gyro" else "ug") in row[3]
        assert re.match(r"(accepted|rejected) \(p = [0-9.e-]+\), \d+ % of levels in band", row[7])
        assert ax.noise is not None  # exports written: N and K per axis
        assert row[-2].startswith(f"{ax.noise.noise_density:.4g}")
        assert row[-1].startswith(f"{ax.noise.random_walk:.4g}")


def test_the_summary_says_what_the_final_model_replaced(report):
    import attrs

    from stochmod.fit.equivalence import FinalFit, Replacement
    from stochmod.output.html_report import summary_rows

    axes, _ = report
    fit = axes[0].selection.best
    r = Replacement("GM1", 1e-3, "white noise", 2e-5, (0.01, 0.005, 0.002))
    replaced = attrs.evolve(axes[0], final=FinalFit(fit, fit, (r,)))
    headers, rows = summary_rows([replaced, *axes[1:]])
    cell = rows[0][headers.index("replaced")]
    assert cell == f"fitted {fit.model.name}: {r.summary()}"
    assert [row[headers.index("replaced")] for row in rows[1:]] == ["-"] * (len(axes) - 1)


def test_long_tables_are_collapsed(report):
    axes, text = report
    page = _Outline()
    page.feed(text)
    inside = [tag for d in page.details for tag in d]
    n_candidates = len(CANDIDATES)
    assert n_candidates > SHOWN_ROWS
    assert inside.count("table.selection rest") == len(axes)  # every ranking continues there
    assert "pre." in inside  # the exported file, collapsed
    shown = re.findall(r'<table class="selection">(.*?)</table>', text)
    assert all(t.count("<tr>") == SHOWN_ROWS + 1 for t in shown)  # header + the first rows
    rest = re.findall(r'<table class="selection rest">(.*?)</table>', text)
    assert all(t.count("<tr>") == n_candidates - SHOWN_ROWS + 1 for t in rest)
    # the summary and the exports come before the first per-axis section
    assert text.index('id="summary"') < text.index('id="exports"') < text.index('<h2 id="gyro_x"')


def test_the_allan_figure_is_in_datasheet_units(report):
    pytest.importorskip("matplotlib")
    axes, _ = report
    fig = allan_overview(axes)
    labels = [ax.get_ylabel() for ax in fig.axes if ax.get_visible() and ax.axison]
    assert labels == ["Allan deviation [deg/h]", "Allan deviation [deg/h]",
                      "Allan deviation [ug]"]
    lines = {line.get_label() for ax in fig.axes for line in ax.get_lines()}
    assert "data ADEV" in lines and "exported N\u00b2/\u03c4 + K\u00b2\u03c4/3" in lines
    # the exported bound is N^2/tau + K^2 tau/3, drawn in deg/h for a gyro
    noise = axes[0].noise
    bound = next(line for line in fig.axes[0].get_lines() if line.get_label().startswith("exported"))
    t, y = bound.get_data()
    si = np.sqrt(noise.noise_density**2 / t + noise.random_walk**2 * t / 3)
    np.testing.assert_allclose(y, si * 180 / np.pi * 3600, rtol=1e-9)


def test_the_axis_figure_draws_its_allan_deviation_in_datasheet_units(report):
    pytest.importorskip("matplotlib")
    from stochmod.output.html_report import axis_figure

    axes, _ = report
    wv, adev = axis_figure(axes[2]).axes  # accel_x
    assert wv.get_ylabel() == "Haar wavelet variance [(m/s^2)^2]"
    assert adev.get_ylabel() == "Allan deviation [ug]"


def test_a_figure_task_sends_only_what_the_figures_draw(report):
    pytest.importorskip("matplotlib")
    import pickle

    from stochmod.output.html_report import allan_overview_png, axis_figure_png

    axes, _ = report
    slim = [a.for_figures() for a in axes]
    assert all(not a.selection.fits and a.selection.best is b.selection.best
               for a, b in zip(slim, axes))
    assert len(pickle.dumps(slim)) < 0.5 * len(pickle.dumps(axes))
    assert axis_figure_png(slim[0]) == axis_figure_png(axes[0])
    assert allan_overview_png(slim) == allan_overview_png(axes)


def test_allan_units_follow_the_sensor():
    assert allan_unit("rad/s") == "deg/h"
    assert allan_unit("m/s^2", [1e-4]) == "ug"  # about 10 ug
    assert allan_unit("m/s^2", [0.05, 0.005]) == "ug"  # the minimum is about 500 ug
    assert allan_unit("m/s^2", [0.05, 0.02]) == "mg"  # thousands of ug everywhere
    assert allan_unit("V") == "V"
    tau = np.array([0.1, 1.0, 10.0])
    fig = plot_allan(AllanCurves("accel_z", "m/s^2", tau=tau, adev=np.full(3, 0.02),
                                 model_tau=tau, model_adev=np.full(3, 0.02), model_name="WN"))
    ax = fig.axes[0]
    assert ax.get_ylabel() == "Allan deviation [mg]"
    np.testing.assert_allclose(ax.get_lines()[0].get_ydata(), 0.02 / 9.80665 * 1e3)


def test_the_report_without_exports_has_no_export_columns(run_, tmp_path, monkeypatch):
    captured = {}
    monkeypatch.setattr(html_report, "write_report",
                        lambda path, axes, **kw: captured.update(kw, axes=axes) or path)
    write_report_for(_args(), run_, [], "title", tmp_path)
    axes = captured.pop("axes")
    assert all(a.noise is None for a in axes)
    text = render_report(axes, figures=False, **captured)
    assert "exported N" not in text and 'id="exports"' not in text
    assert write_report_for(_args(report=False), run_, [], "title", tmp_path) == []
