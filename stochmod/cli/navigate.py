"""``stochmod navigate``: the loosely-coupled INS/GNSS filter on a recording (IMU CSV + GNSS CSV),
writing the trajectory with its 1-sigma, a text report and (with matplotlib) figures."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from stochmod.core.errors import InputError
from stochmod.core.model import Model
from stochmod.nav.alignment import InitialState
from stochmod.nav.filter import ERROR_MODELS, LooselyCoupledFilter, NavResult
from stochmod.nav.logs import calibration_record, read_calibration, read_gnss_csv, read_imu_csv
from stochmod.nav.records import GnssData, ImuData
from stochmod.plugin.registry import get_process

__all__ = ["TRAJECTORY_COLUMNS", "UNTRUSTED_STATUS", "default_models", "register", "run"]

TRAJECTORY_COLUMNS = ("time", "lat", "lon", "height", "vn", "ve", "vd", "roll", "pitch",
                      "heading")
_DEG_H = math.pi / 180.0 / 3600.0
#: Turn-on bias 1-sigma without --gyro-bias-sd / --accel-bias-sd (a low-grade MEMS IMU).
DEFAULT_GYRO_BIAS_SD = 300.0 * _DEG_H
DEFAULT_ACCEL_BIAS_SD = 0.05
#: GNSS velocity 1-sigma per axis without --vel-sd, m/s.
DEFAULT_VEL_SD = 0.2
#: Exit status of a run whose solution fails the health rule (2: bad input).
UNTRUSTED_STATUS = 3


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``navigate`` subcommand."""
    p = subparsers.add_parser(
        "navigate",
        help="loosely-coupled INS/GNSS filter on an IMU CSV and a GNSS CSV",
        description=(
            "Run the closed-loop error-state EKF (stochmod.nav) on a recording and write "
            "DIR/trajectory.csv (time, lat, lon, height, vn, ve, vd, roll, pitch, heading and a "
            "sd_ column for each: sd_lat/sd_lon/sd_height are north/east/down 1-sigma in m, "
            "sd_roll/sd_pitch/sd_heading the attitude-error 1-sigma in deg), with --smooth "
            "DIR/trajectory_smoothed.csv (the same columns), DIR/report.txt, DIR/health.json and, "
            "with matplotlib, DIR/map.png and DIR/sigma.png. IMU_FILE: header time, gyro_x, "
            "gyro_y, gyro_z, accel_x, accel_y, accel_z (rad/s, m/s^2, w.r.t. inertial space, "
            "body x forward / y right / z down) or time, dtheta_x..z, dv_x..z (rad, m/s over the "
            "interval ending at time). GNSS_FILE: time, lat, lon, height (deg, deg, m "
            "ellipsoidal), optional vn, ve, vd (used when present) and sd_n, sd_e, sd_d (m). "
            "The report ends with the filter's health: where and how it aligned, the share of "
            "fixes the innovation gate rejected, its recoveries and the NIS per 60 s window. A "
            "solution that fails the health rule (a measurement kind with more than 20 % of "
            "its updates rejected, or a window's mean NIS after the first 60 s above 3 x the "
            "upper end of its 99 % chi-square band) is reported as UNTRUSTED on stderr and the "
            "command exits with status 3 unless --accept-untrusted; DIR/health.json holds the "
            "same."
        ),
    )
    p.add_argument("imu_file", metavar="IMU_FILE", help="IMU CSV (rates or increments)")
    p.add_argument("gnss_file", metavar="GNSS_FILE", help="GNSS CSV")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--calibration", default=None, metavar="FILE",
                   help="calibration.json of `stochmod calibrate`: the models of its columns "
                        "gyro_x ... accel_z are the filter's sensor-error models (default: white "
                        "noise 1 deg/sqrt(h) + random walk 30 deg/h/sqrt(h) per gyro, 0.1/60 "
                        "m/s/sqrt(s) + 0.01/60 m/s^2/sqrt(s) per accelerometer)")
    p.add_argument("--gyro-bias-sd", type=float, default=None, metavar="RAD_S",
                   help=f"turn-on gyro bias 1-sigma, rad/s (default {DEFAULT_GYRO_BIAS_SD:.3g}, "
                        "300 deg/h; 0: none)")
    p.add_argument("--accel-bias-sd", type=float, default=None, metavar="M_S2",
                   help=f"turn-on accelerometer bias 1-sigma, m/s^2 (default "
                        f"{DEFAULT_ACCEL_BIAS_SD:g}; 0: none)")
    p.add_argument("--init", default=None, metavar="LAT,LON,HEIGHT,VN,VE,VD,ROLL,PITCH,HEADING",
                   help="initial state at the first IMU time (deg, m, m/s, deg); without it the "
                        "filter aligns itself from GNSS velocity")
    p.add_argument("--lever-arm", type=float, nargs=3, default=(0.0, 0.0, 0.0),
                   metavar=("X", "Y", "Z"), help="IMU to antenna in the body frame, m")
    p.add_argument("--lever-arm-sd", type=float, nargs="+", default=[0.0], metavar="SD",
                   help="1-sigma of --lever-arm, m (one value or three for x y z): nonzero "
                        "estimates the lever arm as three constant filter states started at "
                        "--lever-arm, and reports the estimate (default 0: --lever-arm is exact)")
    p.add_argument("--outage", type=float, nargs=2, action="append", default=[],
                   metavar=("START", "DURATION"),
                   help="withhold GNSS from START for DURATION s (START from the first IMU time); "
                        "repeatable")
    p.add_argument("--dt-filter", type=float, default=0.1, metavar="S",
                   help="covariance step of the filter, s (default 0.1)")
    p.add_argument("--error-model", choices=ERROR_MODELS, default="psi",
                   help="the filter's error formulation, which sets how it feeds back and "
                        "resets its covariance: psi (default, the psi-angle model) or "
                        "modified-phi (Scherzinger & Reid's, the one pyins uses: choose it to "
                        "reproduce a pyins filter; docs/navigation.md, 'Reset')")
    p.add_argument("--gate", default="0.9999", metavar="P|off",
                   help="probability of the chi-square innovation gate (default 0.9999), or "
                        "off: every update is applied")
    p.add_argument("--recover-after", default="5", metavar="N|off",
                   help="after N consecutive gate rejections of one kind, apply the next one "
                        "after inflating the covariance (default 5; off: never; "
                        "docs/navigation.md, 'Gating and recovery')")
    p.add_argument("--init-position-sd", type=float, default=None, metavar="M",
                   help="initial position 1-sigma, m (default: 3 with --init, the fix's sd "
                        "when the filter aligns itself)")
    p.add_argument("--init-velocity-sd", type=float, default=None, metavar="M_S",
                   help="initial velocity 1-sigma, m/s (default 0.3 with --init, 0.5 aligned)")
    p.add_argument("--init-level-sd", type=float, default=None, metavar="DEG",
                   help="initial roll and pitch 1-sigma, deg (default 1 with --init, 2 aligned)")
    p.add_argument("--init-heading-sd", type=float, default=None, metavar="DEG",
                   help="initial heading 1-sigma, deg (default 3 with --init, 5 aligned)")
    p.add_argument("--vel-sd", type=float, default=DEFAULT_VEL_SD, metavar="M_S",
                   help=f"GNSS velocity 1-sigma per axis, m/s (default {DEFAULT_VEL_SD:g})")
    p.add_argument("--smooth", action="store_true",
                   help="also run the fixed-interval (Rauch-Tung-Striebel) smoother and write "
                        "DIR/trajectory_smoothed.csv (the columns of trajectory.csv, the "
                        "sigmas smoothed)")
    p.add_argument("--accept-untrusted", action="store_true",
                   help="exit with status 0 even when the solution fails the health rule "
                        "(the warning and the report stay)")
    p.add_argument("--no-plots", action="store_true", help="do not write figures")
    p.set_defaults(func=run)


