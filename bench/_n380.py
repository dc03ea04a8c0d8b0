"""The onavdata HGuide n380 car drive ("2021-04-27 HGuide n380 Car Hill Driving") in stochmod's
conventions, loaded from the installed ``onavdata`` package (its data carry no licence: nothing
of it is copied into the repository).

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

import os
from pathlib import Path

import attrs
import numpy as np

from stochmod.nav.emulate import Trajectory
from stochmod.nav.records import GnssData, ImuData

__all__ = [
    "SHORTNAME",
    "N380Drive",
    "load_n380",
    "onavdata_missing_reason",
    "write_navigate_csvs",
]

SHORTNAME = "2021-04-27 HGuide n380 Car Hill Driving"
NAV_MODE = 4


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

    pos, vel, att = (_read(files[k]).set_index("SystemTov") for k in ("position", "velocity", "attitude"))
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
        delimiter=",", fmt="%.17g", header="time,lat,lon,height,vn,ve,vd,sd_n,sd_e,sd_d", comments="",
    )
    return imu_path, gnss_path
