"""Stebler Section VI on real error signals: GNSS-outage studies whose IMU errors are windows of
the static ADIS16405 recordings, navigated by filters built from four calibrations of the first
half of imu1 (docs/outages_real_errors.md quotes this script's output).

1. Cut the first half of ``adis_16405_imu1.npz`` (5000 s at 100 Hz; gyro deg/s, accel g, as
   its ``units`` entry says) into a file of its own and calibrate it four ways:

   a. ``allan``: white noise and random walk read off the Allan variance of each axis
      (``stochmod.allan_reading``: N from its -1/2 region; K from its +1/2 region, or, where
      the reading finds none, from the +1/2 line fitted to the averaging times from the Allan
      deviation's minimum to the longest one: the practice of the IMU-noise tools);
   b. ``allan x10``: the same with N and K multiplied by 10 (variances by 100), the inflation
      that users of Kalibr are told to apply to Allan-variance noise figures;
   c. ``gmwm``: ``stochmod calibrate`` (GMWM with WVIC model selection per axis);
   d. ``triad``: ``stochmod calibrate --triad`` (one structure per sensor triad).

   (a) and (b) are written as ``calibration.json`` files with the same ``columns`` / ``model``
   layout, so every filter comes from a file read by ``stochmod.nav.logs.read_calibration``.
2. Run the outage study (``stochmod.nav.study.outage_study``, 10-minute drive, three 60 s
   outages) twice: with the windows of imu1's second half (the first half excluded: 8 runs)
   and with the windows of imu2 (a second unit of the same model, 16 runs). Each run adds the
   error signal of its own window, less the mean of the record it comes from.

Run ``python studies/outages_real_errors.py [--quick] [--runs R] [--workers N] [--dt-filter S]
[--keep DIR]``; about 2 minutes with the defaults on two cores. Needs ../shared/data beside
the repository.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import stochmod
from stochmod.fit.classical.build import allan_model
from stochmod.io.recording import read_recording
from stochmod.nav.logs import calibration_record, read_calibration
from stochmod.nav.study import (
    DEFAULT_OUTAGES,
    DEFAULT_PROFILE,
    OutageStudy,
    outage_study,
    static_errors,
)

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "imudata"
IMU1, IMU2 = DATA / "adis_16405_imu1.npz", DATA / "adis_16405_imu2.npz"
#: Turn-on bias 1-sigma drawn per run and told to every filter (rad/s, m/s^2): a new power-up
#: per drive, which one static record cannot show.
GYRO_BIAS_SD, ACCEL_BIAS_SD = 1e-3, 0.02
INFLATION = 10.0


def cut_first_half(src: Path, dst: Path) -> tuple[int, float]:
    """Write the first half of an npz recording (every per-sample entry) to `dst`."""
    with np.load(src) as d:
        n = max(d[k].shape[0] for k in d.files if d[k].ndim == 1 and d[k].dtype.kind == "f")
        half = n // 2
        out = {k: (d[k][:half] if d[k].ndim == 1 and d[k].shape[0] == n else d[k])
               for k in d.files}
        freq = float(d["freq"])
    np.savez(dst, **out)
    return half, freq


def allan_wn_rw(x: np.ndarray, freq: float) -> stochmod.Model:
    """White noise + random walk read off the Allan variance (see the module docstring)."""
    reading = stochmod.allan_reading(x, freq, terms=("N", "K"), require=("N",))
    if "K" not in reading.coefficient_values():
        av = reading.avar
        i = int(np.argmin(av.avar))
        lo = av.tau[i] if i < av.tau.size - 1 else av.tau[-2]
        region = (float(lo) * 0.999, float(av.tau[-1]) * 1.001)
        reading = stochmod.allan_reading(x, freq, terms=("N",), require=("N",),
                                         regions={"K": region})
    return allan_model(reading, freq)


def write_calibration(path: Path, models: dict[str, stochmod.Model], n: int, freq: float,
                      note: str) -> None:
    """A calibration.json with the columns' model specs (what read_calibration reads)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    columns = {c: {"name": m.name, "model": m.to_spec()} for c, m in models.items()}
    path.write_text(json.dumps({"freq": freq, "n": n, "method": note, "columns": columns},
                               indent=1))


