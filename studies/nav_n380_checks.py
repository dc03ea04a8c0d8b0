"""Diagnostics behind docs/navigation.md "Real drive: the HGuide n380 and pyins".

Needs ``tests/nav/_n380.py`` (the onavdata loader) and the ``test`` extra. Prints:

1. ``fd``: the filter's transition over ``--steps`` IMU samples against central finite
   differences of the mechanisation itself, on the drive's increments from the reference state
   (at a stop, in turns, at speed), for every navigation and sensor state;
2. ``lever``: a least-squares fit of the GNSS fixes to the unit's own solution,
   ``p_gnss - p_ref = C_nb l - v tau + c`` (lever arm, latency, constant), and the GNSS velocity
   latency that best matches the reference;
3. ``runs``: the outage errors with the lever arm ignored and estimated (``lever_arm_sd``),
   position only and with velocity, with pyins' example models (as ``_n380.run_stochmod``).

Run ``python studies/nav_n380_checks.py [fd] [lever] [runs]``. Uses private filter internals
(``_Run._propagate``, ``_Run._feedback``) on purpose: the check is of those very functions.
"""

from __future__ import annotations

import math
import sys
import types
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "nav"))

from _n380 import OUTAGE_DURATION, OUTAGE_STARTS, load_n380, outage_windows

import stochmod
import stochmod.nav.filter as nav_filter
from stochmod.nav import GnssData, InitialState, LooselyCoupledFilter, earth, frames
from stochmod.nav.emulate import Trajectory
from stochmod.nav.strapdown import Mechanisation, NavState, imu_increments

DEG_H = math.pi / 180 / 3600


def pyins_models(freq: float = 100.0):
    """pyins' real-data example MEMS parameters (studies/nav_pyins_n380.py) as stochmod models."""
    gyro = (stochmod.WN.from_density(math.pi / 180 / 60, freq)
            + stochmod.RW.from_rrw(30 * DEG_H / 60, freq)).bind(freq)
    accel = (stochmod.WN.from_density(0.1 / 60, freq)
             + stochmod.RW.from_rrw(0.01 / 60, freq)).bind(freq)
    return gyro, accel, 300 * DEG_H, 0.05


def horizontal_error(ref: Trajectory, t, lat, lon) -> np.ndarray:
    tr = ref.at(t)
    la = np.radians(tr.lat)
    rn, re = earth.principal_radii(la)
    return np.hypot(np.radians(lat - tr.lat) * (rn + tr.height),
                    np.radians(lon - tr.lon) * (re + tr.height) * np.cos(la))


# the filter setting the checks' stand-in loops read: the default psi feedback
FILTER = types.SimpleNamespace(error_model="psi")


def check_transition(drive, steps: int) -> None:
    ref, imu, t0 = drive.reference, drive.imu, drive.t0
    gyro, accel, gb, ab = pyins_models()
    sens = nav_filter._Sensors(nav_filter._axis_models(gyro, accel), 0.01, gb, ab)
    h, dth, dv, con, scu = imu_increments(imu.time, imu.gyro, imu.accel, "increment")
    t = imu.time
    n = 9 + sens.n
    eps = np.r_[[1.0] * 3, [0.1] * 3, [1e-3] * 3,
                [1e-4 if sens.H[0:3, j].any() else 1e-2 for j in range(sens.n)]]
    names = list(nav_filter.NAV_STATES + sens.names)

    def start(i, dx):
        m = Mechanisation(NavState.from_degrees(lat=ref.lat[i], lon=ref.lon[i],
                                                height=ref.height[i], vel_ned=ref.vel_ned[i],
                                                rph=ref.rph[i]))
        nav_filter._Run._feedback(types.SimpleNamespace(mech=m, sens=types.SimpleNamespace(n=0),
                                                        flt=FILTER), -dx[:9])
        # (an "estimate minus truth" error of dx)
        m.dv_n = [0.0, 0.0, 0.0]
        return m

    def propagate(i, dx):
        m = start(i, dx)
        corr = sens.H @ dx[9:]
        for k in range(i, i + steps):
            m.step(h[k], tuple(dth[k] - corr[:3] * h[k]), tuple(dv[k] - corr[3:] * h[k]),
                   tuple(con[k]), tuple(scu[k]))
        return m

    def error(m0, m1, time):
        row = np.array([m1.lat, m1.lon, m1.h, *m1.v, *m1.q])[None]
        tr = Trajectory(np.array([time - 1, time + 1]), np.degrees([m0.lat] * 2),
                        np.degrees([m0.lon] * 2), np.array([m0.h] * 2), np.array([m0.v] * 2),
                        np.array([frames.quat_to_rph(np.array(m0.q))] * 2))
        return nav_filter.nav_errors(tr, row, np.array([time]))[0]

    for s in (100.0, 160.0, 175.0, 250.0, 300.0, 435.0):
        i = int(np.searchsorted(t, t0 + s))
        nom = propagate(i, np.zeros(n))
        m0 = start(i, np.zeros(n))
        dt = float(np.sum(h[i:i + steps]))
        ns = types.SimpleNamespace(mech=nom, sens=sens, _F=np.zeros((n, n)), _W=np.zeros((n, n)),
                                   P=np.zeros((n, n)), s=np.zeros(sens.n), t_now=0.0,
                                   corr=np.zeros(6), flt=FILTER,
                                   _start=(m0.lat, m0.h, m0.v, m0.q))
        ns._F[0:3, 3:6] = np.eye(3)
        ns._F[9:, 9:], ns._W[9:, 9:] = sens.F, sens.GQG
        ns.P = np.eye(n)  # P = I: after the step P = Phi Phi' + Q; Phi read back below
        captured = {}
        original = nav_filter.discretise

        def grab(F, W, d):
            captured["Phi"] = original(F, W, d)[0]
            return captured["Phi"], np.zeros_like(F)

        nav_filter.discretise = grab
        try:
            nav_filter._Run._propagate(ns, dt, steps, tuple(np.array(nom.dv_n) / dt))
        finally:
            nav_filter.discretise = original
        Phi = captured["Phi"]
        fd = np.zeros((9, n))
        for j in range(n):
            dx = np.zeros(n)
            dx[j] = eps[j]
            fd[:, j] = (error(nom, propagate(i, dx), t[i + steps])
                        - error(nom, propagate(i, -dx), t[i + steps])) / (2 * eps[j])
        diff = (Phi[:9] - fd) * eps
        scale = np.r_[[1e-2] * 3, [1e-3] * 3, [1e-6] * 3][:, None]
        r, c = np.unravel_index(np.argmax(np.abs(diff) / scale), diff.shape)
        print(f"t = {s:5.1f} s, {dt:.2f} s step: worst (Phi - FD) x eps = {diff[r, c]:+.2e} "
              f"in {names[r]} / {names[c]} (Phi {Phi[r, c] * eps[c]:+.3e}, "
              f"FD {fd[r, c] * eps[c]:+.3e})")


