"""The onavdata HGuide n380 car drive ("2021-04-27 HGuide n380 Car Hill Driving") in stochmod's
conventions, loaded from the installed ``onavdata`` package (its data carry no licence: nothing
of it is copied into the repository), and stochmod's filter on it with pyins' settings: what
tests/nav/test_n380.py runs, and the scripts of studies/ that compare the two filters on it
(they put this folder on ``sys.path``).

What onavdata ships (five zipped CSVs on the unit's system clock ``SystemTov``, s):

- ``n380-imu-nav.csv``: ``DeltaTheta[0..2]`` (rad) and ``DeltaVelocity[0..2]`` (m/s) at ~100 Hz,
  in the IMU frame; the increments cover the interval that ends at the time stamp. onavdata's
  meta file ``n380-meta.toml`` gives the rotation ``Rsensor2body`` to the case frame, which the
  dataset description calls x forward / y right / z down (at rest the body z specific force is
  -9.82 m/s^2). ``onavdata.get_data`` also rounds the time to 0.01 s and multiplies the
  increments by 100 (a nominal 100 Hz) to give rates; this loader does neither: it keeps the
  increments and the true time stamps (mean step 9.9997 ms).
- ``n380-gnss-pvt.csv``: 1 Hz fixes, ``GnssLatitude/Longitude`` (rad), ellipsoidal height (m),
  NED velocity (m/s), ``GnssStdvLat/Lon/Alt`` (m); ``SystemTov`` is the time of validity (it maps
  to ``GpsTov`` with the same offset as the INS solution's rows).
- ``n380-position/velocity/attitude.csv``: the unit's own INS/GNSS solution at the IMU times
  (lat/lon in rad, height, NED velocity, ``EulerAttitude`` roll/pitch/heading in rad), the
  reference trajectory.

Rows are kept where ``InsGnssBIT.InsMode`` is 4 (the meta's ``keep-rows-where``: the unit's
navigation mode), i.e. from 41.27 s to 710.69 s, 669.4 s of driving. The description places
the antenna on the roof rack above the rear-right passenger without a measured lever arm.
"""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path

import attrs
import numpy as np

from stochmod.nav.emulate import Trajectory
from stochmod.nav.records import GnssData, ImuData

__all__ = [
    "ENSEMBLE_JSON",
    "ENSEMBLE_VELOCITY_JSON",
    "ENSEMBLE_VELOCITY_LEVER_ARM_JSON",
    "LEVER_ARM",
    "PEER_JSON",
    "SHORTNAME",
    "N380Drive",
    "OUTAGE_DURATION",
    "OUTAGE_STARTS",
    "in_outage",
    "load_cache",
    "load_n380",
    "max_outage_errors",
    "outage_windows",
    "pyins_example_models",
    "pyins_velocity_jacobian",
    "run_stochmod",
    "onavdata_missing_reason",
    "states_before_outages",
    "stochmod_runs",
    "summary",
    "verdict",
    "write_navigate_csvs",
]

SHORTNAME = "2021-04-27 HGuide n380 Car Hill Driving"
NAV_MODE = 4

#: pyins' runs on the drive from the reference start perturbed by its ``generate_pva_error(...,
#: rng=0)``, position and position + velocity updates (written by studies/nav_pyins_n380.py).
PEER_JSON = Path(__file__).parent / "reference" / "nav_pyins_n380.json"
#: pyins' runs from the seeded starts of the ensemble, position updates, lever arm `LEVER_ARM`
#: fixed (written by studies/nav_n380_ensemble.py): per seed the start, the outage errors and
#: the state before each outage.
ENSEMBLE_JSON = Path(__file__).parent / "reference" / "nav_pyins_n380_ensemble.json"
#: The same for position + velocity updates without a lever arm, the settings of the
#: single-start comparison (studies/nav_n380_ensemble.py --velocity).
ENSEMBLE_VELOCITY_JSON = (Path(__file__).parent / "reference"
                          / "nav_pyins_n380_ensemble_velocity.json")
#: The same for position + velocity updates with the lever arm `LEVER_ARM` fixed
#: (studies/nav_n380_ensemble.py --velocity --lever-arm).
ENSEMBLE_VELOCITY_LEVER_ARM_JSON = (Path(__file__).parent / "reference"
                                    / "nav_pyins_n380_ensemble_velocity_lever_arm.json")
