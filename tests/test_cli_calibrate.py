"""``stochmod calibrate`` (the main job), the bundled XSens MTi-G example and the figures."""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest

import stochmod
from stochmod.cli import calibrate as calibrate_cli
from stochmod.cli import main
from stochmod.core.errors import InputError
from stochmod.data.examples import XSENS_COLUMNS, xsens_mtig, xsens_mtig_models
from stochmod.fit.gmwm import gmwm

G0 = 9.80665  # standard gravity, m/s^2 (ug = 1e-6 g0)


@pytest.fixture(scope="module")
def gm_wn_file(tmp_path_factory):
    truth = stochmod.model_from_spec("GM(beta=1.0, sigma2=1e-2) + WN(sigma2=1e-2)", 50.0)
    path = tmp_path_factory.mktemp("rec") / "rec.npy"
    np.save(path, truth.simulate(2**14, rng=9)[:, None])
    return path


def run_json(args: list[str], capsys) -> dict:
    assert main(args) == 0
    return json.loads(capsys.readouterr().out)


# ---------------------------------------------------------------- calibrate on a file
def test_calibrate_file_writes_models_augmentation_and_figure(gm_wn_file, tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["calibrate", "--assume-si", str(gm_wn_file), "--freq", "50", "--out", str(out), "--dt", "0.04",
                 "--candidates", "WN", "GM+WN", "2*GM+WN", "--n-sim", "3"])
    assert code == 0
    text = capsys.readouterr().out
    assert "GM+WN" in text and "calibration.json" in text
    report = json.loads((out / "calibration.json").read_text())
    col = report["columns"]["0"]
    assert col["name"] == "GM+WN"
    assert [r["model"] for r in col["ranking"]][0] == "GM+WN"
    (gm, wn) = col["model"]["processes"]
    beta, s2 = gm["params"]["beta"], gm["params"]["sigma2"]
    assert beta == pytest.approx(1.0, rel=0.5) and s2 == pytest.approx(1e-2, rel=0.5)
    aug = col["augmentation"]
    dt = 0.04
    # closed forms of a GM block at step dt and the WN feed-through
    assert aug["state_names"] == ["GM.x"] or len(aug["state_names"]) == 1
    assert np.asarray(aug["Phi"])[0, 0] == pytest.approx(math.exp(-beta * dt), rel=1e-12)
    assert np.asarray(aug["Q"])[0, 0] == pytest.approx(s2 * -math.expm1(-2 * beta * dt), rel=1e-9)
    assert np.asarray(aug["P0"])[0, 0] == pytest.approx(s2, rel=1e-12)
    assert aug["white_var"] == pytest.approx(wn["params"]["sigma2"], rel=1e-12)
    imu = report["imu_augmentation"]
    assert imu["axes"] == ["0"] and np.asarray(imu["H"]).shape == (1, 1)
    assert {p["name"] for p in col["physical"]} >= {"GM.Tc", "GM.sigma", "WN.N"}
    pytest.importorskip("matplotlib")
    png = (out / "0.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_calibrate_scale_is_equivariant(gm_wn_file, tmp_path, capsys):
    """Scaling the data by s scales every variance by s^2 (GMWM is scale equivariant)."""
    base = ["calibrate", "--assume-si", str(gm_wn_file), "--freq", "50", "--candidates", "GM+WN", "--no-plots",
            "--json"]
    a = run_json(base + ["--out", str(tmp_path / "a")], capsys)["columns"]["0"]["model"]
    b = run_json(base + ["--out", str(tmp_path / "b"), "--scale", "3"], capsys)["columns"]["0"]["model"]
    for pa, pb in zip(a["processes"], b["processes"]):
        assert pb["params"]["sigma2"] == pytest.approx(9 * pa["params"]["sigma2"], rel=1e-5)
    assert b["processes"][0]["params"]["beta"] == pytest.approx(a["processes"][0]["params"]["beta"],
                                                                 rel=1e-5)


def test_calibrate_lattice_and_json_output_match_the_file(gm_wn_file, tmp_path, capsys):
    out = tmp_path / "lat"
    printed = run_json(["calibrate", "--assume-si", str(gm_wn_file), "--freq", "50", "--families", "GM", "WN",
                        "--max-count", "GM=2", "--out", str(out), "--no-plots", "--json"], capsys)
    assert printed == json.loads((out / "calibration.json").read_text())
    ranking = printed["columns"]["0"]["ranking"]
    assert sorted(r["model"] for r in ranking) == sorted(["GM", "2*GM", "WN", "GM+WN", "2*GM+WN"])
    assert printed["columns"]["0"]["name"] == "GM+WN"


def test_calibrate_jobs_do_not_change_the_outputs(gm_wn_file, tmp_path, capsys, monkeypatch):
    """The fits and figures on a pool of 2 worker processes give the same calibration.json and
    the same figure bytes as everything in this process (--jobs 1), however the figure's
    simulations are split into tasks."""
    pytest.importorskip("matplotlib")
    base = ["calibrate", "--assume-si", str(gm_wn_file), "--freq", "50", "--candidates", "WN", "GM+WN",
            "--n-sim", "2", "--json"]
    serial = run_json(base + ["--out", str(tmp_path / "one"), "--jobs", "1"], capsys)
    pooled = run_json(base + ["--out", str(tmp_path / "two"), "--jobs", "2"], capsys)
    assert pooled == serial
    assert (tmp_path / "two" / "0.png").read_bytes() == (tmp_path / "one" / "0.png").read_bytes()
    # the figure's simulations split over two tasks: the same figure, drawn here
    monkeypatch.setattr(calibrate_cli, "SIMULATIONS_PER_TASK", 1)
    split = run_json(base + ["--out", str(tmp_path / "split"), "--jobs", "2"], capsys)
    assert split == serial
    assert (tmp_path / "split" / "0.png").read_bytes() == (tmp_path / "one" / "0.png").read_bytes()
    assert main(base + ["--out", str(tmp_path / "bad"), "--jobs", "0"]) == 2
    assert "--jobs" in capsys.readouterr().err
    # without simulations the pool's workers draw the figures: the same bytes again
    plain = [a for a in base if a not in ("--n-sim", "2")]
    run_json(plain + ["--out", str(tmp_path / "one0"), "--jobs", "1"], capsys)
    run_json(plain + ["--out", str(tmp_path / "two0"), "--jobs", "2"], capsys)
    assert (tmp_path / "two0" / "0.png").read_bytes() == (tmp_path / "one0" / "0.png").read_bytes()


def test_report_and_figures_drawn_on_workers_equal_those_drawn_here(tmp_path, capsys):
    """The axes' figures drawn by the pool's workers while this process writes the exports
    and the Allan overview give the same files as everything drawn here."""
    pytest.importorskip("matplotlib")
    path = tmp_path / "imu.npz"
    x = np.column_stack([stochmod.model_from_spec("WN(sigma2=1e-4)+RW(sigma2=1e-10)", 100.0)
                         .simulate(2**13, rng=s) for s in (1, 2)])
    np.savez(path, gyro_x=x[:, 0], accel_x=x[:, 1], freq=100.0)
    base = ["calibrate", "--assume-si", str(path), "--candidates", "WN", "WN+RW", "--report",
            "--export", "kalibr", "--json"]
    run_json(base + ["--out", str(tmp_path / "one"), "--jobs", "1"], capsys)
    run_json(base + ["--out", str(tmp_path / "two"), "--jobs", "2"], capsys)
    for name in ("report.html", "gyro_x.png", "accel_x.png", "kalibr_imu.yaml"):
        assert (tmp_path / "two" / name).read_bytes() == (tmp_path / "one" / name).read_bytes()


def test_the_overview_is_submitted_between_the_first_figures_and_the_others(tmp_path, capsys,
                                                                          monkeypatch):
    """On a pool of 2: two axis figures, then the report's Allan overview (the longest task),
    then the other axes, so that the overview does not run last beside an idle worker."""
    pytest.importorskip("matplotlib")
    import concurrent.futures

    order: list[str] = []

    class Recording(concurrent.futures.ThreadPoolExecutor):
        def submit(self, fn, *args, **kwargs):
            order.append(fn.__name__)
            return super().submit(fn, *args, **kwargs)

    pool = Recording(2)  # a context manager of itself, as _pool's pools are
    monkeypatch.setattr(calibrate_cli, "_pool", lambda executor, jobs, warm=(): pool)
    path = tmp_path / "imu.npz"
    x = np.column_stack([stochmod.model_from_spec("WN(sigma2=1e-4)+RW(sigma2=1e-10)", 100.0)
                         .simulate(2**12, rng=s) for s in range(4)])
    np.savez(path, gyro_x=x[:, 0], gyro_y=x[:, 1], accel_x=x[:, 2], accel_y=x[:, 3], freq=100.0)
    assert main(["calibrate", "--assume-si", str(path), "--candidates", "WN", "WN+RW", "--report",
                 "--out", str(tmp_path / "out")]) == 0
    capsys.readouterr()
    drawn = [name for name in order if name in ("axis_figure_png", "allan_overview_png")]
    assert drawn == ["axis_figure_png"] * 2 + ["allan_overview_png"] + ["axis_figure_png"] * 2


def test_matplotlib_is_imported_here_while_reading_and_done_before_the_pool_forks(
        gm_wn_file, tmp_path, capsys, monkeypatch):
    """With figures on a pool of forked workers, this process imports matplotlib on a thread
    while it reads the file; the thread has ended when the pool is made (no thread may be
    importing when a worker is forked), so the workers inherit the modules."""
    pytest.importorskip("matplotlib")
    import importlib
    import threading

    seen = {"on the thread": []}
    made, import_module = calibrate_cli._pool, importlib.import_module

    def pool(*args, **kwargs):
        seen["alive"] = [t.name for t in threading.enumerate()
                         if t.name == "stochmod-figure-imports"]
        seen["before the pool"] = list(seen["on the thread"])
        return made(*args, **kwargs)

    def recorded(name, *args, **kwargs):
        if threading.current_thread().name == "stochmod-figure-imports":
            seen["on the thread"].append(name)
        return import_module(name, *args, **kwargs)

    monkeypatch.setattr(calibrate_cli, "_pool", pool)
    monkeypatch.setattr(importlib, "import_module", recorded)
    args = ["calibrate", "--assume-si", str(gm_wn_file), "--freq", "50", "--candidates", "WN",
            "GM+WN", "--json", "--out", str(tmp_path / "out"), "--jobs", "2"]
    run_json(args, capsys)
    assert seen["alive"] == []
    assert {"matplotlib.figure", "matplotlib.backends.backend_agg"} <= set(seen["before the pool"])
    assert (tmp_path / "out" / "0.png").exists()
    seen["on the thread"].clear()
    run_json(args[:-1] + ["1"], capsys)  # no pool to fork: nothing imported ahead
    assert seen["on the thread"] == []


def test_a_failed_import_ahead_is_no_traceback_and_no_failure(gm_wn_file, tmp_path, capsys,
                                                             monkeypatch):
    """An import that breaks on the thread ahead of the pool leaves the figures to the
    workers, which import matplotlib themselves: the run succeeds and prints no traceback."""
    pytest.importorskip("matplotlib")
    import importlib
    import threading

    import_module = importlib.import_module

    def broken(name, *args, **kwargs):
        if threading.current_thread().name == "stochmod-figure-imports":
            raise RuntimeError("a broken font cache")
        return import_module(name, *args, **kwargs)

    uncaught = []
    monkeypatch.setattr(importlib, "import_module", broken)
    monkeypatch.setattr(threading, "excepthook", uncaught.append)
    args = ["calibrate", "--assume-si", str(gm_wn_file), "--freq", "50", "--candidates", "WN",
            "GM+WN", "--json", "--out", str(tmp_path / "out"), "--jobs", "2"]
    assert main(args) == 0
    captured = capsys.readouterr()
    assert uncaught == [] and "Traceback" not in captured.err
    assert json.loads(captured.out)["columns"]
    assert (tmp_path / "out" / "0.png").exists()


# ---------------------------------------------------------------- the bundled example
def test_calibrate_bundled_example_two_axes(tmp_path, capsys):
    report = run_json(["calibrate", "--assume-si", "--n", "8192", "--column", "gyro_x", "--column", "accel_x",
                       "--candidates", "WN", "GM+WN", "--out", str(tmp_path), "--no-plots",
                       "--json"], capsys)
    assert sorted(report["columns"]) == ["accel_x", "gyro_x"]  # JSON keys are sorted
    assert report["freq"] == 100.0 and report["n"] == 8192
    imu = report["imu_augmentation"]
    assert imu["axes"] == ["gyro_x", "accel_x"]  # row order of H
    n_states = len(imu["state_names"])
    assert np.asarray(imu["H"]).shape == (2, n_states)
    assert np.asarray(imu["Phi"]).shape == (n_states, n_states)
    assert len(imu["white_var"]) == 2
    assert all(name.split(".")[0] in ("gyro_x", "accel_x") for name in imu["state_names"])


def test_calibrate_errors_are_one_line(gm_wn_file, tmp_path, capsys):
    assert main(["calibrate", "--assume-si", str(tmp_path / "nope.csv"), "--freq", "10"]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["calibrate", "--assume-si", str(gm_wn_file), "--freq", "50", "--n", "100"]) == 2
    assert "bundled example only" in capsys.readouterr().err
    assert main(["calibrate", "--assume-si", "--freq", "50", "--out", str(tmp_path)]) == 2
    assert "does not apply" in capsys.readouterr().err
    assert main(["calibrate", "--assume-si", str(gm_wn_file), "--freq", "50", "--scale", "-1"]) == 2
    assert "--scale" in capsys.readouterr().err
    assert main(["calibrate", "--assume-si", str(gm_wn_file), "--freq", "50", "--dt", "0", "--out", str(tmp_path)]) == 2
    assert "--dt" in capsys.readouterr().err


def test_a_short_bundled_example_is_an_error_signal_the_checks_accept(tmp_path, capsys):
    """The slowest accelerometer GM (0.042 g stationary, Tc 72 min) is a constant over 41 s;
    the example's columns are less their means, so the magnitude check does not read that
    bias as gravity in g, and the wavelet variance is that of the uncentred simulation."""
    rec = xsens_mtig(n=4096)
    assert np.all(np.abs(rec.data.mean(axis=0)) < 1e-12 * rec.data.std(axis=0))
    models = xsens_mtig_models()
    raw = models["accel_x"].simulate(4096, np.random.default_rng(0))
    np.testing.assert_allclose(stochmod.wvar(raw - raw.mean(), 100.0).wv,
                               stochmod.wvar(raw, 100.0).wv, rtol=1e-9)
    assert main(["calibrate", "--n", "4096", "--candidates", "WN", "GM+WN", "--no-plots",
                 "--out", str(tmp_path)]) == 0
    assert "accel_x (accel, m/s^2)" in capsys.readouterr().out


def test_example_columns_units_and_reproducibility():
    rec = xsens_mtig(n=4096, seed=3)
    assert rec.columns == XSENS_COLUMNS and rec.freq == 100.0 and rec.data.shape == (4096, 6)
    again = xsens_mtig(n=4096, seed=3)
    assert np.array_equal(rec.data, again.data)
    assert not np.array_equal(rec.data, xsens_mtig(n=4096, seed=4).data)
    assert abs(np.corrcoef(rec.data[:, 0], rec.data[:, 1])[0, 1]) < 0.1  # independent axes
    with pytest.raises(InputError):
        xsens_mtig(n=10)
    with pytest.raises(InputError, match="reading"):
        xsens_mtig_models(reading="psd")


def test_example_models_follow_table_ii():
    """Stebler et al. (2014) Table II, converted by hand: WN density N -> N^2 freq; GM driving
    density q -> stationary variance q^2 / (2 beta); deg -> rad, ug -> 1e-6 g0."""
    models = xsens_mtig_models(100.0)
    gyro, accel = models["gyro_x"], models["accel_z"]
    assert [p.family for p in gyro.processes] == ["GM", "GM", "WN"]
    assert [p.family for p in accel.processes] == ["GM", "GM", "GM", "WN"]
    deg = math.pi / 180
    assert gyro.processes[2].sigma2 == pytest.approx((0.032 * deg) ** 2 * 100, rel=1e-12)
    assert gyro.processes[1].beta == 9.03e-4
    assert gyro.processes[1].sigma2 == pytest.approx((8.64e-4 * deg) ** 2 / (2 * 9.03e-4), rel=1e-12)
    assert accel.processes[3].sigma2 == pytest.approx((85.5e-6 * G0) ** 2 * 100, rel=1e-12)
    assert accel.processes[2].sigma2 == pytest.approx((900e-6 * G0) ** 2 / (2 * 2.32e-4), rel=1e-12)
    alt = xsens_mtig_models(100.0, reading="stationary")["accel_x"]
    assert alt.processes[2].sigma2 == pytest.approx((900e-6 * G0) ** 2, rel=1e-12)


def test_example_simulation_has_the_models_wavelet_variance():
    rec = xsens_mtig(n=2**15, seed=5)
    J = 8
    for k in (0, 3):
        fit_wv = stochmod.wvar(rec.data[:, k], 100.0, levels=J)
        truth = xsens_mtig_models()[rec.columns[k]].wv(J)
        eta = np.maximum(fit_wv.n_coef / 2.0 ** fit_wv.levels, 1)
        z = (fit_wv.wv - truth) / (truth * np.sqrt(2 / eta))  # chi2 standard errors
        assert np.all(np.abs(z) < 4), (rec.columns[k], z)


# ---------------------------------------------------------------- figures
def test_simulated_wv_mean_matches_theory_and_figure_has_the_layers():
    pytest.importorskip("matplotlib")
    from stochmod.output.plots import plot_fit, simulated_wv

    truth = stochmod.model_from_spec("WN(sigma2=4.0)", 10.0)
    fit = gmwm(truth.simulate(2**12, rng=1), "WN", 10.0)
    sims = simulated_wv(fit, n_sim=40, rng=2)
    theory = fit.model.wv(fit.levels)
    se = sims.std(axis=0, ddof=1) / np.sqrt(40)
    assert np.all(np.abs(sims.mean(axis=0) - theory) < 4 * se)
    fig = plot_fit(fit, n_sim=5, rng=0, unit="rad/s")
    ax = fig.axes[0]
    assert len(ax.lines) == 5 + 2  # simulations, empirical, model
    assert ax.get_xscale() == "log" and "(rad/s)^2" in ax.get_ylabel()


def test_simulated_wv_slices_stack_to_the_full_set_and_can_be_drawn():
    pytest.importorskip("matplotlib")
    from stochmod.output.plots import plot_fit, simulated_wv

    truth = stochmod.model_from_spec("GM(beta=2.0, sigma2=1.0) + WN(sigma2=0.5)", 10.0)
    fit = gmwm(truth.simulate(2**11, rng=3), "GM+WN", 10.0)
    full = simulated_wv(fit, n_sim=5, rng=4)
    parts = [simulated_wv(fit, n_sim=5, rng=4, indices=slice(a, b)) for a, b in [(0, 2), (2, 5)]]
    assert np.array_equal(np.vstack(parts), full)
    assert simulated_wv(fit, n_sim=5, rng=4, indices=slice(5, 5)).shape == (0, fit.levels)
    ax = plot_fit(fit, simulated=full[:3]).axes[0]
    assert len(ax.lines) == 3 + 2
    assert np.array_equal(ax.lines[1].get_ydata(), full[1])
    with pytest.raises(InputError, match="levels"):
        plot_fit(fit, simulated=full[:, :-1])


def test_plots_without_matplotlib_name_the_extra(monkeypatch):
    from stochmod.output import plots

    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    fit = gmwm(np.random.default_rng(0).standard_normal(1024), "WN", 10.0)
    with pytest.raises(ImportError, match=r"stochmod\[plots\]"):
        plots.plot_fit(fit, n_sim=0)


def test_freq_against_time_stamps_and_clock_columns_are_refused(tmp_path, capsys):
    rng = np.random.default_rng(3)
    t = np.arange(400) / 100.0
    path = tmp_path / "imu.csv"
    rows = ["time,gyro_x,tiem"] + [f"{a:.2f},{b:.6e},{a:.2f}"
                                   for a, b in zip(t, 1e-3 * rng.standard_normal(t.size))]
    path.write_text("\n".join(rows) + "\n")
    out = str(tmp_path / "out")
    # --freq 200 against 100 Hz time stamps
    assert main(["calibrate", "--assume-si", str(path), "--column", "gyro_x", "--freq", "200", "--out", out]) == 2
    assert "--freq 200 contradicts the time stamps" in capsys.readouterr().err
    # a misspelled time column is not modelled as a sensor unless it is named
    assert main(["calibrate", "--assume-si", str(path), "--out", out, "--no-plots"]) == 2
    err = capsys.readouterr().err
    last = err.strip().splitlines()[-1]  # after the reader's note on the time stamps
    assert last.startswith("stochmod calibrate: error: ") and "column 'tiem' increases" in last
    # within 1 % of the time stamps' rate, and the column named: read as asked
    assert main(["wv", str(path), "--column", "gyro_x", "--column", "tiem", "--freq", "100.5"]) == 0
