"""Free-inertial mechanisation on a trajectory and ideal IMU made by pyins' simulator (not by
stochmod): 10 min at 100 Hz, rates and increments.

pyins (``python-ins``, test extra) builds the trajectory from a sinusoidal NED velocity and its
exact IMU (rotation and position splines). Horizontally stochmod must stay within centimetres.
Vertically the two libraries' gravity models differ (pyins: Somigliana times ``1 - 2h/a``;
stochmod: Gonzalez Table II) by ~7e-6 m/s^2; the height error must be exactly what that
difference drives through the unstable vertical channel, ``dh'' = (2 g / R) dh - dg``,
integrated independently here. Through the Coriolis term that vertical error moves the
horizontal position by 1-2 cm in ten minutes: with pyins' own gravity model
(``strapdown(..., gravity=)``) the mechanisation is within a millimetre from increments, as
pyins' own integrator is on its own data.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from stochmod.nav import earth, strapdown

pyins = pytest.importorskip("pyins", reason="pyins (python-ins) is in the test extra")

DT, DURATION = 0.01, 600.0
LLA0 = [58.0, 56.0, 150.0]


@pytest.fixture(scope="module", params=[pytest.param("rate", marks=pytest.mark.slow), "increment"])
def run(request):
    kind = request.param
    traj, imu = pyins.sim.generate_sine_velocity_motion(
        DT, DURATION, LLA0, [10.0, -5.0, 0.0], velocity_change_amplitude=[3.0, 2.0, 0.5],
        velocity_change_period=60.0, sensor_type=kind)
    first = traj.iloc[0]
    result = strapdown(
        imu.index.to_numpy(), imu[pyins.util.GYRO_COLS].to_numpy(),
        imu[pyins.util.ACCEL_COLS].to_numpy(), kind=kind, lat=first["lat"], lon=first["lon"],
        height=first["alt"], vel_ned=first[pyins.util.VEL_COLS].to_numpy(dtype=float),
        rph=first[pyins.util.RPH_COLS].to_numpy(dtype=float))
    return traj, result


def test_horizontal_position_within_centimetres(run) -> None:
    traj, result = run
    lat, h = traj["lat"].to_numpy(), traj["alt"].to_numpy()
    r_n, r_e = earth.principal_radii(np.radians(lat))
    north = np.radians(result.lat - lat) * (r_n + h)
    east = np.radians(result.lon - traj["lon"].to_numpy()) * (r_e + h) * np.cos(np.radians(lat))
    assert traj.index[-1] - traj.index[0] >= DURATION - 2 * DT
    assert np.hypot(north, east).max() < 0.03  # m after 10 min (distance travelled ~6.7 km)
    vel = result.vel_ned[:, :2] - traj[["VN", "VE"]].to_numpy()
    assert np.abs(vel).max() < 1e-3  # m/s
    heading = (result.rph[:, 2] - traj["heading"].to_numpy() + 180.0) % 360.0 - 180.0
    assert np.abs(heading).max() < 1e-4  # deg
    np.testing.assert_allclose(result.rph[:, :2], traj[["roll", "pitch"]].to_numpy(), atol=1e-4)


def test_height_error_is_the_gravity_model_difference(run) -> None:
    traj, result = run
    t, lat, h = traj.index.to_numpy(), traj["lat"].to_numpy(), traj["alt"].to_numpy()
    g_ours = earth.gravity_ned(np.radians(lat), h)[:, 2]
    dg = g_ours - pyins.earth.gravity(lat, h)
    assert 1e-6 < np.abs(dg).max() < 2e-5  # the two normal-gravity formulas, m/s^2
    r_n, r_e = earth.principal_radii(np.radians(lat))
    k = 2.0 * g_ours / np.sqrt((r_n + h) * (r_e + h))

    def rhs(s: float, y: np.ndarray) -> list[float]:
        return [y[1], np.interp(s, t, k) * y[0] - np.interp(s, t, dg)]

    predicted = solve_ivp(rhs, (t[0], t[-1]), [0.0, 0.0], t_eval=t, rtol=1e-9, atol=1e-12).y[0]
    observed = result.height - h
    assert np.abs(observed).max() > 1.0  # the effect is real and large
    np.testing.assert_allclose(observed, predicted, atol=0.01)  # and fully explained, to 1 cm


def _horizontal_error(traj, lat_deg: np.ndarray, lon_deg: np.ndarray) -> np.ndarray:
    lat, h = traj["lat"].to_numpy(), traj["alt"].to_numpy()
    r_n, r_e = earth.principal_radii(np.radians(lat))
    north = np.radians(lat_deg - lat) * (r_n + h)
    east = np.radians(lon_deg - traj["lon"].to_numpy()) * (r_e + h) * np.cos(np.radians(lat))
    return np.hypot(north, east)


def test_with_the_simulators_gravity_the_error_is_pyins_own() -> None:
    """Increments: with pyins' gravity the horizontal error after 10 min is pyins' own
    integrator's on the same data to within 0.5 mm (0.9 mm and 0.7 mm), the height error
    below a millimetre (the vertical channel no longer driven)."""
    traj, imu = pyins.sim.generate_sine_velocity_motion(
        DT, DURATION, LLA0, [10.0, -5.0, 0.0], velocity_change_amplitude=[3.0, 2.0, 0.5],
        velocity_change_period=60.0, sensor_type="increment")
    first = traj.iloc[0]
    result = strapdown(
        imu.index.to_numpy(), imu[pyins.util.GYRO_COLS].to_numpy(),
        imu[pyins.util.ACCEL_COLS].to_numpy(), kind="increment", lat=first["lat"],
        lon=first["lon"], height=first["alt"],
        vel_ned=first[pyins.util.VEL_COLS].to_numpy(dtype=float),
        rph=first[pyins.util.RPH_COLS].to_numpy(dtype=float),
        gravity=lambda lat, h: float(pyins.earth.gravity(np.degrees(lat), h)))
    ours = _horizontal_error(traj, result.lat, result.lon).max()
    theirs_traj = pyins.strapdown.Integrator(first, True).integrate(
        pyins.strapdown.compute_increments_from_imu(imu, "increment")).reindex(
        traj.index, method="nearest")
    theirs = _horizontal_error(traj, theirs_traj["lat"].to_numpy(),
                               theirs_traj["lon"].to_numpy()).max()
    assert ours < 2e-3 and abs(ours - theirs) < 5e-4, (ours, theirs)
    assert np.abs(result.height - traj["alt"].to_numpy()).max() < 1e-3
