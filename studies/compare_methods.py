"""The numbers of docs/comparison.md: classical methods vs GMWM on one real recording.

    python studies/compare_methods.py                    # real data (../shared/data), ~1 min
    python studies/compare_methods.py --monte-carlo 100  # the simulations behind the test tolerances

Real data: ADIS16405 imu1 (`../shared/data/imudata/adis_16405_imu1.npz`), Gyro_X (deg/s ->
rad/s) and Accel_X (g -> m/s^2), mean removed, 100 Hz. For each column it runs the Allan (AV),
PSD, ACF, Burg AR(3), de-noised AR(3), AVWD and GMWM methods, prints each model's parameters in
datasheet units (stochmod.core.units), the GMWM objective of every model's wavelet variance against
the data's (stochmod.fit.classical.pipelines.compare_models), the per-level ratios, and the wall time
of each method. There is no peer to time against here (bench_allan / bench_gmwm do that); the
times only show what each method costs on 10^6 samples.

Monte Carlo: seeded simulations of the test cases of tests/test_pipelines.py (A: WN + GM + RW,
B: WN + BI + RW, C: GM + WN), R replications each (seeds 2000..), printing the mean, standard
deviation and range of each estimate / truth and the tolerance ``|bias| + 3 sd`` the tests use.
"""

from __future__ import annotations

import argparse
import datetime
import math
import sys
import time
from pathlib import Path

import numpy as np

import stochmod as sm
from stochmod.fit.classical import ar_model
from stochmod.empirical.ar_fit import fit_ar
from stochmod.fit.classical.pipelines import (
    acf_gm_model,
    av_model,
    avwd_model,
    compare_models,
    denoised_ar_model,
    psd_model,
)
from stochmod.empirical.allan_reading import DATASHEET_UNITS, TERMS
from stochmod.core.units import STANDARD_GRAVITY, convert, parse_unit

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "imudata"
FS = 100.0

# ----------------------------------------------------------------------------- real data


def _timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def datasheet(model: sm.Model, unit: str) -> str:
    """Physical parameters of every process of `model`, in the Allan summary's datasheet units
    (N in deg/sqrt(h) or m/s/sqrt(h), B-like sigmas in deg/h or ug, K in deg/h^1.5 ...)."""
    term_of = {template: name for name, (_, _, template) in TERMS.items()}
    targets = DATASHEET_UNITS[parse_unit(unit).kind]
    parts = []
    for label, proc in zip(model.labels, model.processes):
        for name, pv in proc.physical(model.freq).items():
            term = term_of.get(pv.unit)
            if term is None:
                parts.append(f"{label}.{name} {pv.value:.4g} {pv.unit}")
                continue
            src = pv.unit.replace("u", f"({unit})", 1)
            value = float(convert(pv.value, src, targets[term], kind=term))
            parts.append(f"{label}.{name} {value:.4g} {targets[term]}")
        if proc.family == "AR":
            phi = ", ".join(f"{v:.5g}" for v in proc.phi)
            parts.append(f"{label}.phi [{phi}]")
    return "; ".join(parts)