#: The IMU-to-antenna lever arm fitted from the drive's data (body x/y/z, m;
#: docs/navigation.md, "Real drive").
LEVER_ARM = (-1.3, 0.0, 0.0)


def onavdata_missing_reason() -> str | None:
    """Why the drive cannot be loaded here (None when it can): the reason a test skips with."""
    try:
        import onavdata  # noqa: F401
        import pandas  # noqa: F401
    except ImportError as exc:
        return f"onavdata is not installed ({exc}); pip install -e '.[test]'"
    return None


@attrs.frozen
class N380Drive:
    """IMU increments, GNSS fixes and the reference trajectory (the n380's own INS solution at
    the IMU times: deg, m, m/s, roll/pitch/heading deg) of the drive, in stochmod's conventions."""

    imu: ImuData
    gnss: GnssData
    reference: Trajectory

    @property
    def t0(self) -> float:
        """The first epoch (first IMU time in navigation mode), s on the system clock."""
        return float(self.imu.time[0])


def _paths() -> tuple[dict[str, Path], dict]:
    import onavdata.onavdata as od
    import toml

    entry = od.get_shortname_dict(od.config)[SHORTNAME]["paths"]
    files = {}
    for name in entry["data"]:
        zipped = name + ".zip"
        files[os.path.basename(name).removeprefix("n380-").removesuffix(".csv")] = Path(
            zipped if os.path.isfile(zipped) else name
        )
    return files, toml.load(entry["meta"])


def _read(path: Path):  # noqa: ANN202 (pandas is optional)
    import pandas as pd

    frame = pd.read_csv(path, skipinitialspace=True)
    frame.columns = [c.strip() for c in frame.columns]
    frame = frame[frame["InsGnssBIT.InsMode"] == NAV_MODE]
    return frame.drop_duplicates("SystemTov").sort_values("SystemTov")


def load_n380() -> N380Drive:
    """Load the drive from the installed onavdata package.

    Returns
    -------
    N380Drive
        ``imu``: increments (``kind="increment"``, rad and m/s over the interval ending at the
        stamp, body x fwd / y right / z down); ``gnss``: fixes with NED velocity and position
        sd; ``reference``: the unit's INS solution. Times are on the unit's clock (s).
    """
    files, meta = _paths()
    rotation = np.asarray(meta["Rsensor2body"]["AngleRate"], dtype=float)
    if not np.allclose(rotation, np.asarray(meta["Rsensor2body"]["Accel"], dtype=float)):
        raise ValueError("n380 meta: gyro and accelerometer frames differ; update the loader")

    imu = _read(files["imu-nav"])
    dtheta = imu[[f"DeltaTheta[{i}]" for i in range(3)]].to_numpy() @ rotation.T
    dv = imu[[f"DeltaVelocity[{i}]" for i in range(3)]].to_numpy() @ rotation.T
    imu_time = imu["SystemTov"].to_numpy()
    imu_data = ImuData(imu_time, dtheta, dv, kind="increment")

    gnss = _read(files["gnss-pvt"])
    gnss = gnss[(gnss["SystemTov"] >= imu_time[0]) & (gnss["SystemTov"] <= imu_time[-1])]
    gnss_data = GnssData(
        time=gnss["SystemTov"].to_numpy(),
        lat=np.rad2deg(gnss["GnssLatitude"].to_numpy()),
        lon=np.rad2deg(gnss["GnssLongitude"].to_numpy()),
        height=gnss["GnssAltitudeAboveEllipsoid"].to_numpy(),
        vel_ned=gnss[["GnssVelocityN", "GnssVelocityE", "GnssVelocityD"]].to_numpy(),
        sd=gnss[["GnssStdvLat", "GnssStdvLon", "GnssStdvAlt"]].to_numpy(),
        sd_vel=gnss[["GnssStdvN", "GnssStdvE", "GnssStdvD"]].to_numpy(),
    )

    pos, vel, att = (_read(files[k]).set_index("SystemTov")
                     for k in ("position", "velocity", "attitude"))
    common = pos.index.intersection(vel.index).intersection(att.index)
    pos, vel, att = pos.loc[common], vel.loc[common], att.loc[common]
    reference = Trajectory(
        time=common.to_numpy(dtype=float),
        lat=np.rad2deg(pos["Latitude"].to_numpy()),
        lon=np.rad2deg(pos["Longitude"].to_numpy()),
        height=pos["AltitudeAboveEllipsoid"].to_numpy(),
        vel_ned=vel[[f"VelocityNED[{i}]" for i in range(3)]].to_numpy(),
        rph=np.rad2deg(att[[f"EulerAttitude[{i}]" for i in range(3)]].to_numpy()),
    )
    return N380Drive(imu=imu_data, gnss=gnss_data, reference=reference)


