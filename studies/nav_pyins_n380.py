"""Peer run: pyins' loosely-coupled feedback filter on the onavdata HGuide n380 drive with three
60 s GNSS outages, printing the maximum horizontal error in each outage against the
unit's own INS solution and the wall time, and writing them to
``tests/nav/reference/nav_pyins_n380.json`` (the numbers stochmod's real-drive test compares with).

Settings are those of pyins' real-data example (``examples/real_data_processing.ipynb`` of
pyins 1.0, the example with a low-to-middle grade MEMS IMU):

- gyro: bias sd 300 deg/h, white noise 1 deg/sqrt(h), bias random walk 30 deg/h/sqrt(h)
  (``bias_walk = 30 DH_TO_RS / 60``); accelerometer: bias sd 0.05 m/s^2, noise 0.1/60
  m/s/sqrt(s), bias walk 0.01/60 m/s^2/sqrt(s);
- GNSS position sd 1 m and NED velocity sd 0.3 m/s; initial sd 5 m, 0.5 m/s, level 0.2 deg,
  azimuth 1 deg; the initial state is the reference at the first epoch perturbed by
  ``generate_pva_error(..., rng=0)`` as in the example;
- covariance step 0.1 s (pyins' default).

The lever arm of the n380 drive is not given by onavdata (antenna "above rear-right passenger
on the roof rack"), so it is zero here by default, as it is for stochmod in that comparison;
``--lever-arm -1.3 0 0`` gives both filters the lever arm fitted from the data
(docs/navigation.md) and stores the run as ``raw/position/lever_arm`` with pyins' attitude
error, biases and 1-sigma just before each outage (``states_at_outages``), the numbers the
real-drive test compares stochmod's state with.

Two inputs are run:

- ``raw``: the increments and true time stamps of tests/nav/_n380.py (what stochmod gets);
- ``onavdata``: ``onavdata.get_data`` output (time rounded to 0.01 s, increments x 100 as
  rates, integrated by ``pyins.strapdown.compute_increments_from_imu(imu, "rate")``), the
  path a pyins user following onavdata's loader takes.

Run ``python studies/nav_pyins_n380.py [--write]`` (``--write`` refreshes the JSON's runs
of the inputs given with ``--inputs``). Timings are
noisy on a shared machine: wall time includes numba's JIT on the first run.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "nav"))

from _n380 import (OUTAGE_DURATION, OUTAGE_STARTS, SHORTNAME, in_outage,
                   load_n380, max_outage_errors)
from _n380 import PEER_JSON as REFERENCE_JSON

# pyins' real-data example (module docstring), SI units
GYRO = {"bias_sd_deg_h": 300.0, "noise_deg_sqrt_h": 1.0, "bias_walk_deg_h_sqrt_h": 30.0}
ACCEL = {"bias_sd": 0.05, "noise": 0.1 / 60, "bias_walk": 0.01 / 60}
POSITION_SD, VELOCITY_SD = 1.0, 0.3
INIT = {"position_sd": 5.0, "velocity_sd": 0.5, "level_sd": 0.2, "azimuth_sd": 1.0}


def _models():
    import pyins

    deg_h = pyins.transform.DH_TO_RS
    gyro = pyins.inertial_sensor.EstimationModel(
        bias_sd=GYRO["bias_sd_deg_h"] * deg_h,
        noise=GYRO["noise_deg_sqrt_h"] * pyins.transform.DRH_TO_RRS,
        bias_walk=GYRO["bias_walk_deg_h_sqrt_h"] * deg_h / 60)
    accel = pyins.inertial_sensor.EstimationModel(
        bias_sd=ACCEL["bias_sd"], noise=ACCEL["noise"], bias_walk=ACCEL["bias_walk"])
    return gyro, accel


def raw_inputs(drive):
    """pyins frames from the loader's increments (one 'before' row, as pyins expects)."""
    import pandas as pd
    import pyins

    imu = drive.imu
    imu_frame = pd.DataFrame(np.column_stack([imu.gyro, imu.accel]), index=imu.time,
                             columns=pyins.util.GYRO_COLS + pyins.util.ACCEL_COLS)
    increments = pyins.strapdown.compute_increments_from_imu(imu_frame, "increment")
    g = drive.gnss
    gnss = pd.DataFrame({"lat": g.lat, "lon": g.lon, "alt": g.height, "VN": g.vel_ned[:, 0],
                         "VE": g.vel_ned[:, 1], "VD": g.vel_ned[:, 2]}, index=g.time)
    r = drive.reference
    pva0 = pd.Series({"lat": r.lat[0], "lon": r.lon[0], "alt": r.height[0],
                      "VN": r.vel_ned[0, 0], "VE": r.vel_ned[0, 1], "VD": r.vel_ned[0, 2],
                      "roll": r.rph[0, 0], "pitch": r.rph[0, 1], "heading": r.rph[0, 2]},
                     name=float(imu.time[0]))
    return increments, gnss, pva0