def real_column(name: str, x: np.ndarray, unit: str, gmwm_specs: list[str], level: int) -> None:
    """Every method on one column; prints parameters, objectives and per-level ratios."""
    print(f"\n## {name} ({unit}, mean removed, N = {x.size}, {FS:g} Hz)\n")
    results, times = {}, {}
    results["AV"], times["AV"] = _timed(lambda: av_model(x, FS, unit=unit))
    results["AVWD"], times["AVWD"] = _timed(lambda: avwd_model(x, FS, level=level, unit=unit))
    results["PSD"], times["PSD"] = _timed(lambda: psd_model(x, FS))
    results["ACF"], times["ACF"] = _timed(lambda: acf_gm_model(x, FS))
    results["ACF (LS)"], times["ACF (LS)"] = _timed(lambda: acf_gm_model(x, FS, use_ls=True))
    burg, times["Burg AR(3)"] = _timed(lambda: fit_ar(x, FS, 3))
    results["Burg AR(3)"] = ar_model(burg, FS)
    results["WD+AR(3)"], times["WD+AR(3)"] = _timed(lambda: denoised_ar_model(x, FS, 3, level=6))
    for spec in gmwm_specs:
        key = f"GMWM {spec}"
        results[key], times[key] = _timed(lambda spec=spec: sm.gmwm(x, spec, FS))

    print("### Parameters (datasheet units) and time\n")
    for key, res in results.items():
        model = getattr(res, "model", res)
        print(f"- {key} [{times[key]:.2f} s]: {model.name}: {datasheet(model, unit)}")
    av = results["AV"].reading
    print("\n### Allan reading\n")
    print(av.summary())
    print("\n### AVWD: Fig. 17 check\n")
    tau, ratio, inside = results["AVWD"].long_term_check()
    print("tau [s]: " + ", ".join(f"{t:.4g}" for t in tau))
    print("AV de-noised / raw: " + ", ".join(f"{r:.3f}" for r in ratio))
    print("inside raw CI: " + ", ".join("y" if i else "N" for i in inside))
    print("\n### PSD reading\n")
    print(results["PSD"].reading.summary())
    if results["PSD"].bias_tc is not None:
        print(f"GM correlation time from the Allan reading: {results['PSD'].bias_tc:g} s")
    print("\n### ACF caveats\n")
    for c in results["ACF"].fit.caveats:
        print(f"- {c}")
    for spec in gmwm_specs:
        g = results[f"GMWM {spec}"]
        print(f"\n### GMWM {spec}\n")
        print(g.summary())

    comp = compare_models(x, FS, results)
    print("\n### Objective against the raw signal's WV\n")
    print(comp.summary())
    print()
    print(comp.wv_table())
    den = results["AVWD"].denoised.denoising.signal
    dcomp = compare_models(den, FS, {k: results[k] for k in ("AVWD", "WD+AR(3)")})
    print(f"\n### Against the de-noised signal's WV ({level} levels, what a filter fed with the "
          "de-noised input sees)\n")
    print(dcomp.summary())
    print()
    print(dcomp.wv_table())


def real(data: Path) -> None:
    path = data / "adis_16405_imu1.npz"
    if not path.exists():
        sys.exit(f"{path} not found: pass --data DIR (the folder holding adis_16405_imu1.npz)")
    rec = np.load(path)
    print(f"# studies/compare_methods.py, {datetime.date.today().isoformat()}, stochmod "
          f"{sm.__version__}, numpy {np.__version__}")
    gx = np.deg2rad(rec["Gyro_X"])
    ax = rec["Accel_X"] * STANDARD_GRAVITY
    real_column("imu1 Gyro_X", gx - gx.mean(), "rad/s",
                ["2*GM+WN", "GM+WN+RW", "WN+GM", "AR(3)", "AR(2)+GM"], level=7)
    real_column("imu1 Accel_X", ax - ax.mean(), "m/s^2",
                ["3*GM+WN+RW", "GM+WN+RW", "AR(3)", "AR(2)+2*GM+RW"], level=7)


# ----------------------------------------------------------------------------- Monte Carlo

CASES = {
    # Case A is docs/allan.md's Monte Carlo case "WN 3e-4 + GM(sigma 1e-3, Tc 1 s) + RW 3e-4".
    "A": {"spec": f"WN(sigma2={(3e-4) ** 2 * FS!r})+GM(beta=1.0, sigma2=1e-6)"
                  f"+RW(sigma2={(3e-4) ** 2 / FS!r})",
          "truth": {"N": 3e-4, "K": 3e-4, "Tc": 1.0, "sigma": 1e-3}, "gmwm": "WN+GM+RW"},
    "B": {"spec": f"WN(sigma2={(1e-3) ** 2 * FS!r})+BI(B=2e-3, fc=1e-6)"
                  f"+RW(sigma2={(5e-4) ** 2 / FS!r})",
          "truth": {"N": 1e-3, "B": 2e-3, "K": 5e-4}, "gmwm": "WN+BI+RW"},
    "C": {"spec": f"GM(beta=1.0, sigma2=1e-6)+WN(sigma2={(1e-4) ** 2 * FS!r})",
          "truth": {"Tc": 1.0, "sigma2": 1e-6}, "gmwm": None},
}
N_SAMPLES = 1_000_000


def _gmwm_values(model: sm.Model) -> dict[str, float]:
    out = {}
    for p in model.processes:
        phys = p.physical(model.freq)
        if p.family == "WN":
            out["N"] = phys["N"].value
        elif p.family == "RW":
            out["K"] = phys["K"].value
        elif p.family == "GM":
            out["Tc"], out["sigma"] = phys["Tc"].value, phys["sigma"].value
        elif p.family == "BI":
            out["B"] = p.B
    return out


