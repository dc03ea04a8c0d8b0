"""``stochmod export``: navigation-stack configurations from a ``calibration.json``, without
refitting (the same files as ``stochmod calibrate --export``)."""

from __future__ import annotations

import argparse

from stochmod.cli._calibrate_outputs import EXPORT_HORIZON_HELP
from stochmod.io.calibration import Calibration
from stochmod.output.exports import EXPORT_FORMATS, exports_from_calibration

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``export`` subcommand."""
    p = subparsers.add_parser(
        "export",
        help="Kalibr / OpenVINS / pyins / stochmod-nav configs from a calibration.json",
        description=(
            "Write navigation-stack configurations from the final noise models of a "
            "calibration file written by `stochmod calibrate` (nothing is refitted): kalibr "
            "(DIR/kalibr_imu.yaml), openvins (DIR/kalibr_imu_chain.yaml), pyins "
            "(DIR/pyins_imu.json), stochmod-nav (DIR/stochmod_nav.json). Each axis's white "
            "density N and random walk K over-bound its model's Allan variance over "
            "[1/fs, H] (docs/datasheet_exports.md); the headers state the range and the "
            "inflation over the model's own N and K."
        ),
    )
    p.add_argument("calibration", metavar="CALIBRATION_JSON",
                   help="calibration file written by `stochmod calibrate`")
    p.add_argument("--format", nargs="+", required=True, choices=sorted(EXPORT_FORMATS),
                   metavar="FORMAT", dest="formats",
                   help="one or more of: " + ", ".join(sorted(EXPORT_FORMATS)))
    p.add_argument("--out", default=".", metavar="DIR",
                   help="output folder (default the current folder; created if missing)")
    p.add_argument("--export-horizon", type=float, default=None, metavar="SECONDS",
                   help=EXPORT_HORIZON_HELP)
    p.add_argument("--rostopic", default="/imu0", help="IMU topic in the Kalibr/OpenVINS files")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Read the calibration, write the asked files, print their paths."""
    calibration = Calibration.read(args.calibration)
    written = exports_from_calibration(calibration, args.formats, args.out,
                                       horizon=args.export_horizon, rostopic=args.rostopic)
    print(f"wrote {', '.join(str(p) for p in written)}")
    return 0
