"""``stochmod navigate`` and ``stochmod outages`` end to end on emulated recordings written as the
CLI's CSV inputs: outputs, accuracy against the emulation's truth, the calibration file, errors."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

import stochmod
from stochmod.cli import main
from stochmod.cli.navigate import TRAJECTORY_COLUMNS, UNTRUSTED_STATUS
from stochmod.nav import (
    Segment,
    add_sensor_errors,
    gnss_measurements,
    ideal_imu,
    trajectory_from_profile,
)
from stochmod.nav.emulate import AXES
from stochmod.nav.logs import calibration_record, read_calibration
from stochmod.nav.study import horizontal_error

FS = 50.0
GYRO = (stochmod.WN.from_density(3e-4, FS) + stochmod.RW.from_rrw(1e-5, FS)).bind(FS)
ACCEL = (stochmod.WN.from_density(2e-3, FS) + stochmod.RW.from_rrw(1e-4, FS)).bind(FS)
MODELS = {a: GYRO if a.startswith("gyro") else ACCEL for a in AXES}
PROFILE = [Segment(10, speed=12), Segment(10, turn=90), Segment(15, speed=18),
           Segment(10, turn=-60), Segment(15)]


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """An emulated 60 s drive written as navigate's CSVs, with its truth."""
    truth = trajectory_from_profile(PROFILE, rate=FS, lat=46.5, lon=6.6, height=400.0,
                                    heading=20.0, speed=5.0)
    imu = add_sensor_errors(ideal_imu(truth, "rate"), MODELS, 5)
    gnss = gnss_measurements(truth, 1.0, sigma_h=1.0, sigma_v=2.0, sigma_vel=0.1, rng=6)
    folder = tmp_path_factory.mktemp("drive")
    np.savetxt(folder / "imu.csv", np.column_stack([imu.time, imu.gyro, imu.accel]),
               delimiter=",", fmt="%.17g", comments="",
               header="Time,Gyro_X,gyro_y,gyro_z,accel_x,accel_y,accel_z")
    np.savetxt(folder / "gnss.csv",
               np.column_stack([gnss.time, gnss.lat, gnss.lon, gnss.height, gnss.vel_ned,
                                gnss.sd]), delimiter=",", fmt="%.17g", comments="",
               header="time,lat,lon,height,vn,ve,vd,sd_n,sd_e,sd_d")
    calibration = {"freq": FS, "columns": {a.upper(): {"model": m.to_spec()}
                                           for a, m in MODELS.items()}}
    (folder / "calibration.json").write_text(json.dumps(calibration))
    return folder, truth


def _init_text(truth) -> str:
    first = truth.at(truth.time[:1])
    values = [first.lat[0], first.lon[0], first.height[0], *first.vel_ned[0], *first.rph[0]]
    return ",".join(f"{v:.12f}" for v in values)


def test_navigate_writes_an_accurate_trajectory(recording, tmp_path, capsys) -> None:
    folder, truth = recording
    out = tmp_path / "out"
    code = main(["navigate", str(folder / "imu.csv"), str(folder / "gnss.csv"), "--out", str(out),
                 "--calibration", str(folder / "calibration.json"), "--init", _init_text(truth),
                 "--gyro-bias-sd", "1e-4", "--accel-bias-sd", "0.01", "--outage", "30", "15",
                 "--no-plots"])
    assert code == 0
    assert "gnss_position" in capsys.readouterr().out
    header = (out / "trajectory.csv").read_text().splitlines()[0].split(",")
    assert header == list(TRAJECTORY_COLUMNS) + [f"sd_{c}" for c in TRAJECTORY_COLUMNS[1:]]
    table = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 0], truth.time, rtol=1e-12)
    err = horizontal_error(truth, table[:, 0], table[:, 1], table[:, 2])
    sd_h = np.hypot(table[:, 11], table[:, 12])
    assert np.median(err) < 2.0  # m, GNSS at 1 m
    assert np.mean(err < 3 * sd_h + 0.5) > 0.95  # the reported 1-sigma covers the error
    in_outage = (table[:, 0] - truth.time[0] > 30) & (table[:, 0] - truth.time[0] < 45)
    assert sd_h[in_outage].max() > 2 * np.median(sd_h)  # uncertainty grows without GNSS
    report = (out / "report.txt").read_text()
    assert "calibration.json" in report and "(30.0, 15.0)" in report


