"""Outage study in the shape of Stebler et al. (2014) Table III (and Quinchia et al. 2013
Tables 9-10): the simulated XSens MTi-G of stochmod.examples (Stebler Table II: gyros GM + GM +
WN, accelerometers GM + GM + GM + WN) is the truth; three filters differ only in their error
model, each fitted by the GMWM to the same simulated static recording:

- model 1: WN only;
- model 2: GM + WN (the long-correlation part only);
- model 3: the complete structure (2*GM + WN gyros, 3*GM + WN accelerometers).

Run ``python bench/study_xsens.py [--runs R] [--quick]``; the printed table is quoted in
docs/outages.md.
"""

from __future__ import annotations

import argparse
import sys
import time

from stochmod.examples import xsens_mtig
from stochmod.fit.gmwm import gmwm
from stochmod.cli.outages import QUICK_OUTAGES, QUICK_PROFILE
from stochmod.nav.study import DEFAULT_OUTAGES, DEFAULT_PROFILE, outage_study
from stochmod.examples import xsens_mtig_models

STRUCTURES = {
    "model 1 (WN)": {"gyro": "WN", "accel": "WN"},
    "model 2 (GM+WN)": {"gyro": "GM+WN", "accel": "GM+WN"},
    "model 3 (full)": {"gyro": "2*GM+WN", "accel": "3*GM+WN"},
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="3.5 min drive, two 30 s outages")
    parser.add_argument("--n", type=int, default=2**18, help="static samples per axis to fit")
    args = parser.parse_args()
    freq = 100.0
    truth = xsens_mtig_models(freq)
    rec = xsens_mtig(args.n, freq=freq)
    t = time.perf_counter()
    filters = {}
    for name, spec in STRUCTURES.items():
        filters[name] = {c: gmwm(rec.column(c), spec[c.split("_")[0]], freq).model.bind(freq)
                         for c in rec.columns}
    print(f"GMWM fits: {time.perf_counter() - t:.1f} s", flush=True)
    t = time.perf_counter()
    study = outage_study(filters, truth, runs=args.runs, seed=2014, rate=freq,
                         profile=QUICK_PROFILE if args.quick else DEFAULT_PROFILE,
                         outages=QUICK_OUTAGES if args.quick else DEFAULT_OUTAGES,
                         progress=lambda r, n: print(f"run {r + 1}: {n}", flush=True))
    print(f"study: {time.perf_counter() - t:.1f} s")
    print(study.summary())
    return 0


if __name__ == "__main__":
    sys.exit(main())