def fit_lever_arm(drive) -> None:
    ref, g = drive.reference, drive.gnss
    tr = ref.at(g.time)
    la = np.radians(tr.lat)
    rn, re = earth.principal_radii(la)
    ned = np.column_stack([np.radians(g.lat - tr.lat) * (rn + tr.height),
                           np.radians(g.lon - tr.lon) * (re + tr.height) * np.cos(la),
                           -(g.height - tr.height)])
    C = frames.rph_to_dcm(tr.rph)
    moving = np.hypot(tr.vel_ned[:, 0], tr.vel_ned[:, 1]) > 3.0
    A = np.zeros((3 * moving.sum(), 7))
    for k in range(3):
        A[k::3, 0:3] = C[moving][:, k, :]
        A[k::3, 3] = -tr.vel_ned[moving, k]
        A[k::3, 4 + k] = 1.0
    sol = np.linalg.lstsq(A, ned[moving].reshape(-1), rcond=None)[0]
    print(f"GNSS - reference, moving epochs: lever arm {np.round(sol[:3], 2)} m, position "
          f"latency {sol[3]:.3f} s, constant NED {np.round(sol[4:], 2)} m")
    for lag in (0.0, -0.1, -0.15, -0.175, -0.2, -0.25):
        d = g.vel_ned[moving] - ref.at(g.time[moving] + lag).vel_ned
        print(f"GNSS velocity vs reference {lag:+.3f} s later: horizontal rms "
              f"{np.sqrt(np.mean(d[:, :2] ** 2)):.3f} m/s")


def run(drive, velocity: bool, lever_arm_sd: float):
    ref, imu, g = drive.reference, drive.imu, drive.gnss
    gyro, accel, gb, ab = pyins_models()
    init = InitialState(ref.lat[0], ref.lon[0], ref.height[0], ref.vel_ned[0], ref.rph[0],
                        sd_position=5.0, sd_velocity=0.5, sd_attitude=(0.2, 0.2, 1.0))
    flt = LooselyCoupledFilter(gyro, accel, dt_filter=0.1, gyro_bias_sd=gb, accel_bias_sd=ab,
                               gate=None, gnss_sd=1.0, gnss_vel_sd=0.3, lever_arm_sd=lever_arm_sd)
    res = flt.run(imu.time, imu.gyro, imu.accel, kind=imu.kind,
                  gnss=GnssData(g.time, g.lat, g.lon, g.height,
                                vel_ned=g.vel_ned if velocity else None),
                  init=init, outages=[(s, OUTAGE_DURATION) for s in OUTAGE_STARTS])
    err = horizontal_error(ref, res.time, res.lat, res.lon)
    worst = [err[(res.time >= a) & (res.time < b)].max() for a, b in outage_windows(drive.t0)]
    arm = "" if res.lever_arm is None else f", final lever arm {np.round(res.lever_arm[-1], 2)} m"
    print(f"{'position+velocity' if velocity else 'position only':17s} lever_arm_sd "
          f"{lever_arm_sd:3.1f}: max horizontal error {np.round(worst, 1)} m{arm}")


def main(argv: list[str]) -> int:
    what = argv or ["fd", "lever", "runs"]
    drive = load_n380()
    if "fd" in what:
        for steps in (10, 100):
            check_transition(drive, steps)
    if "lever" in what:
        fit_lever_arm(drive)
    if "runs" in what:
        for velocity in (False, True):
            for sd in (0.0, 1.0):
                run(drive, velocity, sd)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