ARM = (1.2, -0.6, -1.5)  # m, IMU to antenna, body x/y/z


def test_navigate_estimates_the_lever_arm(recording, tmp_path) -> None:
    folder, truth = recording
    gnss = gnss_measurements(truth, 1.0, sigma_h=0.3, sigma_v=0.5, sigma_vel=0.05, lever_arm=ARM,
                             rng=7)
    np.savetxt(tmp_path / "gnss.csv", np.column_stack([gnss.time, gnss.lat, gnss.lon, gnss.height,
                                                       gnss.vel_ned, gnss.sd]),
               delimiter=",", fmt="%.17g", comments="",
               header="time,lat,lon,height,vn,ve,vd,sd_n,sd_e,sd_d")
    common = [str(folder / "imu.csv"), str(tmp_path / "gnss.csv"), "--calibration",
              str(folder / "calibration.json"), "--init", _init_text(truth), "--gyro-bias-sd",
              "1e-4", "--accel-bias-sd", "0.01", "--no-plots"]
    errors = {}
    for name, extra in (("estimated", ["--lever-arm-sd", "2"]), ("ignored", [])):
        out = tmp_path / name
        assert main(["navigate", *common, "--out", str(out), *extra]) == 0
        table = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
        errors[name] = np.median(horizontal_error(truth, table[:, 0], table[:, 1], table[:, 2]))
    report = (tmp_path / "estimated" / "report.txt").read_text()
    line = next(x for x in report.splitlines() if x.startswith("lever arm"))
    est = [float(v) for v in re.findall(r"([xyz]) (-?[0-9.]+) \+- ([0-9.]+)", line)
           for v in v[1:]]
    arm, sd = np.array(est[0::2]), np.array(est[1::2])
    assert np.all(np.abs(arm - ARM) < 3 * sd + 0.05), (arm, sd)
    assert np.all(sd[:2] < 0.5)  # the turns make x and y observable; z (height) barely is
    assert sd[2] <= 2.0
    assert "(fixed)" in (tmp_path / "ignored" / "report.txt").read_text()
    assert errors["estimated"] < 0.5 * errors["ignored"], errors


def test_navigate_error_model_option(recording, tmp_path) -> None:
    """--error-model modified-phi reaches the filter (the report names it, the trajectory
    differs from psi's at second order) and keeps the trajectory as accurate."""
    folder, truth = recording
    tables = {}
    for model in ("psi", "modified-phi"):
        out = tmp_path / model
        assert main(["navigate", str(folder / "imu.csv"), str(folder / "gnss.csv"), "--out",
                     str(out), "--init", _init_text(truth), "--gyro-bias-sd", "1e-4",
                     "--accel-bias-sd", "0.01", "--error-model", model, "--no-plots"]) == 0
        assert f"filter error model: {model}" in (out / "report.txt").read_text()
        tables[model] = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    a, b = tables["psi"], tables["modified-phi"]
    assert 0 < np.abs(a[:, 4:7] - b[:, 4:7]).max() < 0.1  # m/s: the resets differ, a little
    for t in tables.values():
        assert np.median(horizontal_error(truth, t[:, 0], t[:, 1], t[:, 2])) < 2.0
    with pytest.raises(SystemExit):  # argparse refuses an unknown name
        main(["navigate", str(folder / "imu.csv"), str(folder / "gnss.csv"), "--out",
              str(tmp_path / "x"), "--error-model", "phi"])