def inflated(model: stochmod.Model, factor: float) -> stochmod.Model:
    """Every process's variance parameter times factor^2 (N and K times factor)."""
    spec = model.to_spec()
    for proc in spec["processes"]:
        proc["params"]["sigma2"] *= factor ** 2
    return stochmod.model_from_spec(spec)


def calibrations(work: Path) -> dict[str, Path]:
    cut = work / "imu1_first_half.npz"
    n, freq = cut_first_half(IMU1, cut)
    files = {}
    for name, extra in (("gmwm", []), ("triad", ["--triad"])):
        out = work / name
        t = time.perf_counter()
        subprocess.run([sys.executable, "-c", "from stochmod.cli import script; script()",
                        "calibrate", str(cut), "--out", str(out), "--no-plots", *extra],
                       check=True, stdout=subprocess.DEVNULL)
        print(f"calibrate {' '.join(extra) or '(default)'}: {time.perf_counter() - t:.1f} s",
              file=sys.stderr)
        files[name] = out / "calibration.json"
    rec = read_recording(cut).to_si()
    allan = {c: allan_wn_rw(rec.data[:, k], freq) for k, c in enumerate(rec.columns)}
    files["allan"] = work / "allan" / "calibration.json"
    write_calibration(files["allan"], allan, n, freq, "Allan variance reading, WN + RW")
    files["allan x10"] = work / "allan_x10" / "calibration.json"
    write_calibration(files["allan x10"], {c: inflated(m, INFLATION) for c, m in allan.items()},
                      n, freq, f"Allan variance reading, WN + RW, N and K x{INFLATION:g}")
    return {k: files[k] for k in ("allan", "allan x10", "gmwm", "triad")}


def describe(files: dict[str, Path]) -> None:
    for name, path in files.items():
        models = read_calibration(path)
        print(f"{name}: " + "; ".join(f"{a} {m.name}" for a, m in models.items()))
        for axis, m in models.items():
            parts = []
            for label, proc in zip(m.labels, m.processes):
                phys = {k: float(v.value) for k, v in proc.physical(m.freq).items()
                        if k in ("Tc", "sigma", "N", "K")}
                parts.append(f"{label}(" + ", ".join(f"{k}={v:.3g}" for k, v in phys.items())
                             + ")")
            print(f"    {axis}: " + " + ".join(parts))


def markdown(study: OutageStudy, label: str) -> str:
    """The study as the markdown table of docs/outages_real_errors.md."""
    lo, hi = study.nees_band()
    head = (f"**{label}** ({study.runs} runs, seed {study.seed}; NEES band for "
            f"{study.runs} runs [{lo:.2f}, {hi:.2f}])")
    columns = ("| outage | filter | states | mean (m) | median (m) | 95% (m) | NEES at end | "
               "RMS error / sigma |")
    lines = [head, "", columns, "|---|---|---:|---:|---:|---:|---:|---:|"]
    for k, (start, dur) in enumerate(study.outages):
        for name in study.filters:
            mean, med, p95 = study.statistics(name)[k]
            nees, rms, _ = study.consistency(name)[k]
            mark = "" if lo <= nees <= hi else (" (above)" if nees > hi else " (below)")
            lines.append(f"| {start:g}+{dur:g} s | {name} | {study.n_states[name]} | "
                         f"{mean:.4g} | {med:.4g} | {p95:.4g} | {nees:.3g}{mark} | {rms:.3g} |")
    ref = "gmwm"
    paired = (f"Paired against `{ref}` (same windows, GNSS noise and starts): the run-by-run "
              "difference of the max horizontal error, mean ± standard error (m), and the runs "
              "in which the filter's error is the smaller.")
    lines += ["", paired, "",
              "| outage | " + " | ".join(n for n in study.filters if n != ref) + " |",
              "|---|" + "---:|" * (len(study.filters) - 1)]
    for k, (start, dur) in enumerate(study.outages):
        cells = []
        for name in study.filters:
            if name == ref:
                continue
            d = study.max_error[name][:, k] - study.max_error[ref][:, k]
            se = float(np.std(d, ddof=1) / math.sqrt(d.size)) if d.size > 1 else float("nan")
            cells.append(f"{float(np.mean(d)):+.4g} ± {se:.3g} ({int(np.sum(d < 0))}/{d.size})")
        lines.append(f"| {start:g}+{dur:g} s | " + " | ".join(cells) + " |")
    lines += ["", "| filter | run NEES mean | run NEES median | GNSS updates rejected |",
              "|---|---:|---:|---:|"]
    for name in study.filters:
        lines.append(f"| {name} | {float(np.mean(study.nees[name])):.3g} | "
                     f"{float(np.median(study.nees[name])):.3g} | "
                     f"{int(np.sum(study.rejected[name]))} |")
    return "\n".join(lines)


