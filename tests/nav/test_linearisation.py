"""The covariance step's linearisation point and the time a fix refers to (stochmod.nav.filter
notes).

The exact transition of the error state over a step is the time-ordered exponential of the
time-varying F along the trajectory; the filter freezes F over the step. Frozen at the middle
(the midpoint rule, the first Magnus term) the transition over a fixed interval converges as
dt^2; frozen at the end, as dt. Checked here against a fine-step product of the filter's own F
along a known trajectory (a level turn at 15 m/s and 17 deg/s), so the test fails for the end
point."""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import expm

from stochmod.nav import LooselyCoupledFilter, frames
from stochmod.nav.filter import error_dynamics, midpoint_pva

from .test_filter import ACCEL, GYRO

SPEED, RATE, LAT0, HEIGHT, G, RADIUS = 15.0, 0.3, 0.6, 100.0, 9.8, 6.371e6  # m/s, rad/s, rad, m


def _pva(t: float) -> tuple:
    """The turn at time t: (lat rad, height m, NED velocity m/s, quaternion of heading RATE t)."""
    th = RATE * t
    return (LAT0 + SPEED * math.sin(th) / (RATE * RADIUS), HEIGHT,
            (SPEED * math.cos(th), SPEED * math.sin(th), 0.0),
            (math.cos(th / 2), 0.0, 0.0, math.sin(th / 2)))


def _specific_force(t0: float, t1: float) -> np.ndarray:
    """Mean NED specific force over [t0, t1] (the centripetal acceleration less gravity), m/s^2;
    the filter takes the step's mean the same way (its velocity increment over the step)."""
    dv = np.array([SPEED * (math.cos(RATE * t1) - math.cos(RATE * t0)),
                   SPEED * (math.sin(RATE * t1) - math.sin(RATE * t0)), -G * (t1 - t0)])
    return dv / (t1 - t0)


def _F(state: tuple, f_n: np.ndarray) -> np.ndarray:
    lat, h, v, q = state
    return error_dynamics(lat, h, v, frames.quat_to_dcm(np.array(q)), f_n)


def _transition(n: int, total: float, where: str) -> np.ndarray:
    """Phi over [0, total] from n steps with F frozen at each step's `where` ("mid" or "end")."""
    h = total / n
    Phi = np.eye(15)
    for i in range(n):
        a, b = _pva(i * h), _pva((i + 1) * h)
        at = midpoint_pva(a, b) if where == "mid" else b
        Phi = expm(_F(at, _specific_force(i * h, (i + 1) * h)) * h) @ Phi
    return Phi


def test_midpoint_linearisation_is_second_order_and_the_end_point_first():
    total = 1.6
    # reference: the product over 1 ms sub-steps of the exact transitions at their middles
    # (its own error ~ (1 ms / 50 ms)^2 = 4e-4 of the finest step's below)
    n_ref = 1600
    d = total / n_ref
    ref = np.eye(15)
    for i in range(n_ref):
        tm = (i + 0.5) * d
        f = np.array([-SPEED * RATE * math.sin(RATE * tm), SPEED * RATE * math.cos(RATE * tm), -G])
        ref = expm(_F(_pva(tm), f) * d) @ ref
    steps = (4, 8, 16, 32)  # 0.4 s down to 0.05 s
    err = {w: np.array([np.abs(_transition(n, total, w) - ref).max() for n in steps])
           for w in ("mid", "end")}
    order = {w: np.log2(e[:-1] / e[1:]) for w, e in err.items()}
    # measured: mid 2.00, 2.00, 2.00; end 1.05, 1.03, 1.01 (errors 0.062 .. 9.6e-4 and
    # 0.80 .. 0.093)
    assert np.all(np.abs(order["mid"] - 2.0) < 0.1), order
    assert np.all(np.abs(order["end"] - 1.0) < 0.1), order
    # at the filter's usual 0.1 s step the midpoint's error is ~50x smaller
    assert err["mid"][2] < err["end"][2] / 20


def test_midpoint_pva_is_the_state_in_the_middle_to_second_order():
    for h in (0.2, 0.1):
        lat, hgt, v, q = midpoint_pva(_pva(0.0), _pva(h))
        lat_m, _, v_m, q_m = _pva(h / 2)
        # velocity on the chord of the turn: |v_mid| = S cos(RATE h / 2), error S (RATE h)^2 / 8
        assert np.allclose(v, v_m, atol=SPEED * (RATE * h) ** 2 / 8 * 1.01)
        assert np.allclose(q, q_m, atol=1e-12)  # the normalised mean is the geodesic midpoint
        # latitude on the chord likewise: S RATE h^2 / (8 R) rad
        assert abs(lat - lat_m) < SPEED * RATE * h ** 2 / (8 * RADIUS) * 1.01
        assert hgt == HEIGHT


