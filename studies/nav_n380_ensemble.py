"""stochmod and pyins on the n380 drive over an ensemble of the SAME random starts.

One drive gives one realisation of each outage's maximum error, and the start alone moves
outage 2 by metres, so "no worse than pyins per outage" is decided on the mean over seeded
starts: for seed s both filters start from the reference at the first epoch perturbed by pyins'
``generate_pva_error(5 m, 0.5 m/s, 0.2 deg, 1 deg, rng=s)``, with the settings of
``studies/nav_pyins_n380.py`` (pyins' real-data example MEMS model, GNSS position updates with sd
1 m, the three 60 s outages) and the IMU-to-antenna lever arm fitted from the data, (-1.3, 0, 0)
m, fixed in both.

pyins takes ~95 s a run on a quiet machine (much more under load; it is stopped 1 s after the
last outage, which changes nothing before it: the filter is causal), so its runs are cached per
seed in ``tests/nav/reference/nav_pyins_n380_ensemble.json`` (written after every run, resumed on
the next call): the per-outage maximum horizontal error, the initial error of the seed, and
pyins' state and 1-sigma just before each outage (``nav_pyins_n380.states_at_outages``).
tests/nav/test_n380.py compares stochmod with these runs; the stochmod side (``stochmod_runs``,
``summary``, ``verdict``) lives in tests/nav/_n380.py, which this script imports.

Run ``python studies/nav_n380_ensemble.py --pyins --seeds 10`` (the missing pyins runs, serially,
one at a time) and then ``python studies/nav_n380_ensemble.py`` (stochmod on the cached seeds and
the table: per-outage mean, sd and standard error of both, and of the paired difference
stochmod - pyins). ``--velocity`` does the same with position + velocity updates and no lever arm (the
settings of the single-start comparison), cached in
``tests/nav/reference/nav_pyins_n380_ensemble_velocity.json``, and ``--velocity --lever-arm``
with the fitted lever arm fixed in both, cached in
``tests/nav/reference/nav_pyins_n380_ensemble_velocity_lever_arm.json``; ``--pyins-jacobian``
gives stochmod pyins' velocity Jacobian, without the lever-arm terms
(``pyins_velocity_jacobian`` of tests/nav/_n380.py; docs/navigation_real_drive.md, "With
velocity updates and the lever arm"); ``--first-seed`` starts the
seeds elsewhere than 0. ``--error-model modified-phi`` runs stochmod with pyins' reset and feedback
(the covariance held in ``(dv - v_hat x psi, psi)`` across each feedback;
docs/navigation_real_drive.md, "The cause").

Compared here with library options since removed (studies/README.md keeps the results): the
exact reset Jacobian of the psi model (``error_model="psi-exact"``), and the filter with F at
the end of each covariance step and each fix taken as the error at the next IMU epoch.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

import numpy as np

from stochmod.nav.filter import ERROR_MODELS

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "nav"))

from _n380 import (ENSEMBLE_JSON, ENSEMBLE_VELOCITY_JSON, ENSEMBLE_VELOCITY_LEVER_ARM_JSON,
                   LEVER_ARM, OUTAGE_DURATION, OUTAGE_STARTS, load_cache, load_n380,
                   max_outage_errors, pyins_velocity_jacobian, stochmod_runs, summary,
                   verdict)


def cache_path(velocity: bool, lever_arm: bool) -> Path:
    """The cache of pyins' runs for the updates and lever arm: position updates with the lever
    arm (``ENSEMBLE_JSON``), position + velocity without it (``ENSEMBLE_VELOCITY_JSON``) or
    with it (``ENSEMBLE_VELOCITY_LEVER_ARM_JSON``)."""
    if not velocity:
        return ENSEMBLE_JSON
    return ENSEMBLE_VELOCITY_LEVER_ARM_JSON if lever_arm else ENSEMBLE_VELOCITY_JSON


def run_pyins_seeds(drive, seeds: list[int], velocity: bool = False,
                    lever_arm_too: bool = False) -> dict:
    """Run pyins for the seeds not in the cache, one at a time, saving after each run.
    ``velocity=False``: position updates, lever arm `LEVER_ARM` (``ENSEMBLE_JSON``); True:
    position + velocity updates, no lever arm (``ENSEMBLE_VELOCITY_JSON``), or with
    ``lever_arm_too`` the lever arm `LEVER_ARM` (``ENSEMBLE_VELOCITY_LEVER_ARM_JSON``)."""
    import pyins
    from nav_pyins_n380 import (ACCEL, GYRO, INIT, POSITION_SD, VELOCITY_SD, initial_error,
                                raw_inputs, run_pyins, states_at_outages)

    path = cache_path(velocity, lever_arm_too)
    lever_arm = LEVER_ARM if lever_arm_too or not velocity else (0.0, 0.0, 0.0)
    cache = load_cache(path)
    settings = {"gyro": GYRO, "accel": ACCEL, "position_sd_m": POSITION_SD, "initial": INIT,
                "time_step_s": 0.1}
    if velocity:
        settings["velocity_sd_m_s"] = VELOCITY_SD
    cache.update(pyins_version=pyins.__version__, lever_arm_m=list(lever_arm),
                 mode="position_velocity" if velocity else "position", settings=settings)
    increments, gnss, pva0 = raw_inputs(drive)
    # both filters are causal: nothing after the last outage changes its errors or the states
    # before the outages, so pyins stops 1 s after it (28 % of its ~10 min a run saved)
    end = drive.t0 + OUTAGE_STARTS[-1] + OUTAGE_DURATION + 1.0
    increments, gnss = increments[increments.index <= end], gnss[gnss.index <= end]
    for seed in seeds:
        if str(seed) in cache["runs"]:
            continue
        result, wall = run_pyins(increments, gnss, pva0, velocity=velocity,
                                 lever_arm=lever_arm if any(lever_arm) else None, seed=seed)
        traj = result.trajectory
        errors = max_outage_errors(traj.index.to_numpy(), traj["lat"].to_numpy(),
                                   traj["lon"].to_numpy(), drive.reference, drive.t0)
        cache["runs"][str(seed)] = {"initial_error": initial_error(seed),
                                    "max_horizontal_error_m": errors, "wall_s": wall,
                                    "states_at_outages": states_at_outages(result, drive)}
        path.parent.mkdir(exist_ok=True)
        path.write_text(json.dumps(cache, indent=1) + "\n")
        print(f"pyins seed {seed}: {', '.join(f'{e:6.1f}' for e in errors)} m  "
              f"(wall {wall:.0f} s)", flush=True)
    return cache


def coast(drive, k: int, states: dict) -> float:
    """Maximum horizontal error (m) in outage `k` of stochmod's free-inertial mechanisation
    started from a filter's state before it (``pva_before``, ``gyro_bias_deg_h``,
    ``accel_bias_m_s2`` of either filter) with the increments corrected by its bias estimates:
    the same mechanisation for both filters' states separates the effect of the state at the
    outage start from that of the mechanisation."""
    from stochmod.nav import strapdown

    t_s, lat, lon, alt, *rest = states["pva_before"][k]
    vel, rph = rest[:3], rest[3:]
    start, end = drive.t0 + OUTAGE_STARTS[k], drive.t0 + OUTAGE_STARTS[k] + OUTAGE_DURATION
    imu = drive.imu
    i0 = int(np.searchsorted(imu.time, t_s))  # the row at t_s: its increment ends there
    i1 = int(np.searchsorted(imu.time, end)) + 1
    t = imu.time[i0:i1]
    h = np.diff(imu.time[i0 - 1:i1])[:, None]
    bg = np.radians(np.asarray(states["gyro_bias_deg_h"][k]) / 3600.0)
    ba = np.asarray(states["accel_bias_m_s2"][k])
    res = strapdown(t, imu.gyro[i0:i1] - bg * h, imu.accel[i0:i1] - ba * h, lat=lat, lon=lon,
                    height=alt, vel_ned=vel, rph=rph, kind="increment")
    from stochmod.nav.study import max_outage_errors as worst

    return float(worst(drive.reference, res.time, res.lat, res.lon, [(start, end)])[0])


def compare_states(ours: dict[str, tuple[np.ndarray, dict]], cache: dict) -> None:
    """Per outage, over the seeds: the mean difference stochmod - pyins of each state before
    the outage in units of pyins' 1-sigma (biases: pyins' bias 1-sigma), and the mean ratio of
    stochmod's attitude and velocity 1-sigma to pyins'."""
    sd_of = {"rph_error_deg": "rph_sd_deg", "vel_error_m_s": "vel_sd_m_s",
             "gyro_bias_deg_h": "gyro_bias_sd_deg_h", "accel_bias_m_s2": "accel_bias_sd_m_s2"}
    for k in range(len(OUTAGE_STARTS)):
        print(f"before outage {k + 1}: mean over seeds of (stochmod - pyins) / pyins' sd "
              f"[mean |.|]; sd ratio stochmod/pyins")
        for name, sd_name in sd_of.items():
            d = np.array([(np.array(o[1][name][k]) - cache["runs"][s]["states_at_outages"][name][k])
                          / np.array(cache["runs"][s]["states_at_outages"][sd_name][k])
                          for s, o in ours.items()])
            line = f"  {name:16s} {np.round(d.mean(0), 2)} [{np.round(np.abs(d).mean(0), 2)}]"
            if name in ("rph_error_deg", "vel_error_m_s"):
                ratio = np.array([np.array(o[1][sd_name][k])
                                  / cache["runs"][s]["states_at_outages"][sd_name][k]
                                  for s, o in ours.items()]).mean(0)
                line += f"  sd ratio {np.round(ratio, 3)}"
            print(line)


def print_table(s: dict[str, np.ndarray], cache: dict) -> None:
    print(f"{int(s['n'])} seeded starts, {cache.get('mode', 'position')} updates, lever arm "
          f"{tuple(cache.get('lever_arm_m', LEVER_ARM))} m in both")
    print("outage | stochmod mean (sd) | pyins mean (sd) | stochmod - pyins mean +- se")
    for k in range(len(s["pyins_mean"])):
        print(f"{k + 1:6d} | {s['stochmod_mean'][k]:7.1f} ({s['stochmod_sd'][k]:5.1f})    | "
              f"{s['pyins_mean'][k]:6.1f} ({s['pyins_sd'][k]:5.1f})  | "
              f"{s['difference_mean'][k]:+6.2f} +- {s['difference_se'][k]:.2f}  "
              f"({verdict(s)[k]} at 2 s.e.)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pyins", action="store_true", help="run the missing pyins seeds")
    parser.add_argument("--seeds", type=int, default=10, help="seeds 0 .. N-1 (default 10)")
    parser.add_argument("--velocity", action="store_true",
                        help="position + velocity updates without a lever arm (the settings of "
                             "the single-start comparison) instead of position updates with "
                             "the fitted lever arm")
    parser.add_argument("--lever-arm", action="store_true",
                        help="with --velocity: the fitted lever arm fixed in both filters")
    parser.add_argument("--first-seed", type=int, default=0, help="first seed (default 0)")
    parser.add_argument("--no-stochmod", action="store_true", help="skip stochmod's runs")
    parser.add_argument("--states", action="store_true",
                        help="also compare the two filters' states before each outage")
    parser.add_argument("--pyins-jacobian", action="store_true",
                        help="stochmod with pyins' GNSS velocity Jacobian (no lever-arm terms)")
    parser.add_argument("--error-model", default="psi", choices=ERROR_MODELS,
                        help="stochmod's error model (default psi; modified-phi: pyins' reset)")
    args = parser.parse_args(argv)
    drive = load_n380()
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    if args.lever_arm and not args.velocity:
        parser.error("--lever-arm goes with --velocity (position updates always have it)")
    cache = (run_pyins_seeds(drive, seeds, args.velocity, args.lever_arm) if args.pyins
             else load_cache(cache_path(args.velocity, args.lever_arm)))
    if not args.no_stochmod and cache["runs"]:
        with pyins_velocity_jacobian() if args.pyins_jacobian else contextlib.nullcontext():
            ours = stochmod_runs(drive, cache, error_model=args.error_model)
        print(f"stochmod error model: {args.error_model}"
              + (", pyins' velocity Jacobian" if args.pyins_jacobian else ""))
        for seed in sorted(ours, key=int):
            print(f"seed {seed}: stochmod {np.round(ours[seed][0], 1)} m, pyins "
                  f"{np.round(cache['runs'][seed]['max_horizontal_error_m'], 1)} m")
        print_table(summary({s: o[0] for s, o in ours.items()}, cache), cache)
        if args.states:
            compare_states(ours, cache)
    return 0


if __name__ == "__main__":
    sys.exit(main())
