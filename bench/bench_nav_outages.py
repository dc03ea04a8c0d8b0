"""Speed of an outage study: R emulated 10-minute drives (100 Hz IMU, 1 Hz GNSS, three 60 s
outages) x 3 filters (the Stebler Table III set of studies/study_xsens.py: white noise, slowest
GM + WN, the complete 24-state true model of the simulated XSens MTi-G), spread over worker
processes, against the goal (100 x 3 in under 10 minutes on this 2-core machine).

The reference in the same run is the configuration before the process pool and the
once-per-GNSS-interval covariance step: serial, covariance step 0.1 s, timed on a few runs and
scaled to R (the runs are independent and equally long). The emulated trajectory and its exact
IMU are built once per study and are included in both times. The machine is shared: read the
ratio; the absolute times depend on the load.

Run ``python bench/bench_nav_outages.py [--runs 100] [--workers 2] [--dt-filter 1.0]
[--baseline-runs 2]``; it also prints the study's table (quoted in docs/outages.md).
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "studies"))

from study_xsens import _slowest_gm_and_wn

from stochmod.cli.outages import white_part
from stochmod.data.examples import xsens_mtig_models
from stochmod.nav.study import outage_study


def _cpu() -> float:
    """CPU seconds of this process and its finished children (the pool's workers)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--dt-filter", type=float, default=1.0)
    parser.add_argument("--baseline-runs", type=int, default=2,
                        help="runs of the serial 0.1 s configuration timed for the ratio (0: skip)")
    args = parser.parse_args()
    truth = xsens_mtig_models(100.0)
    filters = {"model 1 (WN)": {a: white_part(m) for a, m in truth.items()},
               "model 2 (GM+WN)": {a: _slowest_gm_and_wn(m) for a, m in truth.items()},
               "model 3 (true)": truth}
    t, c = time.perf_counter(), _cpu()
    study = outage_study(filters, truth, runs=args.runs, seed=2014, dt_filter=args.dt_filter,
                         workers=args.workers)
    wall, cpu = time.perf_counter() - t, _cpu() - c
    print(study.summary())
    print(f"outage study {args.runs} runs x {len(filters)} filters, {args.workers} worker(s), "
          f"covariance step {args.dt_filter:g} s: {wall:.1f} s wall, {cpu:.1f} s CPU in all "
          f"processes ({cpu / args.workers:.1f} s on {args.workers} free cores; goal: 100 x 3 "
          "in < 600 s; load average now "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())})")
    if args.baseline_runs:
        t, c = time.perf_counter(), _cpu()
        outage_study(filters, truth, runs=args.baseline_runs, seed=2014, dt_filter=0.1)
        scale = args.runs / args.baseline_runs
        base, base_cpu = (time.perf_counter() - t) * scale, (_cpu() - c) * scale
        print(f"serial, covariance step 0.1 s: {base:.1f} s wall, {base_cpu:.1f} s CPU for "
              f"{args.runs} runs (scaled from {args.baseline_runs}); ratio wall "
              f"{base / wall:.2f}, CPU {base_cpu / cpu:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
