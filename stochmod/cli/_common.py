"""Arguments and output helpers shared by the subcommands."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import attrs
import numpy as np

from stochmod.core.checks import check_freq
from stochmod.core.errors import InputError
from stochmod.core.jsonable import to_jsonable
from stochmod.io.recording import Recording, column_replicates, longest_segment, read_recording
from stochmod.io.sensors import declare_units

#: Relative difference between --freq and the time stamps' rate that is a contradiction.
FREQ_TOLERANCE = 0.01

__all__ = [
    "FREQ_TOLERANCE",
    "MIN_SEGMENT",
    "add_input_arguments",
    "column_replicates",
    "declared_recording",
    "gap_free_segments",
    "load_input",
    "load_segments",
    "longest_segment",
    "print_json",
    "to_jsonable",
]


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
    log.add_argument("--unit", action="append", default=None, metavar="[COLUMN=]UNIT",
                     help="unit of a column (COLUMN=UNIT, repeatable) or of every column of a "
                          "one-sensor file (UNIT), e.g. deg/s, g, mg; overrides the file's; "
                          "converted to SI (allan reports in it)")
    log.add_argument("--gyro-unit", default=None, metavar="UNIT",
                     help="unit of every gyro column (deg/s, rad/s, deg/h ...)")
    log.add_argument("--accel-unit", default=None, metavar="UNIT",
                     help="unit of every accelerometer column (g, mg, m/s^2 ...)")
    log.add_argument("--assume-si", action="store_true",
                     help="take rad/s and m/s^2 for gyro and accelerometer columns of unknown "
                          "unit (recorded as assumed); without it calibrate refuses them")
    log.add_argument("--split-gaps", action="store_true",
                     help="accept gaps in the time stamps: calibrate, select, fit and wv pool "
                          "the wavelet variances of the gap-free segments, the other "
                          "subcommands use the longest one (without it a gap is an error that "
                          "says where)")


MIN_SEGMENT = 8
"""Fewest samples a gap-free segment needs to be pooled (``--split-gaps``); shorter ones are
dropped, and the samples they hold are reported."""


def gap_free_segments(rec: Recording) -> list[Recording]:
    """The gap-free pieces of `rec` that hold at least :data:`MIN_SEGMENT` samples, in time order.

    The pieces are the replicates whose wavelet variances the pooling subcommands (``calibrate``,
    ``select``, ``fit``, ``wv``) pool; a note on stderr says how many there are and what was
    dropped.

    Raises
    ------
    InputError
        No piece holds :data:`MIN_SEGMENT` samples.
    """
    pieces = rec.segments()
    if len(pieces) == 1:
        return pieces
    kept = [p for p in pieces if p.data.shape[0] >= MIN_SEGMENT]
    dropped = sum(p.data.shape[0] for p in pieces) - sum(p.data.shape[0] for p in kept)
    if not kept:
        raise InputError(f"{rec.path}: no gap-free segment holds {MIN_SEGMENT} samples")
    print(f"{rec.path}: {len(pieces)} gap-free segments; pooling the wavelet variances of "
          f"{len(kept)} ({rec.data.shape[0] - dropped} samples"
          + (f"; {dropped} samples in segments shorter than {MIN_SEGMENT} dropped)" if dropped
             else ")"), file=sys.stderr)
    return kept


def _read(args: argparse.Namespace, to_si: bool, path: str | None = None
          ) -> tuple[Recording, float]:
    path = args.file if path is None else path
    rec = read_recording(path, columns=args.column, reader=getattr(args, "reader", None),
                         split_gaps=getattr(args, "split_gaps", False),
                         topic=getattr(args, "topic", None),
                         instance=getattr(args, "instance", None))
    if rec.timing is not None:
        t = rec.timing
        print(f"{path}: {t.n} samples at {t.rate:.6g} Hz from the time stamps, "
              f"{len(t.gaps)} gap(s), jitter rms {t.jitter_rms:.3g} s", file=sys.stderr)
    # the main job needs every unit (its magnitudes are checked by workflows.calibrate.prepare)
    calibrating = getattr(args, "require_units", False)
    rec = declared_recording(rec, args, required=calibrating)
    if to_si:
        rec = rec.to_si()
    if args.freq is not None and rec.timing is not None:
        rate = rec.timing.rate
        if abs(args.freq - rate) > FREQ_TOLERANCE * rate:
            raise InputError(f"--freq {args.freq:g} contradicts the time stamps of {path} "
                             f"({rate:.6g} Hz): drop --freq, or fix the time stamps")
    _refuse_clock_columns(rec, args.column)
    freq = args.freq if args.freq is not None else rec.freq
    if freq is None:
        raise InputError(f"{path} does not record its sampling frequency: pass --freq HZ")
    return rec, check_freq(freq, name="--freq")


def _refuse_clock_columns(rec: Recording, named: list[str] | None) -> None:
    """Refuse a column that increases at every sample (a time stamp or a counter the reader did
    not take as time), unless the user named it with ``--column``: a sensor at rest does not
    do that, and its model would be meaningless."""
    named = set(named or ())
    for k, column in enumerate(rec.columns):
        x = rec.data[:, k]
        if column not in named and x.size > 2 and bool(np.all(np.diff(x) > 0)):
            raise InputError(
                f"{rec.path}: column {column!r} increases at every sample, like a time stamp or "
                "a counter: name the time column so that the reader takes it as time (CSV: "
                "'time', 't' or 'timestamp'), leave the column out with --column, or name it "
                "with --column to model it anyway")


def declared_recording(rec: Recording, args: argparse.Namespace, *, required: bool
                       ) -> Recording:
    """`rec` with each column's declared kind and unit (:func:`stochmod.io.sensors.declare_units`
    from the file and ``--sensor``, ``--unit``, ``--gyro-unit``, ``--accel-unit``,
    ``--assume-si``): its
    :attr:`~stochmod.io.recording.Recording.units` are the declared ones."""
    sensor = getattr(args, "sensor", None)  # what every column measures, where the file is silent
    kinds = rec.kinds if rec.kinds is not None or sensor is None else (sensor,) * len(rec.columns)
    declared = declare_units(rec.columns, rec.units, kinds, unit=getattr(args, "unit", None),
                             gyro_unit=getattr(args, "gyro_unit", None),
                             accel_unit=getattr(args, "accel_unit", None),
                             assume_si=getattr(args, "assume_si", False), required=required)
    return attrs.evolve(rec, units=tuple(c.unit for c in declared), declared=declared)


def load_input(args: argparse.Namespace, *, to_si: bool = True) -> tuple[Recording, float]:
    """Read ``args.file`` restricted to ``args.column``, in SI, and resolve the sampling frequency.

    The reader options (``--reader``, ``--topic``, ``--instance``, ``--split-gaps``) go to
    :func:`~stochmod.io.recording.read_recording`; ``--unit`` (else the file's units) converts to SI
    unless `to_si` is False (a subcommand that reports in the user's unit). A recording with
    gaps (``--split-gaps``) gives its longest gap-free segment, with a note on stderr; the
    subcommands that pool the segments use :func:`load_segments`.
    """
    rec, freq = _read(args, to_si)
    pieces = rec.segments()
    longest = longest_segment(pieces)
    if longest is not rec:
        print(f"{rec.path}: {len(pieces)} gap-free segments; using the longest "
              f"({longest.data.shape[0]} of {rec.data.shape[0]} samples, from t = "
              f"{longest.time[0]:.6g} s; calibrate, select, fit and wv pool all segments)",
              file=sys.stderr)
    return longest, freq


def load_segments(args: argparse.Namespace, path: str | None = None
                  ) -> tuple[list[Recording], float]:
    """Like :func:`load_input`, but a recording with gaps (``--split-gaps``) gives all its
    gap-free segments (:func:`gap_free_segments`), whose wavelet variances the caller pools as
    replicates (:mod:`stochmod.fit.replicates`); one segment without gaps. `path` replaces
    ``args.file`` (``calibrate --pooled`` reads several files with the same options)."""
    rec, freq = _read(args, True, path)
    return gap_free_segments(rec), freq


def print_json(obj: Any) -> None:
    """Print `obj` as indented, key-sorted strict JSON on stdout."""
    json.dump(to_jsonable(obj), sys.stdout, indent=1, sort_keys=True, allow_nan=False)
    sys.stdout.write("\n")
