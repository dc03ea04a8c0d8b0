"""Outage study in the shape of Stebler et al. (2014) Table III (and Quinchia et al. 2013
Tables 9-10): the simulated XSens MTi-G of stochmod.data.examples (Stebler Table II: gyros GM + GM +
WN, accelerometers GM + GM + GM + WN) is the truth; three filters differ only in their error
model:

- model 1: white noise only (each axis's WN of the truth);
- model 2: GM + WN (the truth's slowest Gauss-Markov process and its WN);
- model 3: the complete true model (2*GM + WN gyros, 3*GM + WN accelerometers).

Unlike Stebler, models 1 and 2 are sub-models of the truth, not re-fitted by the GMWM (a GMWM
fit of the complete structure on a short record can return a very fast Gauss-Markov process;
the filter's discretisation overflowed on one such fit, see the report).

Run ``python studies/study_xsens.py [--runs R] [--quick]``; the printed table is quoted in
docs/outages.md.
"""

from __future__ import annotations

import argparse
import sys
import time

from stochmod.cli.outages import QUICK_OUTAGES, QUICK_PROFILE, white_part
from stochmod.data.examples import xsens_mtig_models
from stochmod.core.model import Model
from stochmod.nav.study import DEFAULT_OUTAGES, DEFAULT_PROFILE, outage_study


def _slowest_gm_and_wn(model: Model) -> Model:
    gms = [p for p in model.processes if p.family == "GM"]
    slowest = min(gms, key=lambda p: p.beta)
    return Model((slowest, *[p for p in model.processes if p.family == "WN"])).bind(model.freq)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="3 min drive, two 30 s outages")
    args = parser.parse_args()
    freq = 100.0
    truth = xsens_mtig_models(freq)
    filters = {"model 1 (WN)": {a: white_part(m) for a, m in truth.items()},
               "model 2 (GM+WN)": {a: _slowest_gm_and_wn(m) for a, m in truth.items()},
               "model 3 (true)": truth}
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
