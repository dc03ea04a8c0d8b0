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
    log = parser.add_argument_group("logs, time stamps and units (docs/readers.md)")
    log.add_argument("--reader", default=None, metavar="NAME",
                     help="reader to use (default: by the file's content, then its suffix)")
    log.add_argument("--topic", default=None, metavar="NAME",
                     help="topic of a ROS bag (/imu) or a PX4 ULog (sensor_combined, "
                          "vehicle_imu, ...)")
    log.add_argument("--instance", type=int, default=None, metavar="K",
                     help="instance of a multi-instance ULog topic (default 0)")
    log.add_argument("--unit", default=None, metavar="UNIT",
                     help="unit of the data, e.g. deg/s, mg (default: the file's header); "
                          "converted to SI (allan reports in it)")
    log.add_argument("--split-gaps", action="store_true",
                     help="accept gaps in the time stamps and use the gap-free data "
                          "(without it a gap is an error that says where)")


def _longest_segment(rec: Recording) -> Recording:
    """The longest gap-free piece of `rec` (pooling all pieces is not wired into the CLIs yet)."""
    pieces = rec.segments()
    if len(pieces) == 1:
        return rec
    longest = max(pieces, key=lambda r: r.data.shape[0])
    print(f"{rec.path}: {len(pieces)} gap-free segments; using the longest "
          f"({longest.data.shape[0]} of {rec.data.shape[0]} samples, "
          f"from t = {longest.time[0]:.6g} s)",
          file=sys.stderr)
    return longest


def load_input(args: argparse.Namespace, *, to_si: bool = True) -> tuple[Recording, float]:
    """Read ``args.file`` restricted to ``args.column``, in SI, and resolve the sampling frequency.

    The reader options (``--reader``, ``--topic``, ``--instance``, ``--split-gaps``) go to
    :func:`~stochmod.io.read_recording`; ``--unit`` (else the file's units) converts to SI
    unless `to_si` is False (a subcommand that reports in the user's unit).
    """
    rec = read_recording(args.file, columns=args.column, reader=getattr(args, "reader", None),
                         split_gaps=getattr(args, "split_gaps", False),
                         topic=getattr(args, "topic", None),
                         instance=getattr(args, "instance", None))
    if rec.timing is not None:
        t = rec.timing
        print(f"{args.file}: {t.n} samples at {t.rate:.6g} Hz from the time stamps, "
              f"{len(t.gaps)} gap(s), jitter rms {t.jitter_rms:.3g} s", file=sys.stderr)
    rec = _longest_segment(rec.to_si(getattr(args, "unit", None)) if to_si else rec)
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