def test_navigate_runs_the_library_filter(recording, tmp_path) -> None:
    """The command's trajectory is the library filter's with the same settings on the same
    files, to the digits it writes."""
    from stochmod.cli.navigate import default_models, trajectory_table
    from stochmod.nav.alignment import InitialState
    from stochmod.nav.filter import LooselyCoupledFilter
    from stochmod.nav.logs import read_gnss_csv, read_imu_csv

    folder, truth = recording
    imu, gnss = read_imu_csv(folder / "imu.csv"), read_gnss_csv(folder / "gnss.csv")
    gyro, accel = default_models(FS)
    init = [float(v) for v in _init_text(truth).split(",")]
    out = tmp_path / "default"
    assert main(["navigate", str(folder / "imu.csv"), str(folder / "gnss.csv"), "--out",
                 str(out), "--init", _init_text(truth), "--gyro-bias-sd", "1e-4",
                 "--accel-bias-sd", "0.01", "--no-plots"]) == 0
    flt = LooselyCoupledFilter({a: gyro for a in "xyz"}, {a: accel for a in "xyz"},
                               gyro_bias_sd=1e-4, accel_bias_sd=0.01)
    ref = flt.run(imu.time, imu.gyro, imu.accel, kind=imu.kind, gnss=gnss,
                  init=InitialState(*init[:3], init[3:6], init[6:9], time=float(imu.time[0])))
    table = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(table, trajectory_table(ref), rtol=1e-11, atol=0)
    assert np.median(horizontal_error(truth, table[:, 0], table[:, 1], table[:, 2])) < 2.0


def test_navigate_aligns_itself_and_plots(recording, tmp_path) -> None:
    pytest.importorskip("matplotlib")
    folder, truth = recording
    out = tmp_path / "out"
    assert main(["navigate", str(folder / "imu.csv"), str(folder / "gnss.csv"), "--out",
                 str(out), "--gyro-bias-sd", "1e-4", "--accel-bias-sd", "0.01"]) == 0
    assert (out / "map.png").stat().st_size > 0 and (out / "sigma.png").stat().st_size > 0
    table = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    late = table[:, 0] > truth.time[0] + 30
    assert np.median(horizontal_error(truth, table[late, 0], table[late, 1],
                                      table[late, 2])) < 3.0


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--init", "1,2,3"], "--init needs 9"),
        (["--init", "a,b"], "--init must be 9"),
        (["--gyro-bias-sd", "-1"], "--gyro-bias-sd must be"),
        (["--outage", "10", "0"], "DURATION must be positive"),
        (["--lever-arm-sd", "1", "2"], "one or three values"),
        (["--lever-arm-sd", "-1"], "--lever-arm-sd must be"),
        (["--calibration", "absent.json"], "no such calibration file"),
        (["--gate", "1.5"], "--gate must be a probability"),
        (["--gate", "never"], "--gate must be a number or off"),
        (["--recover-after", "0"], "--recover-after must be"),
        (["--init-level-sd", "0"], "--init-level-sd must be a positive"),
        (["--vel-sd", "-1"], "--vel-sd must be a positive"),
    ],
)
def test_navigate_bad_arguments(recording, tmp_path, capsys, extra, message) -> None:
    folder, _ = recording
    code = main(["navigate", str(folder / "imu.csv"), str(folder / "gnss.csv"), "--out",
                 str(tmp_path / "o"), "--no-plots", *extra])
    assert code == 2
    assert message in capsys.readouterr().err


def test_read_calibration_round_trip_and_errors(recording, tmp_path) -> None:
    folder, _ = recording
    models = read_calibration(folder / "calibration.json")
    assert set(models) == set(AXES)
    for axis in AXES:
        assert models[axis] == MODELS[axis]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"freq": FS, "columns": {"gyro_x": {"model": GYRO.to_spec()}}}))
    with pytest.raises(stochmod.core.errors.InputError, match=r"no column\(s\) \['gyro_y'"):
        read_calibration(bad)
    bad.write_text("{not json")
    with pytest.raises(stochmod.core.errors.InputError, match="not a JSON file"):
        read_calibration(bad)