def default_models(freq: float) -> tuple[Model, Model]:
    """The per-axis models used without --calibration, bound to `freq` (gyro, accel)."""
    wn, rw = get_process("WN"), get_process("RW")
    gyro = (wn.from_density(math.pi / 180.0 / 60.0, freq)
            + rw.from_rrw(30.0 * _DEG_H / 60.0, freq)).bind(freq)
    accel = (wn.from_density(0.1 / 60.0, freq)
             + rw.from_rrw(0.01 / 60.0, freq)).bind(freq)
    return gyro, accel


def _init(text: str | None, imu: ImuData) -> InitialState | None:
    if text is None:
        return None
    try:
        values = [float(v) for v in text.replace(" ", "").split(",")]
    except ValueError:
        raise InputError(f"--init must be 9 comma-separated numbers, got {text!r}") from None
    if len(values) != 9 or not all(math.isfinite(v) for v in values):
        raise InputError(f"--init needs 9 finite numbers lat,lon,height,vn,ve,vd,roll,pitch,"
                         f"heading; got {len(values)} in {text!r}")
    return InitialState(values[0], values[1], values[2], values[3:6], values[6:9],
                        time=float(imu.time[0]))


def _models(args: argparse.Namespace, imu: ImuData) -> tuple[dict[str, Model], dict[str, Model]]:
    if args.calibration is None:
        gyro, accel = default_models(round(1.0 / float(np.median(np.diff(imu.time))), 6))
        return {a: gyro for a in "xyz"}, {a: accel for a in "xyz"}
    models = read_calibration(args.calibration)
    return ({a: models[f"gyro_{a}"] for a in "xyz"}, {a: models[f"accel_{a}"] for a in "xyz"})


