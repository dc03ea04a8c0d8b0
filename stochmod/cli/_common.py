"""Arguments and output helpers shared by the subcommands."""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

import numpy as np

from stochmod._validation import check_freq
from stochmod.errors import InputError
from stochmod.io import Recording, read_recording

__all__ = ["add_input_arguments", "load_input", "print_json", "to_jsonable"]


def add_input_arguments(parser: argparse.ArgumentParser, *, file_required: bool = True) -> None:
    """Add FILE, ``--freq``, ``--column`` (repeatable) and ``--json`` to a subcommand."""
    parser.add_argument(
        "file", metavar="FILE", nargs=None if file_required else "?",
        help="recording: CSV (optional header), .npy or .npz",
    )
    parser.add_argument("--freq", type=float, default=None,
                        help="sampling frequency in Hz (read from an .npz 'freq' entry if omitted)")
    parser.add_argument("--column", action="append", default=None, metavar="C",
                        help="column name or 0-based index; repeat for several (default: all)")
    parser.add_argument("--json", action="store_true", help="print machine-readable JSON")


def load_input(args: argparse.Namespace) -> tuple[Recording, float]:
    """Read ``args.file`` restricted to ``args.column`` and resolve the sampling frequency."""
    rec = read_recording(args.file, columns=args.column)
    freq = args.freq if args.freq is not None else rec.freq
    if freq is None:
        raise InputError(f"{args.file} does not record its sampling frequency: pass --freq HZ")
    return rec, check_freq(freq, name="--freq")


def to_jsonable(obj: Any) -> Any:
    """Convert numpy scalars/arrays (recursively) into JSON-safe Python objects.

    Non-finite floats become ``None`` so that the output is strict JSON.
    """
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        value = float(obj)
        return value if math.isfinite(value) else None
    return obj


def print_json(obj: Any) -> None:
    """Print `obj` as indented, key-sorted strict JSON on stdout."""
    json.dump(to_jsonable(obj), sys.stdout, indent=1, sort_keys=True, allow_nan=False)
    sys.stdout.write("\n")
