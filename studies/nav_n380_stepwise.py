"""Step-by-step comparison of stochmod's and pyins' filters on one seeded start of the n380 drive
(docs/navigation_real_drive.md, "The cause"): where the outage-3 gap comes from.

pyins runs once with its Kalman correction and its error-propagation function wrapped, so that
every propagation (``Phi, Q``, the step, its linearisation point: mid-step PVA and mean body
specific force) and every update (``P`` before, ``z, H, R``) is logged in order; stochmod runs
from the same start with each error model (``error_model="psi"`` and ``"modified-phi"``; the
figures of the exact psi reset, a library option then, are in studies/README.md). Printed:

1. at times through the standstill (the first 120 s), the drive and the 60 s before outage 3:
   the heading and gyro-z bias 1-sigma of the filters, and the difference of each
   stochmod filter's accelerometer biases from pyins' in units of pyins' 1-sigma;
2. a replay of the covariance recursion along pyins' own linearisation points and updates:
   with pyins' matrices (which reproduces pyins) and with stochmod's psi-angle propagation
   (``_Run._propagate`` of the filter, at pyins' PVA and specific force), without and with the
   modified-phi reset. The heading 1-sigma at the end of the standstill is the measure.

Run ``python studies/nav_n380_stepwise.py [--seed 0] [--stop 483]`` (`--stop`: s after the first
epoch at which pyins stops; pyins takes 2 to 8 minutes here).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "nav"))

from _n380 import LEVER_ARM, load_n380, run_stochmod
from nav_pyins_n380 import initial_error, raw_inputs, run_pyins

from stochmod.nav import InitialState, frames
from stochmod.nav.filter import ERROR_MODELS, _Run, _Sensors

TIMES = (50.0, 100.0, 119.0, 160.0, 250.0, 421.9)


def pyins_logged(drive, seed: int, stop: float):
    """pyins' run to `stop` s after the first epoch with every propagation and update logged in
    order: ``("prop", pva_mid, accel_mean_body, dt, Phi, Q)`` and ``("upd", P, z, H, R)``."""
    import pyins.filters as pf
    import pyins.kalman as pk

    events = []
    correct, propagate = pk.correct, pf._compute_error_propagation_matrices

    def logged_correct(x, P, z, H, R):
        events.append(("upd", P.copy(), z.copy(), H.copy(), R.copy()))
        return correct(x, P, z, H, R)

    def logged_propagate(pva, gyro, accel, dt, *models):
        Phi, Q = propagate(pva, gyro, accel, dt, *models)
        events.append(("prop", pva.copy(), np.asarray(accel, dtype=float), dt, Phi, Q))
        return Phi, Q

    increments, gnss, pva0 = raw_inputs(drive)
    end = drive.t0 + stop
    increments, gnss = increments[increments.index <= end], gnss[gnss.index <= end]
    pk.correct, pf._compute_error_propagation_matrices = logged_correct, logged_propagate
    try:
        result, _ = run_pyins(increments, gnss, pva0, velocity=False, lever_arm=LEVER_ARM,
                              seed=seed)
    finally:
        pk.correct, pf._compute_error_propagation_matrices = correct, propagate
    return result, events


def replay(drive, events, seed: int, error_model: str) -> np.ndarray:
    """stochmod's covariance recursion along pyins' linearisation points and updates: the
    filter's own propagation (``_Run._propagate`` at pyins' mid-step PVA and mean specific
    force) and, for ``"modified-phi"``, its own reset with the velocity correction of pyins'
    innovation. Returns the psi_D 1-sigma (deg) before each update."""
    from _n380 import pyins_example_models
    from stochmod.nav import LooselyCoupledFilter

    gyro, accel, gb, ab = pyins_example_models()
    flt = LooselyCoupledFilter(gyro, accel, gyro_bias_sd=gb, accel_bias_sd=ab,
                               lever_arm=LEVER_ARM, error_model=error_model)
    ref, err = drive.reference, initial_error(seed)
    init = InitialState(ref.lat[0], ref.lon[0], ref.height[0], ref.vel_ned[0] + err["vel"],
                        ref.rph[0] + np.asarray(err["rph"]), sd_position=5.0, sd_velocity=0.5,
                        sd_attitude=(0.2, 0.2, 1.0))
    z = np.zeros((1, 3))
    run = _Run(flt, _Sensors(flt.models, 0.01, gb, ab), init, np.array([0.0, 0.01]),
               np.array([0.01]), z, z, z, z, [], None)
    run.t_now = 0.0
    out = []
    for ev in events:
        if ev[0] == "prop":
            _, pva, f_b, dt, _, _ = ev
            rph = pva[["roll", "pitch", "heading"]].to_numpy(dtype=float)
            mech = run.mech
            mech.q = tuple(frames.rph_to_quat(rph))
            mech.lat, mech.h = np.radians(float(pva["lat"])), float(pva["alt"])
            mech.v = tuple(pva[["VN", "VE", "VD"]].to_numpy(dtype=float))
            # both ends of the step at pyins' mid-step PVA: the filter's midpoint is that state
            run._start = (mech.lat, mech.h, mech.v, mech.q)
            run._propagate(dt, max(1, round(dt / 0.01)), tuple(frames.rph_to_dcm(rph) @ f_b))
            continue
        _, _, innovation, H, R = ev
        out.append(float(np.degrees(np.sqrt(run.P[8, 8]))))
        Hf = np.zeros((H.shape[0], run.n))
        Hf[:, :9] = H[:, :9]
        K = run.P @ Hf.T @ np.linalg.inv(Hf @ run.P @ Hf.T + R)
        U = np.eye(run.n) - K @ Hf
        run.P = U @ run.P @ U.T + K @ R @ K.T
        if error_model == "modified-phi":  # the hold only (pyins' state is not replayed)
            run._reset(slice(3, 6), slice(3, 9),
                       np.hstack([np.eye(3), frames.skew(-(K @ innovation)[3:6])]))
    return np.array(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--stop", type=float, default=483.0)
    args = parser.parse_args(argv)
    drive = load_n380()
    theirs, events = pyins_logged(drive, args.seed, args.stop)
    ours = {m: run_stochmod(drive, velocity=False, initial_error=initial_error(args.seed),
                            lever_arm=LEVER_ARM, error_model=m) for m in ERROR_MODELS}
    t0 = drive.t0
    pt = theirs.accel.index.to_numpy()
    print(f"seed {args.seed}: 1-sigma and accelerometer biases (stochmod - pyins) / pyins' sigma;"
          " stochmod's gyro-z sd: hypot of its random-walk and turn-on states (their"
          " correlation ignored)")
    for ts in TIMES:
        if ts > args.stop:
            break
        i = int(np.searchsorted(pt, t0 + ts)) - 1
        k = int(np.searchsorted(theirs.trajectory_sd.index.to_numpy(), t0 + ts)) - 1
        line = (f"{ts:6.1f} s  heading sd: pyins {theirs.trajectory_sd['heading'].iloc[k]:6.3f}"
                f" deg, gyro z sd {theirs.gyro_sd.iloc[k, 2]:.3g} rad/s")
        for m, r in ours.items():
            j = int(np.searchsorted(r.epoch_time, t0 + ts)) - 1
            d = (r.sensor_errors[j, 3:] - theirs.accel.to_numpy()[i]) / theirs.accel_sd.to_numpy()[i]
            gz = np.hypot(r.epoch_sd[j, 11], r.epoch_sd[j, 17])
            line += (f" | {m}: {np.degrees(r.epoch_sd[j, 8]):6.3f} deg, {gz:.3g} rad/s, accel "
                     f"{np.array2string(d, precision=2)}")
        print(line)
    update_times = np.array([t for t in theirs.innovations["Position"].index])
    pyins_sd = np.array([np.degrees(np.sqrt(ev[1][8, 8])) for ev in events if ev[0] == "upd"])
    replays = {m: replay(drive, events, args.seed, m) for m in ("psi", "modified-phi")}
    print("replay along pyins' linearisation points and updates: psi_D / phi_D 1-sigma (deg)")
    for ts in (50.0, 100.0, 119.0):
        k = int(np.searchsorted(update_times, t0 + ts)) - 1
        print(f"{ts:6.1f} s  pyins {pyins_sd[k]:6.3f}  " + "  ".join(
            f"stochmod {m} {r[k]:6.3f}" for m, r in replays.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
