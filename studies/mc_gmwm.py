"""Monte Carlo study of the GMWM estimator: bias, RMSE, interval coverage, J-test size, fit time.

For each model below, R seeded simulations of N samples at 100 Hz are fitted by
``stochmod.gmwm`` twice: with the default weighting (``"diagonal"``, all levels, intervals
from the eq. 17 covariance of the data) and with ``weighting="optimal"`` (Omega = V^-1 of
eq. 17, on the levels whose equivalent degrees of freedom ``M_j / 2^j`` are at least
``OPT_MIN_EDF``, fewer when V is not positive definite there). Per parameter it reports
the bias, RMSE, relative RMSE, the median absolute relative error and the coverage of the
95 % intervals of ``.parameters()``; per model the J-test rejection rate at 5 %, the share
of fits whose objective is worse than the truth's (same Omega: a search failure), the
inference failures and the mean fit times. Repeated components are compared in gmwm's
canonical order (largest first parameter first: GM fastest first), in which the truths
below are written.

Run (deterministic: simulation r of a case uses ``SeedSequence(SEED, spawn_key=(case.seed_key, r))``,
gmwm its default ``rng=0``)::

    python studies/mc_gmwm.py                       # all models, default R, 2 workers
    python studies/mc_gmwm.py --only 2GM+WN --reps 20 --out /tmp/mc.md

With ``--bootstrap B`` the study checks the parametric bootstrap instead
(:mod:`stochmod.fit.bootstrap`): each record gets the default fit only and B bootstrap
replicates (seeded by ``SeedSequence(SEED, spawn_key=(case.seed_key, r, 1))``). The fit (its
signal dropped, its eq. 17 V kept) and the draws are saved with ``--save`` after every
record; the tables are computed from them: per parameter how often the identification
diagnostic flags it and the coverage of the asymptotic, bootstrap (basic, the default; BC;
percentile) and ``intervals="auto"`` intervals with binomial standard errors, per model the
J-test size with the chi-square, bootstrap and "auto" p-values. ``--load`` recomputes the
tables from saved fits and draws with the installed stochmod (a changed diagnostic or
interval rule, no refits); a run cut short leaves the records it finished. Cases run in the
order of ``--only``; ``--first`` starts at another record, and ``--load`` repeated merges
runs that extend one another::

    python studies/mc_gmwm.py --bootstrap 200 --reps 40 --save /tmp/boot.pkl --out /tmp/mc_boot.md
    python studies/mc_gmwm.py --load /tmp/boot.pkl          # the tables again, no fits
    python studies/mc_gmwm.py --bootstrap 200 --first 40 --reps 40 --save /tmp/boot2.pkl
    python studies/mc_gmwm.py --load /tmp/boot.pkl --load /tmp/boot2.pkl   # 80 records

Run time with the default settings: about 16 min wall clock with 2 workers on the 2-core
machine; the AR(2) fits take half of it (their Jacobian is numerical: ~5 s per fit). Reruns give identical tables (only the times change). The
markdown tables go to stdout and, with ``--out``, to a file (docs/gmwm_monte_carlo.md
quotes them).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import pickle
import shlex
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor

import attrs
import numpy as np

import stochmod
from stochmod.core.errors import EstimationError
from stochmod.fit.bootstrap import (
    DEFAULT_METHOD,
    INTERVAL_METHODS,
    bootstrap,
    bootstrap_draws,
    identification,
    with_intervals,
)
from stochmod.fit.gmwm import gmwm

FREQ = 100.0
SEED = 20240917


@dataclasses.dataclass(frozen=True)
class Case:
    """One Monte Carlo design: a true model, the sample size and the number of replications."""

    name: str
    spec: str
    n: int
    reps: int
    seed_key: int  # cases with the same key fit the same simulations
    start_at_truth: bool = False  # also give gmwm the truth as a start (separates search from statistics)


# Realistic MEMS-gyro values in rad/s at 100 Hz (ADIS16405-like white noise, 3e-6 (rad/s)^2
# per sample, i.e. 0.01 (deg/s)^2); GM correlation times 0.5 s, 50 s, 2000 s.
AR2_SPEC = "AR(phi=[1.949, -0.94905], sigma2=1e-10) + WN(sigma2=3e-6)"
CASES = (
    Case("2GM+WN", "GM(beta=2.0, sigma2=1e-6) + GM(beta=0.02, sigma2=1e-7) + WN(sigma2=3e-6)",
         2**18, 100, 0),
    Case("3GM+WN", "GM(beta=2.0, sigma2=1e-6) + GM(beta=0.02, sigma2=1e-7) "
         "+ GM(beta=5e-4, sigma2=2e-7) + WN(sigma2=3e-6)", 2**18, 100, 1),
    Case("3GM+WN (N=2^20)", "GM(beta=2.0, sigma2=1e-6) + GM(beta=0.02, sigma2=1e-7) "
         "+ GM(beta=5e-4, sigma2=2e-7) + WN(sigma2=3e-6)", 2**20, 50, 2),
    Case("GM+WN+RW", "GM(beta=0.1, sigma2=1e-7) + WN(sigma2=3e-6) + RW(sigma2=1e-12)", 2**18, 100, 3),
    Case("QN+WN+RW+RR", "QN(Q2=1e-7) + WN(sigma2=3e-6) + RW(sigma2=1e-12) + RR(omega=1e-8)",
         2**18, 100, 4),
    # AR(2) with real roots 0.999 and 0.95 (e-folding times 10 s and 0.2 s)
    Case("AR(2)+WN", AR2_SPEC, 2**18, 30, 5),
    Case("AR(2)+WN, truth among the starts", AR2_SPEC, 2**18, 30, 5, start_at_truth=True),
)


def _intervals(fit) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """Estimates, interval ends (NaN when the inference fails) and the failure kind."""
    est = fit.model.vector()[fit.free_mask]
    try:
        params = fit.parameters()
    except EstimationError:
        nan = np.full(est.size, np.nan)
        return est, nan, nan, "singular"
    low = np.array([p.low for p in params])
    high = np.array([p.high for p in params])
    se = np.array([p.std_error for p in params])
    return est, low, high, ("zero-se" if np.any(se == 0) else "")


def _truth_objective(fit, truth) -> float:
    r = fit.empirical.wv[: fit.levels] - truth.wv(fit.levels)
    return float(r @ fit.omega @ r)


def one_replication(case: Case, rep: int) -> dict:
    """Simulate replication `rep` of `case` and fit it with both weightings."""
    truth = stochmod.model_from_spec(case.spec, FREQ)
    x = truth.simulate(case.n, np.random.default_rng(np.random.SeedSequence(SEED, spawn_key=(case.seed_key, rep))))
    out: dict = {"rep": rep}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # every warning is a defect worth counting
        t0 = time.perf_counter()
        starts = (truth,) if case.start_at_truth else ()
        fit = gmwm(x, truth.freed(), FREQ, starts=starts)
        out["time"] = time.perf_counter() - t0
        out["levels"] = fit.levels
        t0 = time.perf_counter()
        out["est"], out["low"], out["high"], out["fail"] = _intervals(fit)
        out["time_inference"] = time.perf_counter() - t0
        out["search_worse"] = fit.objective > _truth_objective(fit, truth) * (1 + 1e-9)
        jt = fit.jtest
        out["jtest_p"] = np.nan if jt is None else jt.pvalue
        t0 = time.perf_counter()
        opt = gmwm(x, truth.freed(), FREQ, weighting="optimal", starts=starts)
        out["time_opt"] = time.perf_counter() - t0
        out["levels_opt"] = opt.levels
        out["est_opt"], out["low_opt"], out["high_opt"], out["fail_opt"] = _intervals(opt)
        out["search_worse_opt"] = opt.objective > _truth_objective(opt, truth) * (1 + 1e-9)
    out["warnings"] = sorted({f"{w.category.__name__}: {w.message}" for w in caught})
    return out


def one_bootstrap_replication(case: Case, rep: int, n_boot: int) -> dict:
    """Simulate replication `rep` of `case`, fit it (default weighting) and draw `n_boot`
    bootstrap replicates of the fit. The fit (without its signal, with its eq. 17 V) and the
    draws are kept: :func:`summarise_bootstrap` computes the diagnostic, every interval and
    both J-test p-values from them with the installed stochmod, so ``--load`` re-evaluates a
    saved run under the current rules without refitting."""
    truth = stochmod.model_from_spec(case.spec, FREQ)
    x = truth.simulate(case.n, np.random.default_rng(np.random.SeedSequence(SEED, spawn_key=(case.seed_key, rep))))
    out: dict = {"rep": rep}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        t0 = time.perf_counter()
        starts = (truth,) if case.start_at_truth else ()
        fit = gmwm(x, truth.freed(), FREQ, starts=starts)
        out["time"] = time.perf_counter() - t0
        try:
            covariance = fit.wv_covariance
        except EstimationError:
            covariance = None
        _ = fit.jtest_form
        t0, c0 = time.perf_counter(), time.process_time()
        out["draws"] = bootstrap_draws(fit, n_boot, rng=np.random.SeedSequence(SEED, spawn_key=(case.seed_key, rep, 1)))
        out["time_boot"] = time.perf_counter() - t0
        out["cpu_boot"] = time.process_time() - c0
        out["fit"] = fit if covariance is None else attrs.evolve(fit, signal=None, covariance=covariance)
    out["warnings"] = sorted({f"{w.category.__name__}: {w.message}" for w in caught})
    return out


def _ends(params) -> np.ndarray:
    return np.array([[p.low, p.high] for p in params])


def evaluate_bootstrap(record: dict) -> dict:
    """Diagnostic, interval ends of every kind and J-test p-values of one saved record."""
    fit, draws = record["fit"], record["draws"]
    out: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out["est"], out["low"], out["high"], out["fail"] = _intervals(fit)
        out["flagged"] = identification(fit).flagged
        jt = fit.jtest
        out["jtest_p"] = np.nan if jt is None else jt.pvalue
        boot = bootstrap(fit, draws=draws)
        res = boot.resampling
        for method in INTERVAL_METHODS:
            ends = np.array([res.interval(i, method=method)[1:] for i in range(out["est"].size)])
            out[f"low_{method}"], out[f"high_{method}"] = ends[:, 0], ends[:, 1]
        bj = res.jtest()
        out["jtest_p_boot"] = np.nan if bj is None else bj.pvalue
        try:
            auto = with_intervals(fit, "auto", draws=draws)
            out["low_auto"], out["high_auto"] = _ends(auto.parameters()).T
        except EstimationError:  # an unflagged parameter's asymptotic interval fails
            out["low_auto"] = out["high_auto"] = np.full(out["est"].size, np.nan)
            auto = with_intervals(fit, "auto", draws=draws)
        ja = auto.jtest
        out["jtest_p_auto"] = np.nan if ja is None else ja.pvalue
    out["boot_failed"] = draws.failed
    return out


def _rate(hits: np.ndarray) -> str:
    """A proportion with its binomial standard error, e.g. ``0.93 (0.03)``."""
    p, n = float(np.mean(hits)), hits.size
    return f"{p:.2f} ({np.sqrt(p * (1 - p) / n):.2f})"


def summarise_bootstrap(case: Case, records: list[dict], n_boot: int) -> str:
    """Markdown table of one case's bootstrap study (from the saved fits and draws)."""
    truth = stochmod.model_from_spec(case.spec, FREQ)
    names, tv = truth.param_names, truth.vector()
    R = len(records)
    results = [evaluate_bootstrap(r) for r in records]

    def covered(key: str) -> np.ndarray:
        low = np.array([r[f"low{key}"] for r in results])
        high = np.array([r[f"high{key}"] for r in results])
        return (low <= tv) & (tv <= high)  # NaN interval = not covered

    flagged = np.array([r["flagged"] for r in results])
    asym = covered("")
    boot = {m: covered(f"_{m}") for m in INTERVAL_METHODS}
    auto = covered("_auto")
    others = [m for m in INTERVAL_METHODS if m != DEFAULT_METHOD]
    rows = [("| parameter | truth | flagged | cover asympt. | cover boot. "
             f"{DEFAULT_METHOD} (default) | "
             + " | ".join(f"cover boot. {m}" for m in others) + " | cover auto |"),
            "|---|---|---|---|---|" + "---|" * len(others) + "---|"]
    for i, name in enumerate(names):
        rows.append(f"| {name} | {tv[i]:.4g} | {flagged[:, i].mean():.2f} | {_rate(asym[:, i])} "
                    f"| {_rate(boot[DEFAULT_METHOD][:, i])} | "
                    + " | ".join(_rate(boot[m][:, i]) for m in others)
                    + f" | {_rate(auto[:, i])} |")
    p = np.array([r["jtest_p"] for r in results])
    pb = np.array([r["jtest_p_boot"] for r in results])
    pa = np.array([r["jtest_p_auto"] for r in results])
    ok = np.isfinite(p) & np.isfinite(pb)
    any_flag = flagged.any(axis=1)
    jt = (f"chi-square {_rate(p[ok] < 0.05)}, bootstrap {_rate(pb[ok] < 0.05)}, auto "
          f"{_rate(pa[ok] < 0.05)} ({ok.sum()} tests)") if ok.any() else "n/a"
    lines = [
        f"### {case.name}: R = {R}, N = {case.n} (2^{int(np.log2(case.n))}), 100 Hz, B = {n_boot}",
        "",
        f"Truth `{case.spec}`.",
        "",
        *rows,
        "",
        f"- J-test rejection rate at 5 %: {jt}",
        f"- records where the diagnostic flags some parameter: {any_flag.mean():.2f}",
        (f"- inference failures of the asymptotic intervals: {sum(r['fail'] != '' for r in results)}/{R}; "
         f"failed bootstrap refits: {sum(r['boot_failed'] for r in results)} of {R * n_boot}"),
        f"- replications with a warning: {sum(bool(r['warnings']) for r in records)}"
        + "".join(f"; {m}" for m in sorted({m for r in records for m in r["warnings"]})),
        (f"- mean time: fit {np.mean([r['time'] for r in records]):.2f} s; bootstrap "
         f"{np.mean([r['time_boot'] for r in records]):.1f} s wall, "
         f"{np.mean([r['cpu_boot'] for r in records]):.1f} s CPU"),
    ]
    return "\n".join(lines)


