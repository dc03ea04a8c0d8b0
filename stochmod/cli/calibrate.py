"""``stochmod calibrate``: select and fit a model per column, report, export the EKF augmentation."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from stochmod.cli._common import add_input_arguments, load_input, print_json, to_jsonable
from stochmod.examples import xsens_mtig
from stochmod.fit.selection import select
from stochmod.model import augment_axes
from stochmod.reporting import format_table
from stochmod.signal.wavelet_variance import wvar

__all__ = ["register", "run", "DEFAULT_CANDIDATES"]

#: Candidates tried when the user gives none: the usual inertial-sensor structures.
DEFAULT_CANDIDATES = ("WN", "GM+WN", "2*GM+WN", "3*GM+WN", "GM+WN+RW", "2*GM+WN+RW", "QN+WN+RW")


def register(subparsers: Any) -> None:
    """Add the ``calibrate`` subcommand."""
    p = subparsers.add_parser(
        "calibrate", help="select and fit a noise model per column (the main job)",
        description="Select a composite model per column by the GMWM and a wavelet-variance "
                    "information criterion, print a report, write calibration.json (models, "
                    "physical parameters with intervals, EKF augmentation at --dt) and figures. "
                    "Without FILE, runs on a simulated XSens MTi-G recording (Stebler et al. 2014, Table II).",
    )
    add_input_arguments(p, file_required=False)
    p.add_argument("--dt", type=float, default=None, help="Kalman filter step in s (default 1/freq)")
    p.add_argument("--out", default="stochmod-calibration", help="output folder")
    p.add_argument("--candidates", nargs="+", default=list(DEFAULT_CANDIDATES), metavar="SPEC",
                   help="candidate model specs (default: %(default)s)")
    p.add_argument("--n", type=int, default=2**17, help="samples of the bundled example (no FILE)")
    p.add_argument("--no-plots", action="store_true", help="do not write figures")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the calibration and write its outputs."""
    if args.file is None:
        rec = xsens_mtig(n=args.n).select(args.column)
        freq = float(args.freq or rec.freq)
    else:
        rec, freq = load_input(args)
    data = rec.data - rec.data.mean(axis=0)
    results = select(data, freq, candidates=args.candidates, names=list(rec.columns), progress=False)
    results = results if isinstance(results, list) else [results]
    dt = args.dt if args.dt is not None else 1.0 / freq
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    report: dict[str, Any] = {"source": rec.path, "freq": freq, "dt": dt, "columns": {}}
    rows = []
    for sel in results:
        best = sel.best
        aug = best.model.augment(dt)
        report["columns"][sel.column] = {
            "model": best.model.to_spec(), "name": best.model.name, "objective": best.objective,
            "physical": [vars_of(e) for e in best.physical()],
            "jtest": None if best.jtest is None else vars_of(best.jtest),
            "ranking": [vars_of(r) for r in sel.ranking],
            "augmentation": _augmentation_dict(aug),
        }
        for e in best.physical():
            rows.append([sel.column, best.model.name, e.name, e.value, e.low, e.high, e.unit])
    imu = augment_axes({sel.column: sel.best.model for sel in results}, dt)
    report["imu_augmentation"] = {
        "state_names": list(imu.state_names), "Phi": imu.Phi, "Q": imu.Q, "P0": imu.P0,
        "H": imu.H, "white_var": imu.white_var, "axes": list(imu.axes),
    }
    (out / "calibration.json").write_text(json.dumps(to_jsonable(report), indent=1, sort_keys=True))
    figures = [] if args.no_plots else _figures(results, data, freq, out)
    if args.json:
        print_json(report)
        return 0
    print(format_table(["column", "model", "parameter", "value", "95% low", "95% high", "unit"], rows,
                       title=f"stochmod calibrate: {rec.path} ({data.shape[0]} samples at {freq:g} Hz)"))
    for sel in results:
        jt = sel.best.jtest
        if jt is not None:
            print(f"{sel.column}: J-test p-value {jt.pvalue:.3g} (df {jt.df})")
    print(f"wrote {out / 'calibration.json'}" + (f" and {len(figures)} figure(s)" if figures else ""))
    return 0


def vars_of(obj: Any) -> dict[str, Any]:
    """Fields of an attrs result row as a dict."""
    import attrs

    return attrs.asdict(obj)


def _augmentation_dict(aug: Any) -> dict[str, Any]:
    return {"state_names": list(aug.state_names), "Phi": aug.Phi, "Q": aug.Q, "H": aug.H,
            "P0": aug.P0, "white_var": aug.white_var, "dt": aug.dt}


def _figures(results: list[Any], data: np.ndarray, freq: float, out: Path) -> list[Path]:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    paths = []
    for i, sel in enumerate(results):
        best, emp = sel.best, sel.empirical
        J = best.levels
        sims = np.array([wvar(best.model.simulate(data.shape[0], seed), freq, levels=J).wv
                         for seed in range(20)])
        fig, ax = plt.subplots(figsize=(6, 4.5))
        for s in sims:
            ax.loglog(emp.tau[:J], np.sqrt(s), color="0.8", lw=0.8)
        ax.fill_between(emp.tau[:J], np.sqrt(emp.ci_low[:J]), np.sqrt(emp.ci_high[:J]),
                        color="C0", alpha=0.25, label="95% CI")
        ax.loglog(emp.tau[:J], np.sqrt(emp.wv[:J]), "o", color="C0", label="empirical")
        ax.loglog(emp.tau[:J], np.sqrt(best.model_wv()), "^-", color="C3", label=f"fit {best.model.name}")
        ax.set_xlabel("tau [s]")
        ax.set_ylabel("wavelet deviation (sqrt WV)")
        ax.set_title(f"{sel.column}: {best.model.name}")
        ax.legend()
        path = out / f"{sel.column}.png"
        fig.tight_layout()
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths
