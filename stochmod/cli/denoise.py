"""``stochmod denoise``: wavelet de-noising of every column, written to .npy, .npz or .csv."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from stochmod.cli._common import add_input_arguments, load_input, print_json
from stochmod.core.errors import InputError
from stochmod.empirical.denoise import RULES, wavelet_denoise

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``denoise`` subcommand."""
    p = subparsers.add_parser(
        "denoise",
        help="wavelet de-noising (MATLAB wden conventions) of every column",
        description=(
            "Threshold the wavelet details of each column and write the de-noised columns to "
            "OUT (.npy: a 2-D array; .npz: one array per column plus freq; .csv: a header line "
            "and one row per sample). After L levels the kept band is 0..freq/2^(L+1) Hz."
        ),
    )
    add_input_arguments(p)
    group = p.add_mutually_exclusive_group(required=True)
    group.add_argument("--level", type=int, default=None, metavar="L",
                       help="number of decomposition levels (LOD)")
    group.add_argument("--f-limit", type=float, default=None, metavar="HZ",
                       help="keep the band up to HZ: smallest L with freq/2^(L+1) <= HZ")
    p.add_argument("--wavelet", default="db4", help="orthogonal pywt wavelet (default db4)")
    p.add_argument("--rule", default="rigrsure",
                   help=f"threshold rule: {', '.join(RULES)} (default rigrsure), or a number "
                        "(fixed threshold in noise units)")
    p.add_argument("--mode", choices=["soft", "hard"], default="soft",
                   help="thresholding (default soft)")
    p.add_argument("--noise", choices=["level", "one", "none"], default="level",
                   help="noise scale: per level (default), from level 1 only, or none")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output file: .npy, .npz or .csv")
    p.set_defaults(func=run)


def _rule(text: str) -> str | float:
    if text in RULES:
        return text
    try:
        return float(text)
    except ValueError:
        raise InputError(f"--rule must be one of {RULES} or a number, got {text!r}") from None


def _write(path: Path, data: np.ndarray, columns: tuple[str, ...], freq: float) -> None:
    suffix = path.suffix.lower()
    if suffix == ".npy":
        np.save(path, data)
    elif suffix == ".npz":
        np.savez(path, freq=np.float64(freq), **{c: data[:, k] for k, c in enumerate(columns)})
    elif suffix == ".csv":
        np.savetxt(path, data, delimiter=",", header=",".join(columns), comments="", fmt="%.17g")
    else:
        raise InputError(f"unknown output format {suffix!r} for {path}; use .npy, .npz or .csv")


def run(args: argparse.Namespace) -> int:
    """De-noise every selected column and write them."""
    rule = _rule(args.rule)
    out = Path(args.output)
    if out.suffix.lower() not in (".npy", ".npz", ".csv"):
        raise InputError(f"unknown output format {out.suffix!r} for {out}; use .npy, .npz or .csv")
    rec, freq = load_input(args)
    results = {
        name: wavelet_denoise(rec.data[:, k], args.wavelet, args.level, rule, args.mode,
                              args.noise, freq, args.f_limit)
        for k, name in enumerate(rec.columns)
    }
    data = np.column_stack([r.signal for r in results.values()])
    _write(out, data, rec.columns, freq)
    if args.json:
        print_json({
            "columns": {n: {"level": r.level, "band_limit_hz": r.band_limit, "wavelet": r.wavelet,
                            "rule": r.rule, "mode": r.mode, "noise": r.noise,
                            "thresholds": r.thresholds, "noise_sigma": r.noise_sigma}
                        for n, r in results.items()},
            "freq": freq, "output": str(out),
        })
        return 0
    print("\n\n".join(f"column {n}\n{r.summary()}" for n, r in results.items()))
    print(f"\nwrote {data.shape[0]} x {data.shape[1]} de-noised samples to {out}")
    return 0