def one_run(case: str, seed: int) -> dict[str, float]:
    """Estimates / truth of one replication (NaN where a method gives nothing)."""
    cfg = CASES[case]
    truth = sm.model_from_spec(cfg["spec"], FS)
    t = cfg["truth"]
    x = truth.simulate(N_SAMPLES, seed)
    out: dict[str, float] = {}
    if case == "C":
        raw = acf_gm_model(x, FS)
        ls = acf_gm_model(x, FS, use_ls=True)
        out["ACF 1/e Tc"] = raw.fit.tc / t["Tc"]
        out["ACF LS Tc"] = 1.0 / ls.fit.beta_ls / t["Tc"]
        out["ACF LS sigma2"] = ls.fit.sigma2_ls / t["sigma2"]
        for order in (1, 3):
            ar = denoised_ar_model(x, FS, order, level=3)
            out[f"WD+AR({order}) Tc"] = ar.model.processes[0].physical(FS)["Tc"].value / t["Tc"]
            raw_ar = ar_model(fit_ar(x, FS, order), FS)
            out[f"AR({order}) Tc"] = raw_ar.processes[0].physical(FS)["Tc"].value / t["Tc"]
        return out
    av = av_model(x, FS)
    r = av.reading
    for name in ("N", "B", "K"):
        c = getattr(r, name)
        if name in t:
            out[f"AV {name}"] = math.nan if c is None else c.value / t[name]
    if case == "A" and r.B is not None:  # docs/allan.md: the matched GM's sigma
        out["AV sigma_GM matched"] = math.sqrt(r.B.line / 0.38113865810244997) / t["sigma"]
    wd = avwd_model(x, FS, level=7)
    tau, ratio, inside = wd.long_term_check()
    out["AVWD min ratio tau>=2 limit"] = float(ratio[tau >= 2 * wd.tau_limit].min())
    out["AVWD min ratio tau>=4 limit"] = float(ratio[tau >= 4 * wd.tau_limit].min())
    out["AVWD inside CI tau>=4 limit"] = float(inside[tau >= 4 * wd.tau_limit].all())
    ps = psd_model(x, FS)
    for name in ("N", "B", "K"):
        term = getattr(ps.reading, name)
        if name in t:
            out[f"PSD {name}"] = math.nan if term is None else term.value / t[name]
    g = sm.gmwm(x, cfg["gmwm"], FS)
    for k, v in _gmwm_values(g.model).items():
        if k in t:
            out[f"GMWM {k}"] = v / t[k]
    others = {"AV": av, "AVWD": wd, "PSD": ps, "WD+AR(3)": denoised_ar_model(x, FS, 3),
              "Burg AR(3)": ar_model(fit_ar(x, FS, 3), FS), "GMWM": g}
    try:
        others["ACF"] = acf_gm_model(x, FS)
    except sm.EstimationError:
        pass
    comp = compare_models(x, FS, others)
    out["GMWM smallest objective"] = float(comp.best.name == "GMWM")
    return out


def monte_carlo(reps: int) -> None:
    print(f"# Monte Carlo, {reps} replications per case, N = {N_SAMPLES}, {FS:g} Hz, seeds "
          f"2000..{2000 + reps - 1}, {datetime.date.today().isoformat()}")
    for case, cfg in CASES.items():
        t0 = time.perf_counter()
        runs = [one_run(case, 2000 + i) for i in range(reps)]
        print(f"\n## case {case}: {cfg['spec']} ({time.perf_counter() - t0:.0f} s)\n")
        print("| estimate / truth | found | mean | sd | min | max | tol = abs(bias) + 3 sd |")
        print("| --- | --- | --- | --- | --- | --- | --- |")
        for key in runs[0]:
            v = np.array([r.get(key, math.nan) for r in runs], dtype=float)
            ok = v[np.isfinite(v)]
            if ok.size == 0:
                print(f"| {key} | 0/{reps} | | | | | |")
                continue
            sd = float(ok.std(ddof=1)) if ok.size > 1 else 0.0
            mean = float(ok.mean())
            print(f"| {key} | {ok.size}/{reps} | {mean:.4f} | {sd:.4f} | {ok.min():.4f} | "
                  f"{ok.max():.4f} | {abs(mean - 1) + 3 * sd:.4f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help="folder of adis_16405_imu1.npz")
    parser.add_argument("--monte-carlo", type=int, metavar="R", default=0,
                        help="run the simulation study with R replications instead")
    args = parser.parse_args()
    if args.monte_carlo:
        monte_carlo(args.monte_carlo)
    else:
        real(args.data)


if __name__ == "__main__":
    main()
