"""``stochmod combine``: fuse time-aligned recordings of redundant sensors into a synthetic one.

Each FILE is one sensor (or IMU); columns with the same name across the files are the same
axis. Every column is combined by the chosen combiner plugin (``stochmod combiners`` lists
them), the synthetic signal is written to an ``.npz`` readable by the other subcommands, and
the per-sensor volatility parameters and the noise reduction are printed.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from stochmod.core.checks import check_freq
from stochmod.cli._common import print_json
from stochmod.redundant.combination import CombinationResult, combine
from stochmod.core.errors import InputError
from stochmod.io.recording import Recording, read_recording
from stochmod.plugin.registry import combiner_names
from stochmod.core.tables import format_table

__all__ = ["register", "run", "load_sensors", "combiner_options", "RATE_TOLERANCE",
           "MEAN_WEIGHT_TOLERANCE"]

#: Relative difference of the files' sampling rates above which they are not one time base.
RATE_TOLERANCE = 1e-3
#: Largest difference of a weight from ``1/n`` of a combination that is the mean.
MEAN_WEIGHT_TOLERANCE = 1e-6


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``combine`` subcommand."""
    p = subparsers.add_parser(
        "combine",
        help="fuse redundant sensors (one FILE each) into a synthetic signal",
        description=(
            "Combine time-aligned recordings of redundant sensors, one FILE per sensor, column by "
            "column (columns of the same name are the same axis), with a combiner plugin: mean "
            "(synthetic IMU, eq. 1 of Waegli et al. 2010), averaged-volatility (eqs. 2-3), garch "
            "(ARMA + GARCH per sensor, weights 1/sigma_i^2(t), eq. 12), inverse-variance (static "
            "weights from each sensor's model: --calibration, one per FILE), or any installed one. "
            "Writes OUT (.npz: the synthetic columns, '<column>_variance' and '<column>_weights' "
            "(T x n), 'freq') and, with matplotlib, OUT with suffix .png (volatilities and weights "
            "over time)."
        ),
    )
    p.add_argument("files", metavar="FILE", nargs="+", help="one recording per sensor (.csv/.npy/.npz)")
    p.add_argument("--method", default="mean",
                   help="combiner name (see `stochmod combiners`; default mean)")
    p.add_argument("--column", action="append", default=None, metavar="C",
                   help="column name to combine; repeat for several (default: every column)")
    p.add_argument("--freq", type=float, default=None, help="sampling frequency in Hz (else from the files)")
    p.add_argument("--scale", type=float, default=1.0,
                   help="multiply the data by this factor first (e.g. 0.017453292519943295 for deg/s)")
    p.add_argument("--calibration", action="append", default=None, metavar="JSON",
                   help="calibration.json of a sensor (inverse-variance); one per FILE, in order")
    p.add_argument("--tau", type=float, default=None,
                   help="inverse-variance: averaging time (s) of the wavelet variance used as level")
    p.add_argument("--half-window", type=int, default=None,
                   help="averaged-volatility: T of the 2T+1-sample window (default 100)")
    p.add_argument("--arma", type=int, nargs=2, default=None, metavar=("P", "Q"),
                   help="garch: fixed ARMA orders (default: chosen by AIC)")
    p.add_argument("--garch", type=int, nargs=2, default=None, metavar=("P", "Q"),
                   help="garch: fixed GARCH orders (default: grown until Engle's LM test passes)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="garch: fit the sensors in N processes at once (same result as serial)")
    p.add_argument("--out", default="synthetic.npz", help="output .npz (default synthetic.npz)")
    p.add_argument("--no-plots", action="store_true", help="do not write the figure")
    p.add_argument("--json", action="store_true", help="print machine-readable JSON")
    p.set_defaults(func=run)


def load_sensors(files: list[str], columns: list[str] | None) -> tuple[list[Recording], tuple[str, ...]]:
    """Read each file; check that they share the requested columns and their length."""
    recs = [read_recording(f) for f in files]
    if len(recs) < 2:
        raise InputError("combining needs at least two FILEs (one per sensor)")
    names = tuple(columns) if columns else recs[0].columns
    for rec in recs:
        missing = [c for c in names if c not in rec.columns]
        if missing:
            raise InputError(f"{rec.path} has no column(s) {missing}; its columns are {list(rec.columns)}")
    lengths = {rec.data.shape[0] for rec in recs}
    if len(lengths) != 1:
        raise InputError(f"the recordings have different lengths {sorted(lengths)}: align them first")
    rates = [rec.freq for rec in recs if rec.freq is not None]
    if rates and max(rates) - min(rates) > RATE_TOLERANCE * max(rates):
        listed = ", ".join(f"{rec.path}: {rec.freq:g} Hz" for rec in recs if rec.freq is not None)
        raise InputError(f"the recordings have different sampling rates ({listed}): resample "
                         "them to one rate and align them first")
    return [rec.select(list(names)) for rec in recs], names


def combiner_options(args: argparse.Namespace) -> dict[str, Any]:
    """Options of the chosen combiner from the command line (only those given)."""
    opts: dict[str, Any] = {}
    if args.calibration is not None:
        if len(args.calibration) != len(args.files):
            raise InputError(f"{len(args.calibration)} --calibration file(s) for {len(args.files)} FILEs")
        opts["calibrations"] = args.calibration
    if args.tau is not None:
        opts["tau"] = args.tau
    if args.half_window is not None:
        opts["half_window"] = args.half_window
    if args.arma is not None:
        opts["arma"] = tuple(args.arma)
    if args.garch is not None:
        opts["garch"] = tuple(args.garch)
    if getattr(args, "workers", None) is not None:
        if args.method != "garch":
            raise InputError(f"--workers applies to --method garch, not {args.method!r}")
        opts["workers"] = args.workers
    return opts


def _sensor_rows(column: str, res: CombinationResult, files: list[str]) -> list[list[Any]]:
    rows = []
    for i, path in enumerate(files):
        fit = next((f for f in res.sensors if getattr(f, "sensor", None) == i), None)
        sv = "-" if res.sensor_variance is None else float(np.mean(np.asarray(res.sensor_variance)[i]))
        if fit is not None:
            g = fit.garch
            params = (f"ARMA{fit.arma.order} GARCH{g.order}: omega {g.omega:.4g}, alpha "
                      f"{np.array2string(g.alpha, precision=4)}, beta {np.array2string(g.beta, precision=4)}")
        else:
            params = "-"
        rows.append([column, Path(path).name, float(np.mean(res.weights[i])), sv, params])
    return rows


def _is_mean(res: CombinationResult) -> bool:
    """Whether a combination's weights are the mean's, ``1/n`` at every sample, to
    :data:`MEAN_WEIGHT_TOLERANCE` (two sensors' volatility fits agree to their optimizer's
    tolerance, not to rounding)."""
    return bool(np.all(np.abs(res.weights - 1.0 / res.n_sensors) <= MEAN_WEIGHT_TOLERANCE))


def _figure(results: dict[str, CombinationResult], freq: float, path: Path) -> Path | None:
    import importlib.util

    if importlib.util.find_spec("matplotlib") is None:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(results), figsize=(5 * len(results), 6), squeeze=False, sharex=True)
    for k, (column, res) in enumerate(results.items()):
        t = np.arange(res.signal.size) / freq
        step = max(1, t.size // 4000)
        top, bottom = axes[0, k], axes[1, k]
        if res.sensor_variance is not None:
            sv = np.broadcast_to(res.sensor_variance, res.weights.shape) if np.ndim(res.sensor_variance) > 1 \
                else np.broadcast_to(np.asarray(res.sensor_variance)[:, None], res.weights.shape)
            for i in range(res.n_sensors):
                top.plot(t[::step], np.sqrt(sv[i, ::step]), lw=0.8, label=f"sensor {i}")
        top.plot(t[::step], np.sqrt(res.variance[::step]), "k", lw=1.2, label="synthetic")
        top.set_yscale("log")
        top.set_title(f"{column}: {res.method}")
        top.set_ylabel("estimated error std [u]")
        top.legend(fontsize=7)
        for i in range(res.n_sensors):
            bottom.plot(t[::step], res.weights[i, ::step], lw=0.8)
        bottom.set_xlabel("time [s]")
        bottom.set_ylabel("weight")
    fig.tight_layout()
    out = path.with_suffix(".png")
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def run(args: argparse.Namespace) -> int:
    """Combine, report, write the synthetic .npz (+ figure)."""
    if args.method not in combiner_names():
        raise InputError(f"unknown --method {args.method!r}; registered: {', '.join(combiner_names())}")
    if not args.scale > 0:
        raise InputError(f"--scale must be positive, got {args.scale}")
    if Path(args.out).suffix != ".npz":
        raise InputError(f"--out {args.out}: the synthetic signal is written as .npz; "
                         "give a path that ends in .npz")
    recs, names = load_sensors(args.files, args.column)
    freq = args.freq if args.freq is not None else recs[0].freq
    if freq is None:
        raise InputError("the files do not record their sampling frequency: pass --freq HZ")
    freq = check_freq(freq, name="--freq")
    opts = combiner_options(args)
    if "tau" in opts:
        opts["freq"] = freq
    results: dict[str, CombinationResult] = {}
    for k, column in enumerate(names):
        x = np.stack([rec.data[:, k] for rec in recs]) * args.scale
        col_opts = dict(opts)
        if "calibrations" in col_opts:
            col_opts["columns"] = [column]
        results[column] = combine(x, args.method, **col_opts)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, np.ndarray] = {"freq": np.array(freq)}
    for column, res in results.items():
        arrays[column] = res.signal
        arrays[f"{column}_variance"] = res.variance
        arrays[f"{column}_weights"] = res.weights.T
    np.savez(out, **arrays)
    figure = None if args.no_plots else _figure(results, freq, out)
    same = [c for c, r in results.items() if args.method != "mean" and _is_mean(r)]
    if args.json:
        print_json({"method": args.method, "files": args.files, "freq": freq, "out": str(out),
                    "columns": {c: {"noise_reduction": r.noise_reduction,
                                    "mean_weights": r.weights.mean(axis=1),
                                    "mean_variance": float(np.mean(r.variance)),
                                    "info": r.info} for c, r in results.items()},
                    "weights_of_the_mean": same})
        return 0
    rows = [row for column, res in results.items() for row in _sensor_rows(column, res, args.files)]
    print(format_table(["column", "sensor", "mean weight", "mean error variance", "volatility model"],
                       rows, title=f"stochmod combine --method {args.method}: {len(recs)} sensors, "
                                   f"{recs[0].data.shape[0]} samples at {freq:g} Hz"))
    print()
    print(format_table(
        ["column", "synthetic error std", "noise reduction"],
        [[c, float(np.sqrt(np.mean(r.variance))),
          "-" if r.noise_reduction is None else f"{100 * r.noise_reduction:.1f}%"] for c, r in results.items()]))
    print(f"\nassumes: {next(iter(results.values())).assumes}")
    if same:
        why = (" with two sensors the residuals from their mean are equal and opposite, so a "
               "method that weights by them cannot differ from the mean") if len(recs) == 2 else ""
        print(f"\nnote: the weights of {', '.join(same)} are those of the mean (1/{len(recs)}, "
              f"to {MEAN_WEIGHT_TOLERANCE:g}):{why}")
    print(f"wrote {out}" + (f", {figure}" if figure else ""))
    return 0