def write_navigate_csvs(drive: N380Drive, directory: str | Path) -> tuple[Path, Path]:
    """Write the drive as the ``stochmod navigate`` inputs: ``imu.csv`` (increments) and
    ``gnss.csv`` (position, velocity, sd); returns their paths."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    imu_path, gnss_path = directory / "imu.csv", directory / "gnss.csv"
    imu = drive.imu
    np.savetxt(
        imu_path, np.column_stack([imu.time, imu.gyro, imu.accel]), delimiter=",", fmt="%.17g",
        header="time,dtheta_x,dtheta_y,dtheta_z,dv_x,dv_y,dv_z", comments="",
    )
    g = drive.gnss
    np.savetxt(
        gnss_path, np.column_stack([g.time, g.lat, g.lon, g.height, g.vel_ned, g.sd]),
        delimiter=",", fmt="%.17g", header="time,lat,lon,height,vn,ve,vd,sd_n,sd_e,sd_d",
        comments="",
    )
    return imu_path, gnss_path


#: The three 60 s GNSS outages of the comparison: starts in s after the first epoch
#: (``N380Drive.t0``); the car moves in all three.
OUTAGE_STARTS = (151.9, 279.2, 422.0)
OUTAGE_DURATION = 60.0


def outage_windows(t0: float) -> list[tuple[float, float]]:
    """The outages as (start, end) on the unit's clock."""
    return [(t0 + s, t0 + s + OUTAGE_DURATION) for s in OUTAGE_STARTS]


def in_outage(time: np.ndarray, t0: float) -> np.ndarray:
    """True where `time` falls inside one of the outages (the fixes to withhold)."""
    time = np.asarray(time, dtype=float)
    mask = np.zeros(time.shape, dtype=bool)
    for start, end in outage_windows(t0):
        mask |= (time >= start) & (time < end)
    return mask


def max_outage_errors(time: np.ndarray, lat: np.ndarray, lon: np.ndarray,
                      reference: Trajectory, t0: float) -> list[float]:
    """Maximum horizontal error (m) of a solution (deg) in each of the drive's outages."""
    from stochmod.nav.study import max_outage_errors as worst

    return worst(reference, time, lat, lon, outage_windows(t0)).tolist()


def pyins_example_models(freq: float = 100.0):
    """pyins' real-data example MEMS model (studies/nav_pyins_n380.py) as stochmod models: the
    defaults of ``stochmod navigate``. Gyro: white noise 1 deg/sqrt(h) + random walk
    30 deg/h/sqrt(h), turn-on bias 300 deg/h; accelerometer: 0.1/60 m/s/sqrt(s) + 0.01/60
    m/s^2/sqrt(s), turn-on bias 0.05 m/s^2. Returns ``(gyro_model, accel_model, gyro_bias_sd,
    accel_bias_sd)`` (models bound to `freq`, sigmas in SI)."""
    from stochmod.cli.navigate import DEFAULT_ACCEL_BIAS_SD, DEFAULT_GYRO_BIAS_SD, default_models

    gyro, accel = default_models(freq)
    return gyro, accel, DEFAULT_GYRO_BIAS_SD, DEFAULT_ACCEL_BIAS_SD