def summarise(case: Case, results: list[dict]) -> str:
    """Markdown tables of one case."""
    truth = stochmod.model_from_spec(case.spec, FREQ)
    names = truth.param_names
    tv = truth.vector()
    est = np.array([r["est"] for r in results])
    est_o = np.array([r["est_opt"] for r in results])

    def cover(key: str) -> np.ndarray:
        low = np.array([r[f"low{key}"] for r in results])
        high = np.array([r[f"high{key}"] for r in results])
        return np.mean((low <= tv) & (tv <= high), axis=0)  # NaN interval = not covered

    err, err_o = est - tv, est_o - tv
    rmse, rmse_o = np.sqrt(np.mean(err**2, axis=0)), np.sqrt(np.mean(err_o**2, axis=0))
    rows = [("| parameter | truth | mean est. | bias | RMSE | rel. RMSE | median abs. rel. err. "
             "| cover 95 % | RMSE (opt.) | cover 95 % (opt.) |"),
            "|---|---|---|---|---|---|---|---|---|---|"]
    cov, cov_o = cover(""), cover("_opt")
    for i, name in enumerate(names):
        rows.append(
            f"| {name} | {tv[i]:.4g} | {est[:, i].mean():.4g} | {err[:, i].mean():+.3g} | {rmse[i]:.3g} "
            f"| {rmse[i] / abs(tv[i]):.3g} | {np.median(np.abs(err[:, i] / tv[i])):.3g} | {cov[i]:.2f} "
            f"| {rmse_o[i]:.3g} | {cov_o[i]:.2f} |")
    gms = [i for i, n in enumerate(names) if n.startswith("GM") and n.endswith(".beta")]
    if len(gms) >= 2:  # the slowest GM's RW-equivalent increment variance 2 beta sigma2 / freq
        b = gms[-1]
        q_true = 2 * tv[b] * tv[b + 1] / FREQ
        q, q_o = 2 * est[:, b] * est[:, b + 1] / FREQ, 2 * est_o[:, b] * est_o[:, b + 1] / FREQ
        e, e_o = q - q_true, q_o - q_true
        r, r_o = np.sqrt(np.mean(e**2)), np.sqrt(np.mean(e_o**2))
        label = names[b].split(".")[0]
        rows.append(f"| {label}: 2 beta sigma2 / freq (derived) | {q_true:.4g} | {q.mean():.4g} | {e.mean():+.3g} "
                    f"| {r:.3g} | {r / q_true:.3g} | {np.median(np.abs(e / q_true)):.3g} | - | {r_o:.3g} | - |")
    R = len(results)
    p = np.array([r["jtest_p"] for r in results])
    jt = f"{np.mean(p[np.isfinite(p)] < 0.05):.2f} ({np.isfinite(p).sum()} tests)" if np.isfinite(p).any() else "n/a"
    fails = sum(r["fail"] != "" for r in results)
    fails_o = sum(r["fail_opt"] != "" for r in results)
    levels_o = sorted({r["levels_opt"] for r in results})
    head = [
        f"### {case.name}: R = {R}, N = {case.n} (2^{int(np.log2(case.n))}), 100 Hz",
        "",
        f"Truth `{case.spec}`.",
        "",
        *rows,
        "",
        f"- J-test rejection rate at 5 % (default fit): {jt}",
        (f"- fits whose objective exceeds the truth's (same Omega): default {np.mean([r['search_worse'] for r in results]):.2f}, "
         f"optimal {np.mean([r['search_worse_opt'] for r in results]):.2f}"),
        (f"- inference failures (singular D'WD or a zero std. error; counted as not covering): "
         f"default {fails}/{R}, optimal {fails_o}/{R}"),
        f"- replications with a warning: {sum(bool(r['warnings']) for r in results)}"
        + "".join(f"; {m}" for m in sorted({m for r in results for m in r["warnings"]})),
        f"- levels: default J = {results[0]['levels']}; optimal weighting J: {levels_o}",
        (f"- mean time: default fit {np.mean([r['time'] for r in results]):.2f} s + intervals "
         f"{np.mean([r['time_inference'] for r in results]):.2f} s; optimal fit (with eq. 17 V) "
         f"{np.mean([r['time_opt'] for r in results]):.2f} s"),
    ]
    return "\n".join(head)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", action="append", help="case name (repeatable); default all")
    parser.add_argument("--reps", type=int, help="replications per case (default: each case's R)")
    parser.add_argument("--n", type=int, help="sample size for every chosen case (default: each case's N)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", help="also write the markdown tables to this file")
    parser.add_argument("--bootstrap", type=int, metavar="B",
                        help="bootstrap study with B replicates per record (default fit only)")
    parser.add_argument("--save", help="bootstrap study: also pickle the per-record results here")
    parser.add_argument("--first", type=int, default=0,
                        help="bootstrap study: index of the first record (default 0), so that "
                        "runs side by side extend one another")
    parser.add_argument("--load", action="append",
                        help="bootstrap study: summarise the results pickled by --save (no "
                        "fits; repeatable: the records of the files together, each once)")
    args = parser.parse_args(argv)
    by_name = {c.name: c for c in CASES}
    unknown = sorted(set(args.only or ()) - set(by_name))
    if unknown:
        parser.error(f"unknown case(s) {unknown}; choose from {sorted(by_name)}")
    chosen = [dataclasses.replace(c, n=args.n or c.n, reps=args.reps or c.reps)
              for c in ([by_name[n] for n in args.only] if args.only else CASES)]  # --only's order
    t_start = time.perf_counter()
    if args.load:
        merged: dict[str, dict[int, dict]] = {}
        n_boot = set()
        for path in args.load:
            with open(path, "rb") as fh:
                saved = pickle.load(fh)
            n_boot.add(saved["n_boot"])
            for name, records in saved["results"].items():
                merged.setdefault(name, {}).update((r["rep"], r) for r in records)
        if len(n_boot) != 1:
            parser.error(f"the files have different B: {sorted(n_boot)}")
        sections = [summarise_bootstrap(c, [merged[c.name][k] for k in sorted(merged[c.name])],
                                        next(iter(n_boot)))
                    for c in chosen if merged.get(c.name)]
        print("\n\n".join(sections))
        return
    with ProcessPoolExecutor(args.workers) as pool:
        if args.bootstrap:
            futures = [[pool.submit(one_bootstrap_replication, c, r, args.bootstrap)
                        for r in range(args.first, args.first + c.reps)] for c in chosen]
            done: dict[str, list[dict]] = {c.name: [] for c in chosen}
            for c, fs in zip(chosen, futures):  # in order; progress on stderr
                for r, f in enumerate(fs, start=args.first):
                    done[c.name].append(f.result())
                    print(f"{c.name} {r} done", file=sys.stderr, flush=True)
                    if args.save:  # after every record: a run cut short keeps what it did
                        with open(args.save, "wb") as fh:
                            pickle.dump({"n_boot": args.bootstrap, "results": done}, fh)
            sections = [summarise_bootstrap(c, done[c.name], args.bootstrap) for c in chosen]
        else:
            futures = [[pool.submit(one_replication, c, r) for r in range(c.reps)] for c in chosen]
            sections = [summarise(c, [f.result() for f in fs]) for c, fs in zip(chosen, futures)]
    elapsed = time.perf_counter() - t_start
    text = "\n\n".join([
        (f"Command: `{shlex.join(['python', 'studies/mc_gmwm.py', *(argv or [])])}`, "
         f"{datetime.date.today().isoformat()}, stochmod {stochmod.__version__}, "
         f"{args.workers} workers, total {elapsed / 60:.1f} min wall clock."),
        *sections,
    ])
    print(text)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