def _lever_arm_sd(values: list[float]) -> tuple[float, float, float]:
    if len(values) not in (1, 3):
        raise InputError(f"--lever-arm-sd takes one or three values (m), got {len(values)}")
    if not all(math.isfinite(v) and v >= 0 for v in values):
        raise InputError(f"--lever-arm-sd must be numbers >= 0 (m), got {values}")
    x, y, z = values * 3 if len(values) == 1 else values
    return x, y, z


def _lever_arm_lines(args: argparse.Namespace, result: NavResult) -> list[str]:
    if result.lever_arm is None:
        return [f"lever arm (m, body): {list(args.lever_arm)} (fixed)"]
    i = result.state_names.index("lever_arm.x")
    arm, sd = result.lever_arm[-1], result.epoch_sd[-1, i:i + 3]
    return [f"lever arm (m, body): prior {list(args.lever_arm)} +- "
            f"{list(_lever_arm_sd(args.lever_arm_sd))}, estimated "
            + ", ".join(f"{a} {v:.3f} +- {e:.3f}" for a, v, e in zip("xyz", arm, sd))]


def _switch(text: str, name: str, parse: type) -> float | int | None:
    """`text` as a number of type `parse`, or None for ``off``."""
    if text.strip().lower() == "off":
        return None
    try:
        return parse(text)
    except ValueError:
        raise InputError(f"{name} must be a number or off, got {text!r}") from None


def _positive(value: float | None, name: str) -> float | None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise InputError(f"{name} must be a positive number, got {value!r}")
    return value


def _bias(value: float | None, default: float, name: str) -> float:
    if value is None:
        return default
    if not (math.isfinite(value) and value >= 0):
        raise InputError(f"{name} must be a number >= 0, got {value!r}")
    return value


def trajectory_table(result: NavResult) -> np.ndarray:
    """The rows of trajectory.csv: the solution then its 1-sigma (m, m/s, deg)."""
    return np.column_stack([result.time, result.lat, result.lon, result.height, result.vel_ned,
                            result.rph, result.sd_position, result.sd_velocity, result.sd_rph])


