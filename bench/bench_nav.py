"""Speed on the onavdata HGuide n380 drive (669 s, 100 Hz increments, 1 Hz GNSS position and
velocity, the issue's three 60 s outages): stochmod's 21-state loosely-coupled filter (9
navigation states + a random walk and a turn-on bias per sensor axis, pyins' example MEMS
model) against pyins 1.0.1's feedback filter with the same model, in the same run.

Wall and CPU times include the start-up of each filter (model assembly, pyins' increments and, on its
first call, numba's compilation), not the loading of the drive. The machine is shared: the
ratio is the number to read, the absolute times are noisy. Run ``python bench/bench_nav.py``.
"""

from __future__ import annotations

import sys
import time

from _n380 import load_n380, max_outage_errors, run_stochmod
from nav_pyins_n380 import initial_error, raw_inputs, run_pyins


def main() -> int:
    drive = load_n380()
    duration = float(drive.imu.time[-1] - drive.imu.time[0])

    t, c = time.perf_counter(), time.process_time()
    ours = run_stochmod(drive, velocity=True, initial_error=initial_error())
    t_ours, c_ours = time.perf_counter() - t, time.process_time() - c
    n_states = len(ours.state_names)

    t, c = time.perf_counter(), time.process_time()
    increments, gnss, pva0 = raw_inputs(drive)
    peer, t_filter = run_pyins(increments, gnss, pva0, velocity=True)
    t_peer, c_peer = time.perf_counter() - t, time.process_time() - c

    err_ours = max_outage_errors(ours.time, ours.lat, ours.lon, drive.reference, drive.t0)
    traj = peer.trajectory
    err_peer = max_outage_errors(traj.index.to_numpy(), traj["lat"].to_numpy(),
                                 traj["lon"].to_numpy(), drive.reference, drive.t0)
    print(f"n380 drive: {duration:.1f} s, {drive.imu.time.size} IMU samples, "
          f"{drive.gnss.time.size} GNSS fixes (position + velocity, 3 x 60 s outages)")
    print(f"stochmod {n_states}-state filter: {t_ours:7.2f} s  ({duration / t_ours:6.1f}x real "
          f"time)  max horizontal error per outage "
          f"{', '.join(f'{e:.1f}' for e in err_ours)} m")
    print(f"pyins feedback filter:      {t_peer:7.2f} s  ({duration / t_peer:6.1f}x real "
          f"time; filter alone {t_filter:.2f} s)  max horizontal error per outage "
          f"{', '.join(f'{e:.1f}' for e in err_peer)} m")
    print(f"CPU time: stochmod {c_ours:.2f} s ({duration / c_ours:.1f}x real time), pyins "
          f"{c_peer:.2f} s ({duration / c_peer:.1f}x)")
    print(f"ratio pyins / stochmod: wall {t_peer / t_ours:.2f}, CPU {c_peer / c_ours:.2f} (issue "
          "goal: stochmod >= 100x real time; wall times noisy on the shared machine)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