def _onavdata_inputs():
    """pyins frames from onavdata.get_data (rounded time, rates = 100 x increments)."""
    import contextlib
    import io

    import onavdata
    import pandas as pd
    import pyins

    with contextlib.redirect_stdout(io.StringIO()):  # get_data prints many notices
        df = onavdata.get_data(SHORTNAME)
    df = df.sort_index()
    imu_rows = df.dropna(subset=["AngleRateX (rad/s)"])
    imu = pd.DataFrame(
        imu_rows[["AngleRateX (rad/s)", "AngleRateY (rad/s)", "AngleRateZ (rad/s)",
                  "AccelX (m/s^2)", "AccelY (m/s^2)", "AccelZ (m/s^2)"]].to_numpy(),
        index=imu_rows.index.to_numpy(), columns=pyins.util.GYRO_COLS + pyins.util.ACCEL_COLS)
    increments = pyins.strapdown.compute_increments_from_imu(imu, "rate")
    fixes = df.dropna(subset=["GNSSPosLat (rad)"])
    gnss = pd.DataFrame({
        "lat": np.rad2deg(fixes["GNSSPosLat (rad)"].to_numpy()),
        "lon": np.rad2deg(fixes["GNSSPosLon (rad)"].to_numpy()),
        "alt": fixes["GNSSPosAlt (m)"].to_numpy(),
        "VN": fixes["GNSSVelNorth (m/s)"].to_numpy(), "VE": fixes["GNSSVelEast (m/s)"].to_numpy(),
        "VD": fixes["GNSSVelDown (m/s)"].to_numpy()}, index=fixes.index.to_numpy())
    first = imu_rows.iloc[0]
    pva0 = pd.Series({"lat": np.rad2deg(first["PosLat (rad)"]),
                      "lon": np.rad2deg(first["PosLon (rad)"]), "alt": first["PosAlt (m)"],
                      "VN": first["VelNorth (m/s)"], "VE": first["VelEast (m/s)"],
                      "VD": first["VelDown (m/s)"],
                      "roll": np.rad2deg(first["AngleRoll (rad)"]),
                      "pitch": np.rad2deg(first["AnglePitch (rad)"]),
                      "heading": np.rad2deg(first["AngleHeading (rad)"])},
                     name=float(imu_rows.index[0]))
    return increments, gnss, pva0


def initial_error(seed: int = 0) -> dict[str, list[float]]:
    """pyins' start perturbation (``generate_pva_error(..., rng=seed)``): NED m, m/s, deg."""
    import pyins

    e = pyins.sim.generate_pva_error(INIT["position_sd"], INIT["velocity_sd"],
                                     INIT["level_sd"], INIT["azimuth_sd"], seed)
    return {"ned": e[["north", "east", "down"]].tolist(), "vel": e[["VN", "VE", "VD"]].tolist(),
            "rph": e[["roll", "pitch", "heading"]].tolist()}


def run_pyins(increments, gnss, pva0, *, velocity: bool, lever_arm=None,
              seed: int = 0) -> tuple[object, float]:
    """pyins' feedback filter with the example's settings; returns (result, wall seconds).
    `lever_arm`: IMU to antenna in the body frame (m), or None (none); `seed`: the draw of
    the initial error (``generate_pva_error(..., rng=seed)``)."""
    import pyins

    gnss = gnss[~in_outage(gnss.index.to_numpy(), float(pva0.name))]
    arm = None if lever_arm is None else np.asarray(lever_arm, dtype=float)
    measurements = [pyins.measurements.Position(gnss, POSITION_SD, arm)]
    if velocity:
        measurements.append(pyins.measurements.NedVelocity(gnss, VELOCITY_SD, arm))
    gyro, accel = _models()
    error = pyins.sim.generate_pva_error(INIT["position_sd"], INIT["velocity_sd"],
                                         INIT["level_sd"], INIT["azimuth_sd"], seed)
    start = pyins.sim.perturb_pva(pva0, error)
    t = time.perf_counter()
    result = pyins.filters.run_feedback_filter(
        start, INIT["position_sd"], INIT["velocity_sd"], INIT["level_sd"], INIT["azimuth_sd"],
        increments, gyro, accel, measurements=measurements)
    return result, time.perf_counter() - t