@contextlib.contextmanager
def pyins_velocity_jacobian():
    """Within the block, stochmod's GNSS velocity measurement takes pyins 1.0.1's Jacobian:
    the antenna velocity ``v + C (w x l)`` is predicted as before, but its derivative keeps only
    the IMU velocity error (``NedVelocity.compute_matrices`` calls
    ``ned_velocity_error_jacobian(pva)`` without the lever arm, so pyins' ``[v x]`` on its
    attitude error, stochmod's zero, lacks ``[(C (w x l)) x]``, and pyins has no gyro-bias
    column). For comparisons only (docs/navigation_real_drive.md, "With velocity updates and
    the lever arm"): the full Jacobian is the derivative of the prediction
    (tests/nav/test_lever_arm.py)."""
    from stochmod.nav.measurements import GnssVelocity

    evaluate, rate = GnssVelocity.evaluate, GnssVelocity.rate_jacobian

    def truncated(self, snap):
        y, H, R = evaluate(self, snap)
        H[:, 6:9] = 0.0
        return y, H, R

    GnssVelocity.evaluate = truncated
    GnssVelocity.rate_jacobian = lambda self, snap: None
    try:
        yield
    finally:
        GnssVelocity.evaluate, GnssVelocity.rate_jacobian = evaluate, rate


def run_stochmod(drive: N380Drive, *, velocity: bool, gyro=None, accel=None,
                 gyro_bias_sd: float | None = None, accel_bias_sd: float | None = None,
                 initial_error: dict | None = None, gate: float | None = None,
                 receiver_sd: bool = False, lever_arm=(0.0, 0.0, 0.0), lever_arm_sd=0.0,
                 dt_filter: float = 0.1, error_model: str = "psi"):
    """stochmod's loosely-coupled filter on the drive with the three outages.

    Defaults: pyins' example models (:func:`pyins_example_models`), GNSS sd 1 m and 0.3 m/s,
    initial sd 5 m, 0.5 m/s, 0.2/0.2/1 deg, covariance step 0.1 s, no lever arm, no gating:
    the settings of the pyins run; ``receiver_sd=True`` uses the receiver's own per-fix position
    and velocity sd instead (what ``stochmod navigate`` does with the CSVs). `initial_error`
    (``{"ned": m, "vel": m/s, "rph": deg}``) perturbs the reference start as pyins' run does.
    `lever_arm` (body x/y/z, m) is the IMU-to-antenna lever arm; ``lever_arm_sd`` > 0 (m, one or
    three values) makes it three constant states started there (``stochmod navigate
    --lever-arm-sd``); `error_model` is the filter's (:class:`stochmod.nav.LooselyCoupledFilter`).
    Returns the NavResult.
    """
    from stochmod.nav import InitialState, LooselyCoupledFilter

    g_default, a_default, gb, ab = pyins_example_models()
    gyro = g_default if gyro is None else gyro
    accel = a_default if accel is None else accel
    gyro_bias_sd = gb if gyro_bias_sd is None else gyro_bias_sd
    accel_bias_sd = ab if accel_bias_sd is None else accel_bias_sd
    ref, imu = drive.reference, drive.imu
    err = initial_error or {"ned": [0, 0, 0], "vel": [0, 0, 0], "rph": [0, 0, 0]}
    from stochmod.nav.earth import principal_radii

    r_n, r_e = principal_radii(np.radians(ref.lat[0]))
    lat0 = ref.lat[0] + np.degrees(err["ned"][0] / (r_n + ref.height[0]))
    lon0 = ref.lon[0] + np.degrees(
        err["ned"][1] / ((r_e + ref.height[0]) * np.cos(np.radians(ref.lat[0]))))
    init = InitialState(lat0, lon0, ref.height[0] - err["ned"][2], ref.vel_ned[0] + err["vel"],
                        ref.rph[0] + np.asarray(err["rph"]), sd_position=5.0, sd_velocity=0.5,
                        sd_attitude=(0.2, 0.2, 1.0))
    g = drive.gnss
    gnss = GnssData(g.time, g.lat, g.lon, g.height, vel_ned=g.vel_ned if velocity else None,
                    sd=g.sd if receiver_sd else None,
                    sd_vel=g.sd_vel if receiver_sd and velocity else None)
    flt = LooselyCoupledFilter(gyro, accel, dt_filter=dt_filter, gyro_bias_sd=gyro_bias_sd,
                               accel_bias_sd=accel_bias_sd, gate=gate, gnss_sd=(1.0, 1.0, 1.0),
                               gnss_vel_sd=0.3, lever_arm=lever_arm, lever_arm_sd=lever_arm_sd,
                               error_model=error_model)
    outages = [(s, OUTAGE_DURATION) for s in OUTAGE_STARTS]
    return flt.run(imu.time, imu.gyro, imu.accel, kind=imu.kind, gnss=gnss, init=init,
                   outages=outages)


