"""Which reset is better when the truth is known: stochmod's filter with each of its error
models (``error_model="psi"`` and pyins' ``"modified-phi"``) on emulated drives
built like the n380 drive (docs/navigation_real_drive.md, "Which reset is better?").

Each run: a standstill (``--still`` s, default 120), then about 5 minutes of driving with turns;
the IMU is the exact one of the trajectory plus errors drawn from pyins' example MEMS model
(white noise + random walk per axis, tests/nav/_n380.py) and turn-on biases of its 1-sigma (300
deg/h, 0.05 m/s^2); GNSS position fixes at 1 Hz with sd 1 m at an antenna 1.3 m behind the IMU
(the n380's fitted lever arm, known to the filter); the start perturbed by draws of pyins'
initial sd (5 m, 0.5 m/s, 0.2/0.2/1 deg); two 60 s outages while driving. Both filters see the
same data; printed per seed and on average: the maximum horizontal error in each outage and
the mean NEES of the 9 navigation states (9 for an honest filter), and the paired difference
of each other model minus psi with its standard error.

Run ``python studies/nav_reset_emulation.py [--seeds 12] [--first-seed 0] [--still 120]
[--fix-offset 0.005]`` (~6 s a seed and model here; ``--fix-offset`` stamps the fixes that many
seconds after the IMU epochs, otherwise on them). ``--velocity-sd SD`` adds GNSS velocity fixes
of the antenna with that 1-sigma (m/s), and ``--jacobians full pyins`` runs each model also
with pyins 1.0.1's velocity Jacobian, which leaves out the lever-arm terms
(docs/navigation_real_drive.md, "With velocity updates and the lever arm"). It also compared
two filter options since removed from the library, the exact reset Jacobian of the psi model
(``"psi-exact"``) and F at the end of each covariance step with each fix taken as the error at
the next IMU epoch; their results are in studies/README.md.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "nav"))

from _n380 import pyins_example_models, pyins_velocity_jacobian

from stochmod.nav import (ImuData, InitialState, LooselyCoupledFilter, Segment,
                          add_sensor_errors, gnss_measurements, ideal_imu,
                          trajectory_from_profile)
from stochmod.nav.emulate import AXES
from stochmod.nav.filter import ERROR_MODELS
from stochmod.nav.study import max_outage_errors

LEVER_ARM = np.array([-1.3, 0.0, 0.0])
INITIAL_SD = np.array([5.0, 5.0, 5.0, 0.5, 0.5, 0.5, 0.2, 0.2, 1.0])  # m, m/s, deg


def drive(still: float):
    """The trajectory and its two outages ((start s after the first epoch, duration s))."""
    profile = [Segment(still, speed=0.0), Segment(5, speed=8), Segment(10, turn=90, speed=10),
               Segment(20, speed=15), Segment(10, turn=-90), Segment(30, speed=20),
               Segment(8, turn=120, speed=10), Segment(20, speed=15), Segment(60, speed=18),
               Segment(10, turn=-60), Segment(15, turn=90, speed=12), Segment(20, speed=20),
               Segment(12, turn=-150, speed=8), Segment(20, speed=16),
               Segment(60, speed=18, turn=30)]
    truth = trajectory_from_profile(profile, rate=100.0, lat=37.0, lon=-122.0, height=50.0,
                                    heading=-107.0, speed=0.0)
    return truth, [(still + 113.0, 60.0), (truth.time[-1] - truth.time[0] - 60.0, 59.0)]


def one_seed(truth, clean: ImuData, outages, seed: int, models=ERROR_MODELS,
             fix_offset: float = 0.0, velocity_sd: float | None = None,
             jacobians=("full",)) -> dict[str, tuple[np.ndarray, float]]:
    """Per error model: maximum horizontal error per outage (m) and mean NEES of one seed.
    `velocity_sd` (m/s): GNSS velocity fixes of the antenna with that noise, None: none;
    `jacobians`: the velocity measurement's Jacobian, ``"full"`` (stochmod's) and/or
    ``"pyins"`` (pyins 1.0.1's, without the lever-arm terms: ``pyins_velocity_jacobian``;
    keyed ``MODEL/pyins-jacobian``)."""
    gyro, accel, gyro_bias_sd, accel_bias_sd = pyins_example_models()
    rng = np.random.default_rng(100 + seed)
    bias = np.r_[rng.normal(0, gyro_bias_sd, 3), rng.normal(0, accel_bias_sd, 3)]
    noisy = add_sensor_errors(clean, {a: gyro if a.startswith("gyro") else accel for a in AXES},
                              rng)
    h = np.diff(clean.time)
    h = np.r_[h[:1], h][:, None]
    imu = ImuData(noisy.time, noisy.gyro + bias[:3] * h, noisy.accel + bias[3:] * h, "increment")
    # fixes `fix_offset` s after the IMU epochs (the n380's fall 0 to 10 ms after them)
    stamped = truth if not fix_offset else truth.at(truth.time[:-1] + fix_offset)
    gnss = gnss_measurements(stamped, 1.0, sigma_h=1.0, sigma_v=1.0, sigma_vel=velocity_sd,
                             lever_arm=LEVER_ARM, rng=rng)
    s0 = truth.at(truth.time[:1])
    e = rng.standard_normal(9) * INITIAL_SD
    lat0 = math.radians(s0.lat[0])
    init = InitialState(s0.lat[0] + math.degrees(e[0] / 6.37e6),
                        s0.lon[0] + math.degrees(e[1] / 6.37e6 / math.cos(lat0)),
                        s0.height[0] - e[2], s0.vel_ned[0] + e[3:6], s0.rph[0] + e[6:9],
                        sd_position=5.0, sd_velocity=0.5, sd_attitude=(0.2, 0.2, 1.0))
    t0 = truth.time[0]
    out = {}
    windows = [(t0 + s, t0 + s + d) for s, d in outages]
    for model in models:
        for jac in jacobians:
            flt = LooselyCoupledFilter(gyro, accel, dt_filter=0.1, gyro_bias_sd=gyro_bias_sd,
                                       accel_bias_sd=accel_bias_sd, gate=None, gnss_sd=1.0,
                                       gnss_vel_sd=velocity_sd or 0.1, lever_arm=LEVER_ARM,
                                       error_model=model)
            with pyins_velocity_jacobian() if jac == "pyins" else contextlib.nullcontext():
                res = flt.run(imu.time, imu.gyro, imu.accel, kind="increment", gnss=gnss,
                              init=init, outages=outages, truth=truth)
            key = model if jac == "full" else f"{model}/pyins-jacobian"
            out[key] = (max_outage_errors(truth, res.time, res.lat, res.lon, windows),
                        res.mean_nees)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=12)
    parser.add_argument("--first-seed", type=int, default=0, help="seeds FIRST .. FIRST+N-1")
    parser.add_argument("--still", type=float, default=120.0, help="standstill at the start, s")
    parser.add_argument("--models", nargs="+", default=list(ERROR_MODELS),
                        choices=ERROR_MODELS)
    parser.add_argument("--fix-offset", type=float, default=0.0,
                        help="GNSS fixes this many seconds after the IMU epochs (< one step)")
    parser.add_argument("--velocity-sd", type=float, default=None,
                        help="also GNSS velocity fixes with this 1-sigma (m/s)")
    parser.add_argument("--jacobians", nargs="+", default=["full"], choices=["full", "pyins"],
                        help="velocity Jacobian: stochmod's (full) and/or pyins' (no lever-arm "
                             "terms)")
    args = parser.parse_args(argv)
    truth, outages = drive(args.still)
    clean = ideal_imu(truth, "increment")
    runs = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        runs.append(one_seed(truth, clean, outages, seed, args.models, args.fix_offset,
                             args.velocity_sd, args.jacobians))
        print(f"seed {seed}: " + "; ".join(f"{m} {np.round(e, 1)} m" for m, (e, _) in
                                             runs[-1].items()), flush=True)
    keys = list(runs[0])
    err = {m: np.array([r[m][0] for r in runs]) for m in keys}
    for m in keys:
        print(f"{m:28s} mean max horizontal error per outage {np.round(err[m].mean(0), 2)} m, "
              f"mean NEES {np.mean([r[m][1] for r in runs]):.2f}")
    pairs = [(m, "psi") for m in keys if m != "psi" and "psi" in keys]
    pairs += [(m, m.split("/")[0]) for m in keys if m.endswith("/pyins-jacobian")
              and m.split("/")[0] != "psi" and m.split("/")[0] in keys]
    for m, base in pairs:
        d = err[m] - err[base]
        se = d.std(0, ddof=1) / math.sqrt(len(d)) if len(d) > 1 else np.full(d.shape[1], np.nan)
        print(f"{m} - {base}: {np.round(d.mean(0), 2)} +- {np.round(se, 2)} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