def test_a_fix_between_imu_epochs_measures_the_error_at_its_own_time():
    """A vehicle at rest, estimated moving at DV (m/s) with its position right at the filter
    epoch t_k: its interpolated position at a fix LAG before t_k is off by -LAG DV. The
    measurement matrix at the fix's own time, H (I - lag F), lets an exact fix there reveal the
    velocity error, and the feedback removes it (read as a position error at t_k, which the
    covariance says is known, the same innovation would leave the velocity wrong)."""
    import stochmod.nav.filter as nf
    from stochmod.nav import earth
    from stochmod.nav.measurements import GnssPosition

    lat, lon, hgt = 37.3, -122.1, 40.0
    dv, h, lag = np.array([1.0, -0.5, 0.2]), 0.01, 0.009  # m/s, s, s
    flt = LooselyCoupledFilter(GYRO, ACCEL)
    init = nf.InitialState(lat, lon, hgt, dv, (0.0, 0.0, 30.0))
    z = np.zeros((1, 3))
    run = nf._Run(flt, nf._Sensors(flt.models, h, 0.0, 0.0), init, np.array([0.0, h]),
                  np.array([h]), z, z, z, z, [], None)
    rn, re = (float(r) for r in earth.principal_radii(np.radians(lat)))
    # the state one IMU step earlier, moving at the estimated velocity
    prev = (np.radians(lat) - dv[0] * h / (rn + hgt),
            np.radians(lon) - dv[1] * h / ((re + hgt) * np.cos(np.radians(lat))),
            hgt + dv[2] * h, tuple(dv))
    nf._fill_error_dynamics(run._F, np.radians(lat), hgt, tuple(dv), (0.0, 0.0, -9.8))
    run.P = np.diag(np.r_[[1e-12] * 3, [1.0] * 3, [1e-12] * 3, [1e-12] * (run.n - 9)])
    run.t_prev, run.t_now = 0.0, h
    run.t_meas = h - lag
    run._update(GnssPosition(lat, lon, hgt, 1e-5), run._snapshot(h - lag, prev, np.zeros(3)))
    # the residual (measured 1.2e-6 m/s): R / (lag^2 sigma_v^2) of it and the O(lag^2) terms
    # of the transition over the lag
    np.testing.assert_allclose(np.array(run.mech.v), 0.0, atol=1e-5)


def test_the_velocity_of_a_fix_is_predicted_from_the_state_its_position_corrected():
    """A vehicle at rest, estimated moving at DV (m/s) for T seconds, so its position error
    DV T is fully correlated with its velocity error. An exact position fix at LAG before the
    filter epoch t_k reveals both, and the feedback corrects the state at t_k; the velocity of
    the same fix is then predicted from the corrected state, interpolated between t_k-1 and t_k
    as the fix falls inside the IMU interval: its innovation is (almost) zero. Interpolated from
    the uncorrected state at t_k-1, it would be (1 - (t_m - t_k-1) / h) DV = 0.9 DV, and the
    update would push the velocity off by that much of its gain."""
    import stochmod.nav.filter as nf
    from stochmod.nav import earth
    from stochmod.nav.measurements import GnssPosition, GnssVelocity

    lat, lon, hgt = 37.3, -122.1, 40.0
    dv, h, lag, T = np.array([1.0, -0.5, 0.2]), 0.01, 0.009, 10.0  # m/s, s, s, s
    rn, re = (float(r) for r in earth.principal_radii(np.radians(lat)))

    def moved(d: np.ndarray) -> tuple[float, float, float]:
        """The truth offset by the NED error `d` (m): lat, lon (rad), height (m)."""
        return (np.radians(lat) + d[0] / (rn + hgt),
                np.radians(lon) + d[1] / ((re + hgt) * np.cos(np.radians(lat))), hgt - d[2])

    at_k = moved(dv * T)
    flt = LooselyCoupledFilter(GYRO, ACCEL)
    init = nf.InitialState(np.degrees(at_k[0]), np.degrees(at_k[1]), at_k[2], dv,
                           (0.0, 0.0, 30.0))
    z = np.zeros((1, 3))
    run = nf._Run(flt, nf._Sensors(flt.models, h, 0.0, 0.0), init, np.array([0.0, h]),
                  np.array([h]), z, z, z, z, [], None)
    nf._fill_error_dynamics(run._F, at_k[0], at_k[2], tuple(dv), (0.0, 0.0, -9.8))
    # velocity error sd 1 m/s carried over T seconds: position sd T, correlation ~1
    P = np.diag(np.r_[[T * T + 1e-4] * 3, [1.0] * 3, [1e-12] * 3, [1e-12] * (run.n - 9)])
    for i in range(3):
        P[i, 3 + i] = P[3 + i, i] = T
    run.P = P
    run.t_prev, run.t_now = 0.0, h
    before = (*moved(dv * (T - h)), tuple(dv))  # the state at t_k-1
    run._epoch_updates([(h - lag, GnssPosition(lat, lon, hgt, 1e-3)),
                        (h - lag, GnssVelocity(np.zeros(3), 0.3))], before, np.zeros(3), h,
                       np.zeros(6))
    y_vel = np.array(run.innov["gnss_velocity"][0][1:])
    # the velocity left by the position fix (measured below 1e-3 m/s) against 0.9 DV
    np.testing.assert_allclose(y_vel, 0.0, atol=0.01)
    np.testing.assert_allclose(np.array(run.mech.v), 0.0, atol=0.01)