def states_at_outages(result, drive) -> dict[str, list]:
    """pyins' state at the last epoch before each outage: roll/pitch/heading error against the
    reference (deg), NED velocity error (m/s), gyro bias (deg/h), accelerometer bias (m/s^2),
    and their 1-sigma; ``pva_before``: the epoch's time and lat, lon (deg), alt (m), NED
    velocity (m/s), roll, pitch, heading (deg)."""
    traj, sd = result.trajectory, result.trajectory_sd
    out: dict[str, list] = {k: [] for k in ("rph_error_deg", "gyro_bias_deg_h", "accel_bias_m_s2",
                                            "rph_sd_deg", "gyro_bias_sd_deg_h",
                                            "accel_bias_sd_m_s2", "vel_error_m_s",
                                            "vel_sd_m_s")}
    for start in OUTAGE_STARTS:
        t = drive.t0 + start
        i = int(np.searchsorted(traj.index.to_numpy(), t)) - 1
        ref = drive.reference.at(np.array([traj.index[i]]))
        err = traj[["roll", "pitch", "heading"]].to_numpy()[i] - ref.rph[0]
        err[2] = (err[2] + 180.0) % 360.0 - 180.0
        j = int(np.searchsorted(result.gyro.index.to_numpy(), t)) - 1
        k = int(np.searchsorted(sd.index.to_numpy(), t)) - 1
        out.setdefault("pva_before", []).append(
            [float(traj.index[i])] + traj[["lat", "lon", "alt", "VN", "VE", "VD", "roll", "pitch",
                                           "heading"]].to_numpy()[i].tolist())
        out["rph_error_deg"].append(err.tolist())
        out["vel_error_m_s"].append(
            (traj[["VN", "VE", "VD"]].to_numpy()[i] - ref.vel_ned[0]).tolist())
        out["vel_sd_m_s"].append(sd[["VN", "VE", "VD"]].to_numpy()[k].tolist())
        out["gyro_bias_deg_h"].append(np.degrees(result.gyro.to_numpy()[j] * 3600.0).tolist())
        out["accel_bias_m_s2"].append(result.accel.to_numpy()[j].tolist())
        out["rph_sd_deg"].append(sd[["roll", "pitch", "heading"]].to_numpy()[k].tolist())
        out["gyro_bias_sd_deg_h"].append(
            np.degrees(result.gyro_sd.to_numpy()[k] * 3600.0).tolist())
        out["accel_bias_sd_m_s2"].append(result.accel_sd.to_numpy()[k].tolist())
    return out


def main(argv: list[str] | None = None) -> int:
    import pyins

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--write", action="store_true", help=f"write {REFERENCE_JSON}")
    parser.add_argument("--inputs", nargs="+", default=["raw", "onavdata"],
                        choices=["raw", "onavdata"])
    parser.add_argument("--modes", nargs="+", default=["position", "position_velocity"],
                        choices=["position", "position_velocity"])
    parser.add_argument("--lever-arm", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"),
                        help="IMU to antenna, body frame, m (default: none)")
    args = parser.parse_args(argv)

    drive = load_n380()
    duration = float(drive.imu.time[-1] - drive.imu.time[0])
    from importlib.metadata import version

    out = {"pyins_version": pyins.__version__, "python_ins_distribution": version("python-ins"),
           "dataset": SHORTNAME,
           "outage_starts_s_after_first_epoch": list(OUTAGE_STARTS),
           "outage_duration_s": OUTAGE_DURATION, "drive_duration_s": duration,
           "settings": {"gyro": GYRO, "accel": ACCEL, "position_sd_m": POSITION_SD,
                        "velocity_sd_m_s": VELOCITY_SD, "initial": INIT, "lever_arm_m": [0, 0, 0],
                        "time_step_s": 0.1},
           "initial_error": initial_error(),
           "issue_figures_m": {"position": [85, 6.6, 18], "position_velocity": [40, 5.2, 15.4]},
           "runs": {}}
    for source in args.inputs:
        increments, gnss, pva0 = raw_inputs(drive) if source == "raw" else _onavdata_inputs()
        for velocity in [m == "position_velocity" for m in args.modes]:
            result, wall = run_pyins(increments, gnss, pva0, velocity=velocity,
                                     lever_arm=args.lever_arm)
            traj = result.trajectory
            errors = max_outage_errors(traj.index.to_numpy(), traj["lat"].to_numpy(),
                                       traj["lon"].to_numpy(), drive.reference, drive.t0)
            mode = "position_velocity" if velocity else "position"
            run = {"max_horizontal_error_m": errors, "wall_s": wall,
                   "x_real_time": duration / wall}
            if args.lever_arm is not None:
                mode += "/lever_arm"
                run.update(lever_arm_m=list(args.lever_arm),
                           states_at_outages=states_at_outages(result, drive))
            out["runs"][f"{source}/{mode}"] = run
            print(f"pyins {pyins.__version__} {source:8s} {mode:17s} max horizontal error per "
                  f"outage: {', '.join(f'{e:6.1f}' for e in errors)} m   wall {wall:5.1f} s "
                  f"({duration / wall:5.1f}x real time)", flush=True)
    print("the pyins figures the comparison set out to match: position 85, 6.6, ~18 m; "
          "position+velocity 40, 5.2, 15.4 m")
    if args.write:
        if REFERENCE_JSON.exists():  # keep the runs of the inputs not run now
            kept = json.loads(REFERENCE_JSON.read_text())["runs"]
            out["runs"] = {**{k: v for k, v in kept.items() if k not in out["runs"]}, **out["runs"]}
        REFERENCE_JSON.parent.mkdir(exist_ok=True)
        REFERENCE_JSON.write_text(json.dumps(out, indent=1) + "\n")
        print(f"wrote {REFERENCE_JSON}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