def _report(args: argparse.Namespace, imu: ImuData, gnss: GnssData, result: NavResult,
            gyro: dict[str, Model], accel: dict[str, Model], gyro_bias_sd: float,
            accel_bias_sd: float) -> str:
    duration = float(imu.time[-1] - imu.time[0])
    lines = [
        f"stochmod navigate {args.imu_file} {args.gnss_file}",
        f"IMU: {imu.n} samples ({imu.kind}), {duration:.1f} s, "
        f"{1.0 / float(np.median(np.diff(imu.time))):.4g} Hz",
        f"GNSS: {gnss.n} fixes, velocity {'used' if gnss.vel_ned is not None else 'absent'}, "
        f"sd {'from the file' if gnss.sd is not None else 'filter default'}",
        f"outages (s from the first IMU time): {[tuple(o) for o in args.outage] or 'none'}",
        *_lever_arm_lines(args, result),
        f"error models: {'from ' + args.calibration if args.calibration else 'default MEMS'}; "
        + ", ".join(f"gyro_{a}: {m.name}" for a, m in gyro.items()) + "; "
        + ", ".join(f"accel_{a}: {m.name}" for a, m in accel.items()),
        f"turn-on bias 1-sigma: gyro {gyro_bias_sd:.3g} rad/s, accel {accel_bias_sd:.3g} m/s^2",
        f"smoother: {'fixed-interval RTS, trajectory_smoothed.csv' if args.smooth else 'off'}",
        f"filter error model: {args.error_model}; GNSS velocity sd "
        f"{'from the file' if gnss.sd_vel is not None else f'{args.vel_sd:g} m/s'}",
        "",
        result.summary(),
    ]
    return "\n".join(lines) + "\n"


def _plots(out: Path, result: NavResult, gnss: GnssData, outages: list, t0: float) -> list[Path]:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    fig, ax = plt.subplots(figsize=(6, 6))
    ax.plot(result.lon, result.lat, "-", lw=1, label="stochmod")
    ax.plot(gnss.lon, gnss.lat, ".", ms=2, label="GNSS")
    ax.set_xlabel("longitude (deg)")
    ax.set_ylabel("latitude (deg)")
    ax.set_aspect(1.0 / math.cos(math.radians(float(np.mean(result.lat)))))
    ax.legend()
    fig.tight_layout()
    paths = [out / "map.png"]
    fig.savefig(paths[0], dpi=120)
    plt.close(fig)
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    t = result.time - t0
    for ax, sd, label in zip(axes, (result.sd_position, result.sd_velocity, result.sd_rph),
                             ("position (m)", "velocity (m/s)", "attitude (deg)")):
        for k, name in enumerate("NED"):
            ax.plot(t, sd[:, k], lw=1, label=name)
        for start, dur in outages:
            ax.axvspan(start, start + dur, color="0.85")
        ax.set_ylabel(f"1-sigma {label}")
        ax.set_yscale("log")
    axes[0].legend(ncol=3)
    axes[-1].set_xlabel("time from the first IMU sample (s); grey: GNSS outages")
    fig.tight_layout()
    paths.append(out / "sigma.png")
    fig.savefig(paths[1], dpi=120)
    plt.close(fig)
    return paths


