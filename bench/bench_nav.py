"""Speed on the onavdata HGuide n380 drive (669 s, 100 Hz increments, 1 Hz GNSS position and
velocity, three 60 s outages): stochmod's 21-state loosely-coupled filter (9
navigation states + a random walk and a turn-on bias per sensor axis, pyins' example MEMS
model) against pyins 1.0.1's feedback filter with the same model, in the same run.

stochmod runs three times: with the covariance step of pyins' run (0.1 s, the comparison of
docs/navigation_real_drive.md), with one covariance step per GNSS interval (1 s; see
docs/navigation.md, "Covariance step", for its effect on the outage errors), and at 0.1 s
with pyins' error model (``error_model="modified-phi"``). Each is the best
of ``--repeats`` runs; every run includes the filter's start-up (model assembly and
discretisation, the increments), not the loading of the drive. pyins runs once (its first
call includes numba's compilation). The machine is shared: the ratio
is the number to read, the absolute times are noisy; the load average is printed.

Run ``python bench/bench_nav.py [--repeats 3] [--no-pyins]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

# the drive's loader lives with the test that checks it, pyins' run with the studies
ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests" / "nav"), str(ROOT / "studies")]

from _n380 import load_n380, max_outage_errors, run_stochmod
from nav_pyins_n380 import initial_error, raw_inputs, run_pyins


def _timed(fn, repeats: int):
    best = None
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall, cpu = time.perf_counter() - t, time.process_time() - c
        if best is None or wall < best[1]:
            best = (out, wall, cpu)
    return best


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-pyins", action="store_true", help="time stochmod only")
    args = parser.parse_args()
    drive = load_n380()
    duration = float(drive.imu.time[-1] - drive.imu.time[0])
    print(f"n380 drive: {duration:.1f} s, {drive.imu.time.size} IMU samples, "
          f"{drive.gnss.time.size} GNSS fixes (position + velocity, 3 x 60 s outages)")
    ours = {}
    for dt, model in ((0.1, "psi"), (1.0, "psi"), (0.1, "modified-phi")):
        res, wall, cpu = _timed(lambda: run_stochmod(drive, velocity=True, dt_filter=dt,
                                                     initial_error=initial_error(),
                                                     error_model=model),
                                args.repeats)
        ours[dt, model] = (wall, cpu)
        err = max_outage_errors(res.time, res.lat, res.lon, drive.reference, drive.t0)
        print(f"stochmod {len(res.state_names)}-state filter ({model}), covariance step {dt:g} s: "
              f"{wall:6.2f} s wall ({duration / wall:6.1f}x real time), {cpu:6.2f} s CPU "
              f"({duration / cpu:6.1f}x); best of {args.repeats}; max horizontal error per "
              f"outage {', '.join(f'{e:.1f}' for e in err)} m", flush=True)
    if not args.no_pyins:
        t, c = time.perf_counter(), time.process_time()
        increments, gnss, pva0 = raw_inputs(drive)
        peer, t_filter = run_pyins(increments, gnss, pva0, velocity=True)
        t_peer, c_peer = time.perf_counter() - t, time.process_time() - c
        traj = peer.trajectory
        err_peer = max_outage_errors(traj.index.to_numpy(), traj["lat"].to_numpy(),
                                     traj["lon"].to_numpy(), drive.reference, drive.t0)
        print(f"pyins feedback filter (covariance step 0.1 s): {t_peer:7.2f} s wall "
              f"({duration / t_peer:6.1f}x real time; filter alone {t_filter:.2f} s), "
              f"{c_peer:7.2f} s CPU ({duration / c_peer:.1f}x); max horizontal error per "
              f"outage {', '.join(f'{e:.1f}' for e in err_peer)} m")
        for (dt, model), (wall, cpu) in ours.items():
            print(f"ratio pyins / stochmod ({model}, step {dt:g} s): wall {t_peer / wall:.1f}, "
                  f"CPU {c_peer / cpu:.1f}")
    print(f"goal: stochmod >= 100x real time in wall time, start-up included; load "
          f"average {', '.join(f'{x:.1f}' for x in os.getloadavg())} (2 cores, shared)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