def load_cache(path: Path = ENSEMBLE_JSON) -> dict:
    """The cached pyins runs in `path` (``{"runs": {seed: {...}}}``), empty when there are
    none."""
    if path.exists():
        return json.loads(path.read_text())
    return {"runs": {}}


def stochmod_runs(drive, cache: dict, **kwargs) -> dict[str, tuple[np.ndarray, dict]]:
    """stochmod's per-outage maximum horizontal error (m) and state before each outage
    (:func:`states_before_outages`) for every cached seed, started from the same initial error
    as pyins' run of that seed, with the cache's updates (``mode``: ``"position"`` or
    ``"position_velocity"``) and lever arm (``lever_arm_m``). `kwargs` go to ``run_stochmod``."""
    out = {}
    velocity = cache.get("mode", "position") == "position_velocity"
    lever_arm = tuple(cache.get("lever_arm_m", LEVER_ARM))
    for seed, run in cache["runs"].items():
        result = run_stochmod(drive, velocity=velocity, initial_error=run["initial_error"],
                              lever_arm=lever_arm, **kwargs)
        out[seed] = (np.array(max_outage_errors(result.time, result.lat, result.lon,
                                                drive.reference, drive.t0)),
                     states_before_outages(result, drive))
    return out


def states_before_outages(result, drive) -> dict[str, list]:
    """stochmod's state at the last epoch before each outage, in the units and keys of
    ``states_at_outages`` of studies/nav_pyins_n380.py: attitude and velocity error against the
    reference with their 1-sigma, and the estimated sensor errors per axis (gyro deg/h, accel
    m/s^2)."""
    out: dict[str, list] = {k: [] for k in ("rph_error_deg", "vel_error_m_s", "rph_sd_deg",
                                            "vel_sd_m_s", "gyro_bias_deg_h", "accel_bias_m_s2")}
    for start in OUTAGE_STARTS:
        t = drive.t0 + start
        i = int(np.searchsorted(result.time, t)) - 1
        ref = drive.reference.at(result.time[i:i + 1])
        err = result.rph[i] - ref.rph[0]
        err[2] = (err[2] + 180.0) % 360.0 - 180.0
        e = int(np.searchsorted(result.epoch_time, t)) - 1
        out.setdefault("pva_before", []).append(
            [float(result.time[i]), float(result.lat[i]), float(result.lon[i]),
             float(result.height[i]), *result.vel_ned[i].tolist(), *result.rph[i].tolist()])
        out["rph_error_deg"].append(err.tolist())
        out["vel_error_m_s"].append((result.vel_ned[i] - ref.vel_ned[0]).tolist())
        out["rph_sd_deg"].append(result.sd_rph[i].tolist())
        out["vel_sd_m_s"].append(result.sd_velocity[i].tolist())
        out["gyro_bias_deg_h"].append((np.degrees(result.sensor_errors[e, :3]) * 3600).tolist())
        out["accel_bias_m_s2"].append(result.sensor_errors[e, 3:].tolist())
    return out


def summary(ours: dict[str, np.ndarray], cache: dict) -> dict[str, np.ndarray]:
    """Per-outage mean, sd and standard error of both filters and of the paired difference
    (stochmod - pyins) over the seeds both have."""
    seeds = sorted(ours, key=int)
    a = np.array([ours[s] for s in seeds])
    b = np.array([cache["runs"][s]["max_horizontal_error_m"] for s in seeds])
    n = len(seeds)
    out = {"n": np.array(n)}
    for name, x in (("stochmod", a), ("pyins", b), ("difference", a - b)):
        sd = x.std(axis=0, ddof=1) if n > 1 else np.full(x.shape[1], np.nan)
        out[f"{name}_mean"], out[f"{name}_sd"], out[f"{name}_se"] = x.mean(0), sd, sd / np.sqrt(n)
    return out


def verdict(s: dict[str, np.ndarray], margin: float = 2.0) -> list[str]:
    """Per outage, from the paired difference stochmod - pyins: ``"better"`` when its mean is
    below zero by more than `margin` standard errors, ``"worse"`` when above by more, else
    ``"not resolved"`` (no difference beyond the ensemble's standard error)."""
    mean, se = s["difference_mean"], s["difference_se"]
    return ["better" if m + margin * e < 0 else "worse" if m - margin * e > 0
            else "not resolved" for m, e in zip(mean, se)]
