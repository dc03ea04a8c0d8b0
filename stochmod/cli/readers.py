"""``stochmod readers``: the registered log readers, or what one file holds (columns, units,
rate, gaps and jitter of its time stamps)."""

from __future__ import annotations

import argparse

from stochmod.cli._common import add_input_arguments, declared_recording, print_json
from stochmod.io.recording import read_recording
from stochmod.plugin.registry import readers
from stochmod.core.tables import format_table

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``readers`` subcommand."""
    p = subparsers.add_parser(
        "readers",
        help="list the log readers, or inspect a file's columns, units and time stamps",
        description=(
            "Without FILE: every registered reader (first-party and plugins) with its suffixes "
            "and options. With FILE: the columns, units and value ranges it holds, and the report "
            "of its time stamps (rate, dropped samples and gaps with their positions, jitter); "
            "gaps are reported, not refused."
        ),
    )
    add_input_arguments(p, file_required=False)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print the readers table or one file's summary."""
    if args.file is None:
        table = readers()
        if args.json:
            print_json(
                {
                    n: {
                        "suffixes": list(r.suffixes),
                        "options": list(r.options),
                        "description": getattr(r, "description", ""),
                    }
                    for n, r in table.items()
                }
            )
            return 0
        print(
            format_table(
                ["reader", "suffixes", "options", "description"],
                [
                    [
                        n,
                        " ".join(s or "(none)" for s in r.suffixes) or "(sniffed)",
                        " ".join(r.options) or "-",
                        getattr(r, "description", ""),
                    ]
                    for n, r in table.items()
                ],
                title="registered readers",
            )
        )
        return 0
    rec = read_recording(
        args.file,
        columns=args.column,
        reader=args.reader,
        split_gaps=True,
        topic=args.topic,
        instance=args.instance,
    )
    if args.unit or args.gyro_unit or args.accel_unit:  # shown in SI, as the estimators read it
        rec = declared_recording(rec, args, required=False).to_si()
    if args.json:
        t = rec.timing
        print_json(
            {
                "columns": list(rec.columns),
                "units": list(rec.units or []),
                "n": rec.data.shape[0],
                "freq": rec.freq,
                "timing": None
                if t is None
                else {
                    "rate": t.rate,
                    "period": t.period,
                    "start": t.start,
                    "stop": t.stop,
                    "dropped": t.dropped,
                    "jitter_rms": t.jitter_rms,
                    "jitter_max": t.jitter_max,
                    "gaps": [[g.index, g.time, g.duration, g.missing] for g in t.gaps],
                },
            }
        )
        return 0
    print(rec.summary())
    return 0