def test_navigate_takes_a_gm_beyond_the_calibration_record_as_a_random_walk(
        recording, tmp_path, capsys) -> None:
    # a degenerate fit (outages.md): a GM with Tc 7e13 s and sigma 32 rad/s on each gyro of a
    # 2^19-sample calibration; its stationary sigma as the initial bias sd would wreck the run
    folder, truth = recording
    n = 2**19
    gyro = (GYRO + stochmod.GM.from_correlation_time(7e13, 32.0)).bind(FS)
    calibration = {"freq": FS, "n": n, "columns": {
        a: {"model": (gyro if a.startswith("gyro") else ACCEL).to_spec()} for a in AXES}}
    (tmp_path / "calibration.json").write_text(json.dumps(calibration))
    out = tmp_path / "out"
    with pytest.warns(UserWarning, match="random walk"):
        code = main(["navigate", str(folder / "imu.csv"), str(folder / "gnss.csv"), "--out",
                     str(out), "--calibration", str(tmp_path / "calibration.json"), "--init",
                     _init_text(truth), "--gyro-bias-sd", "1e-4", "--accel-bias-sd", "0.01",
                     "--no-plots"])
    assert code == 0
    report = (out / "report.txt").read_text()
    record = n / FS
    assert report.count(f"beyond the {record:g} s record") == 3
    q = 2 * 32.0**2 / 7e13
    assert f"initial sd sqrt(q T) = {np.sqrt(q * record):.3g}" in report
    table = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    assert np.median(horizontal_error(truth, table[:, 0], table[:, 1], table[:, 2])) < 2.0
    capsys.readouterr()


def test_calibration_record_is_the_longest_single_record(tmp_path) -> None:
    path = tmp_path / "c.json"
    for data, want in [({"freq": 100.0, "n": 1000}, 10.0),
                       ({"freq": 100.0, "n": 1500, "segments": [{"start": 0.0, "n": 1000},
                                                                {"start": 20.0, "n": 500}]}, 10.0),
                       ({"freq": 50.0, "n": 700, "replicates": {"n": [300, 400]}}, 8.0),
                       ({"freq": 100.0, "n": 1500, "record_sizes": [500, 1000], "schema": 2}, 10.0),
                       ({"freq": 100.0}, None)]:
        path.write_text(json.dumps({"columns": {}, **data}))
        assert calibration_record(path) == want, data
    for data, message in [({"columns": {}, "n": 10}, "'freq' must be a positive number"),
                          ([1, 2], "no 'columns' object"),
                          ({"columns": {}, "freq": 100.0, "schema": 3}, "schema 3, written by a "
                                                                         "newer stochmod")]:
        path.write_text(json.dumps(data))
        with pytest.raises(stochmod.core.errors.InputError, match=message):
            calibration_record(path)


@pytest.mark.slow
def test_outages_cli_quick(recording, capsys) -> None:
    folder, _ = recording
    code = main(["outages", "--calibration", str(folder / "calibration.json"), "--runs", "2",
                 "--workers", "2", "--quick", "--gyro-bias-sd", "1e-4"])
    assert code == 0
    out = capsys.readouterr().out
    assert "60+30 s" in out and "130+30 s" in out
    assert "calibrated" in out and "white noise" in out and "mean NEES" in out
    assert "2 run(s)" in out
    for bad in (["--runs", "0"], ["--workers", "0"], ["--dt-filter", "0"]):
        assert main(["outages", "--calibration", str(folder / "calibration.json"), *bad]) == 2


def test_white_part() -> None:
    from stochmod.cli.outages import white_part

    two = (stochmod.WN(sigma2=1e-4) + stochmod.WN(sigma2=3e-4)
           + stochmod.GM.from_correlation_time(10.0, 1e-2)).bind(FS)
    assert white_part(two).processes[0].sigma2 == pytest.approx(4e-4)
    gm = stochmod.Model((stochmod.GM.from_correlation_time(10.0, 1e-2),)).bind(FS)
    white = white_part(gm)
    # the substitute white noise has the GM's level-1 wavelet variance (WN's own formula)
    assert float(white.wv(1)[0]) == pytest.approx(float(gm.wv(1)[0]), rel=1e-12)
    assert [p.family for p in white.processes] == ["WN"] and white.freq == FS