def raw(study: OutageStudy) -> dict:
    """The study's per-run numbers, for --save."""
    per = {name: {"max_error": study.max_error[name].tolist(),
                  "end_nees": study.end_nees[name].tolist(),
                  "end_ratio": study.end_ratio[name].tolist(),
                  "nees": study.nees[name].tolist(),
                  "rejected": study.rejected[name].tolist()} for name in study.filters}
    return {"windows": [list(w) for w in study.windows], "outages": study.outages,
            "seed": study.seed, "filters": per}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=None,
                        help="runs per source (default: every window, 8 of imu1, 16 of imu2)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--dt-filter", type=float, default=1.0)
    parser.add_argument("--seed", type=int, default=2014)
    parser.add_argument("--quick", action="store_true",
                        help="the 3 min drive with two 30 s outages of `stochmod outages "
                             "--quick`")
    parser.add_argument("--save", type=Path, default=None, metavar="FILE",
                        help="write the per-run numbers of both studies to this JSON file")
    parser.add_argument("--keep", type=Path, default=None, metavar="DIR",
                        help="write the cut file and the four calibrations here (default: a "
                             "temporary folder)")
    args = parser.parse_args()
    if not IMU1.is_file() or not IMU2.is_file():
        print(f"the ADIS16405 recordings are not under {DATA}", file=sys.stderr)
        return 2
    if args.quick:
        from stochmod.cli.outages import QUICK_OUTAGES, QUICK_PROFILE
        profile, outages = QUICK_PROFILE, QUICK_OUTAGES
    else:
        profile, outages = DEFAULT_PROFILE, DEFAULT_OUTAGES
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        files = calibrations(work)
        describe(files)
        filters = {name: read_calibration(path) for name, path in files.items()}
        records = {name: calibration_record(path) for name, path in files.items()}
        half = records["gmwm"]
        sources = [("imu1, second half", IMU1, [(0.0, half)]), ("imu2", IMU2, [])]
        length = sum(s.duration for s in profile)
        saved = {}
        for label, path, exclude in sources:
            errors = static_errors(str(path), exclude=exclude)
            fit = len(errors.windows(math.floor(length * errors.freq) + 1))
            runs = fit if args.runs is None else min(args.runs, fit)
            t = time.perf_counter()
            study = outage_study(filters, errors=errors, runs=runs, seed=args.seed,
                                 profile=profile, outages=outages, rate=errors.freq,
                                 gyro_bias_sd=GYRO_BIAS_SD, accel_bias_sd=ACCEL_BIAS_SD,
                                 dt_filter=args.dt_filter, workers=args.workers,
                                 record=records)
            print(f"\n{label}: windows {list(study.windows)} of {path.name} "
                  f"({time.perf_counter() - t:.0f} s)")
            print(study.summary())
            print()
            print(markdown(study, label))
            saved[label] = raw(study)
    if args.save is not None:
        args.save.write_text(json.dumps(saved, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
