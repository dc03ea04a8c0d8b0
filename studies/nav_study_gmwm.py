"""Stebler Table III in shape with GMWM refits: the filters' error models are fitted
by the GMWM to an emulated static record, as in Stebler et al. (2014) Section VI, instead of
being sub-models of the truth (studies/study_xsens.py).

The truth is the simulated XSens MTi-G of stochmod.data.examples (Table II, "driving" reading:
gyros GM + GM + WN, accelerometers GM + GM + GM + WN). Its static record
(``stochmod.data.examples.xsens_mtig``, 2^19 samples at 100 Hz, seed 2014) is fitted per axis with
three structures:

- model 1: ``WN`` (the GMWM gives white noise alone its best level over all scales);
- model 2: ``GM+WN``;
- model 3: the complete structure (``2*GM+WN`` gyros, ``3*GM+WN`` accelerometers).

The outage study then draws the sensor errors of each emulated drive from the TRUE models and
navigates with the three fitted ones and with the true models themselves (the reference row).
The filters are told the record's length (5243 s), so a fitted Gauss-Markov component whose
correlation time lies beyond it enters them as the random walk it is over the record
(``outage_study(record=)``, stochmod.fit.equivalence); ``--no-record`` takes the fits as they are
(the degenerate full fit then navigates at kilometres). Run ``python studies/nav_study_gmwm.py
[--runs R] [--workers N] [--dt-filter S] [--no-record]``; the table is quoted in
docs/outages.md.
"""

from __future__ import annotations

import argparse
import sys
import time

import stochmod
from stochmod.data.examples import xsens_mtig, xsens_mtig_models
from stochmod.nav.study import outage_study

STRUCTURES = {"model 1 (WN fit)": ("WN", "WN"),
              "model 2 (GM+WN fit)": ("GM+WN", "GM+WN"),
              "model 3 (full fit)": ("2*GM+WN", "3*GM+WN")}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--dt-filter", type=float, default=1.0)
    parser.add_argument("--no-record", action="store_true",
                        help="do not tell the filters the record length (fits as they are)")
    args = parser.parse_args()
    freq = 100.0
    truth = xsens_mtig_models(freq)
    record = xsens_mtig(seed=2014, freq=freq)
    t = time.perf_counter()
    filters = {}
    for name, (gyro, accel) in STRUCTURES.items():
        filters[name] = {}
        for axis in truth:
            spec = gyro if axis.startswith("gyro") else accel
            fit = stochmod.gmwm(record.column(axis), spec, freq)
            filters[name][axis] = fit.model.bind(freq)
            print(f"{name} {axis}: {fit.model.name} "
                  + ", ".join(f"{p}={v:.4g}" for p, v in _physical(fit.model).items()),
                  flush=True)
    print(f"fits: {time.perf_counter() - t:.1f} s")
    filters["true model"] = truth  # the reference row: no component of it exceeds the record
    t = time.perf_counter()
    seconds = None if args.no_record else len(record.column(next(iter(truth)))) / freq
    study = outage_study(filters, truth, runs=args.runs, seed=2014, rate=freq,
                         dt_filter=args.dt_filter, workers=args.workers, record=seconds)
    print(f"study: {time.perf_counter() - t:.1f} s")
    print(study.summary())
    return 0


def _physical(model) -> dict[str, float]:
    out = {}
    for label, proc in zip(model.labels, model.processes):
        for key, value in proc.physical(model.freq).items():
            if key in ("Tc", "sigma", "N"):
                out[f"{label}.{key}"] = float(value.value)
    return out


if __name__ == "__main__":
    sys.exit(main())