def test_outages_cli_passes_the_calibration_record(recording, tmp_path, monkeypatch,
                                                   capsys) -> None:
    """The calibration's record length reaches the study for the filters and the emulated
    truth alike (both are the calibration's models)."""
    import stochmod.cli.outages as cli_outages

    seen = {}

    class Done:
        def summary(self) -> str:
            return "study"

    def fake(filters, truth, **kw):
        seen.update(kw)
        return Done()

    monkeypatch.setattr(cli_outages, "outage_study", fake)
    n = 30000
    calibration = {"freq": FS, "n": n, "columns": {a: {"model": m.to_spec()}
                                                  for a, m in MODELS.items()}}
    path = tmp_path / "calibration.json"
    path.write_text(json.dumps(calibration))
    # --no-drift: the fake study has no outages to predict the drift of
    assert main(["outages", "--calibration", str(path), "--runs", "1", "--quick",
                 "--no-drift"]) == 0
    assert seen["record"] == seen["truth_record"] == n / FS
    folder, _ = recording  # an older file without the record length: models as given
    assert main(["outages", "--calibration", str(folder / "calibration.json"), "--runs", "1",
                 "--quick", "--no-drift"]) == 0
    assert seen["record"] is None and seen["truth_record"] is None
    capsys.readouterr()


def _biased_imu(folder, tmp_path, bias_deg_h=5000.0):
    """The recording's IMU with turn-on gyro biases of `bias_deg_h` on every axis."""
    table = np.loadtxt(folder / "imu.csv", delimiter=",", skiprows=1)
    table[:, 1:4] += np.radians(bias_deg_h / 3600.0) * np.array([1.0, -1.0, 1.0])
    path = tmp_path / "imu_biased.csv"
    np.savetxt(path, table, delimiter=",", fmt="%.17g", comments="",
               header="time,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z")
    return path


def test_navigate_recovers_from_rejections_and_reports_its_health(recording, tmp_path,
                                                                   capsys) -> None:
    """5000 deg/h gyro biases against the default 300 deg/h prior: with the recovery the run
    is accurate and trusted; without it the gate locks out, the command warns on stderr and
    exits with status 3, or 0 with --accept-untrusted."""
    folder, truth = recording
    imu = _biased_imu(folder, tmp_path)
    common = [str(imu), str(folder / "gnss.csv"), "--init", _init_text(truth), "--no-plots"]
    out = tmp_path / "recovered"
    assert main(["navigate", *common, "--out", str(out)]) == 0
    assert "UNTRUSTED" not in capsys.readouterr().err
    report = (out / "report.txt").read_text()
    assert "recovery t = " in report and "Filter health" in report
    assert "alignment: t = " in report and "in motion (speed 5.00 m/s), given initial" in report
    health = json.loads((out / "health.json").read_text())
    assert health["trusted"] and sum(health["recoveries"].values()) >= 1
    assert health["alignment"]["source"] == "given" and not health["alignment"]["static"]
    table = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    late = table[:, 0] > truth.time[0] + 30
    assert np.median(horizontal_error(truth, table[late, 0], table[late, 1],
                                      table[late, 2])) < 2.0
    locked = tmp_path / "locked"
    assert main(["navigate", *common, "--out", str(locked), "--recover-after", "off"]) == \
        UNTRUSTED_STATUS
    err = capsys.readouterr().err
    assert "WARNING: UNTRUSTED SOLUTION" in err and "of the updates rejected" in err
    health = json.loads((locked / "health.json").read_text())
    assert not health["trusted"] and health["rejected_share"]["gnss_position"] > 0.2
    assert "verdict: UNTRUSTED SOLUTION" in (locked / "report.txt").read_text()
    assert (locked / "trajectory.csv").exists()  # the outputs are written all the same
    assert main(["navigate", *common, "--out", str(locked), "--recover-after", "off",
                 "--accept-untrusted"]) == 0
    assert "exit status 0" in capsys.readouterr().err
    # no gate: nothing rejected, nothing to recover
    assert main(["navigate", *common, "--out", str(tmp_path / "off"), "--gate", "off"]) == 0
    health = json.loads((tmp_path / "off" / "health.json").read_text())
    assert health["rejected_share"] == {"gnss_position": 0.0, "gnss_velocity": 0.0}
    assert "gate off" in (tmp_path / "off" / "report.txt").read_text()