def run(args: argparse.Namespace) -> int:
    """Read the inputs, run the filter and write the outputs; the exit status is
    :data:`UNTRUSTED_STATUS` when the solution fails the health rule (unless
    ``--accept-untrusted``)."""
    imu = read_imu_csv(args.imu_file)
    gnss = read_gnss_csv(args.gnss_file)
    gyro, accel = _models(args, imu)
    gyro_bias_sd = _bias(args.gyro_bias_sd, DEFAULT_GYRO_BIAS_SD, "--gyro-bias-sd")
    accel_bias_sd = _bias(args.accel_bias_sd, DEFAULT_ACCEL_BIAS_SD, "--accel-bias-sd")
    if not (math.isfinite(args.dt_filter) and args.dt_filter > 0):
        raise InputError(f"--dt-filter must be a positive number of s, got {args.dt_filter!r}")
    gate = _switch(args.gate, "--gate", float)
    if gate is not None and not 0.0 < gate < 1.0:
        raise InputError(f"--gate must be a probability in (0, 1) or off, got {args.gate!r}")
    recover_after = _switch(args.recover_after, "--recover-after", int)
    if recover_after is not None and recover_after < 1:
        raise InputError(f"--recover-after must be a whole number >= 1 or off, got "
                         f"{args.recover_after!r}")
    init_sd = tuple(_positive(v, f"--init-{name}-sd") for v, name in (
        (args.init_position_sd, "position"), (args.init_velocity_sd, "velocity"),
        (args.init_level_sd, "level"), (args.init_heading_sd, "heading")))
    vel_sd = _positive(args.vel_sd, "--vel-sd")
    lever_arm_sd = _lever_arm_sd(args.lever_arm_sd)
    outages = [(float(s), float(d)) for s, d in args.outage]
    if any(d <= 0 for _, d in outages):
        raise InputError(f"--outage DURATION must be positive, got {outages}")
    # a fitted component correlated beyond the calibration record is the random walk it is there
    record = None if args.calibration is None else calibration_record(args.calibration)
    flt = LooselyCoupledFilter(gyro, accel, dt_filter=args.dt_filter, lever_arm=args.lever_arm,
                               gyro_bias_sd=gyro_bias_sd, accel_bias_sd=accel_bias_sd,
                               lever_arm_sd=lever_arm_sd, record=record,
                               error_model=args.error_model, gate=gate,
                               recover_after=recover_after, gnss_vel_sd=vel_sd)
    result = flt.run(imu.time, imu.gyro, imu.accel, kind=imu.kind, gnss=gnss,
                     init=_init(args.init, imu), outages=outages,
                     init_sd=None if all(v is None for v in init_sd) else init_sd,
                     smooth=args.smooth)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    written = [_write_trajectory(out / "trajectory.csv", result)]
    if result.smoothed is not None:
        written.append(_write_trajectory(out / "trajectory_smoothed.csv", result.smoothed))
    else:  # not the smoothed solution of an earlier run
        (out / "trajectory_smoothed.csv").unlink(missing_ok=True)
    report = _report(args, imu, gnss, result, gyro, accel, gyro_bias_sd, accel_bias_sd)
    (out / "report.txt").write_text(report)
    health = result.health()
    (out / "health.json").write_text(json.dumps(health.to_dict(), indent=1) + "\n")
    written += [out / "report.txt", out / "health.json"]
    written += [] if args.no_plots else _plots(out, result, gnss, outages, float(imu.time[0]))
    print(report)
    print("wrote " + ", ".join(str(f) for f in written))
    if health.trusted:
        return 0
    banner = "!" * 72
    print(f"{banner}\nstochmod navigate: WARNING: UNTRUSTED SOLUTION\n"
          + "\n".join(f"  - {r}" for r in health.reasons)
          + f"\n  rule: {health.rule}\n"
          + ("  (--accept-untrusted: exit status 0)\n" if args.accept_untrusted else
             f"  exit status {UNTRUSTED_STATUS}; --accept-untrusted to accept it\n") + banner,
          file=sys.stderr)
    return 0 if args.accept_untrusted else UNTRUSTED_STATUS


def _write_trajectory(path: Path, result: NavResult) -> Path:
    header = ",".join(TRAJECTORY_COLUMNS + tuple(f"sd_{c}" for c in TRAJECTORY_COLUMNS[1:]))
    np.savetxt(path, trajectory_table(result), delimiter=",", fmt="%.12g", header=header,
               comments="")
    return path