def test_navigate_initial_and_velocity_sigmas_reach_the_filter(recording, tmp_path) -> None:
    folder, truth = recording
    out = tmp_path / "out"
    # a GNSS file without velocity sigmas: --vel-sd is the one the filter uses
    assert main(["navigate", str(folder / "imu.csv"), str(folder / "gnss.csv"), "--out",
                 str(out), "--init", _init_text(truth), "--init-position-sd", "7",
                 "--init-velocity-sd", "0.7", "--init-level-sd", "0.4", "--init-heading-sd",
                 "9", "--vel-sd", "0.1", "--gate", "0.999", "--no-plots"]) == 0
    report = (out / "report.txt").read_text()
    assert "initial 1-sigma 7 m, 0.7 m/s, level 0.4/0.4 deg, heading 9 deg" in report
    assert "GNSS velocity sd 0.1 m/s" in report and "gate 0.999, recovery after 5" in report
    table = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[0, 10:13], [7.0, 7.0, 7.0])
    np.testing.assert_allclose(table[0, 13:16], [0.7, 0.7, 0.7])
    np.testing.assert_allclose(table[0, 16:19], [0.4, 0.4, 9.0])
    # self-aligned: the options replace the alignment's sigmas too
    assert main(["navigate", str(folder / "imu.csv"), str(folder / "gnss.csv"), "--out",
                 str(tmp_path / "aligned"), "--init-heading-sd", "12", "--no-plots"]) == 0
    report = (tmp_path / "aligned" / "report.txt").read_text()
    assert "in-motion alignment from GNSS" in report and "heading 12 deg" in report
    assert "level 2/2 deg" in report  # the alignment's own



def test_navigate_smooth_writes_the_smoothed_trajectory(recording, tmp_path) -> None:
    folder, truth = recording
    out = tmp_path / "out"
    assert main(["navigate", str(folder / "imu.csv"), str(folder / "gnss.csv"), "--out",
                 str(out), "--init", _init_text(truth), "--outage", "30", "15", "--smooth",
                 "--no-plots"]) == 0
    header = (out / "trajectory.csv").read_text().splitlines()[0]
    assert (out / "trajectory_smoothed.csv").read_text().splitlines()[0] == header
    filtered = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    smoothed = np.loadtxt(out / "trajectory_smoothed.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(smoothed[:, 0], filtered[:, 0])
    t = filtered[:, 0] - truth.time[0]
    gap = (t >= 30) & (t < 45)
    err = {name: horizontal_error(truth, x[gap, 0], x[gap, 1], x[gap, 2]).max()
           for name, x in (("filtered", filtered), ("smoothed", smoothed))}
    assert err["smoothed"] < 0.5 * err["filtered"], err
    assert np.all(smoothed[:, 10:] <= filtered[:, 10:] * (1 + 1e-6) + 1e-9)  # sigmas
    assert "fixed-interval RTS" in (out / "report.txt").read_text()
    # without --smooth in the same folder: no stale smoothed solution is left behind
    assert main(["navigate", str(folder / "imu.csv"), str(folder / "gnss.csv"), "--out",
                 str(out), "--init", _init_text(truth), "--no-plots"]) == 0
    assert not (out / "trajectory_smoothed.csv").exists()
