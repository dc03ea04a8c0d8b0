"""Fitted digits of many GMWM fits, to check that a speed change leaves the results unchanged.

Run ``python bench/fit_digits.py dump OUT.json`` with each version (e.g. an older commit
extracted to a folder and put first on ``PYTHONPATH``, plugins included, run from outside the
worktree), then ``python bench/fit_digits.py compare A.json B.json``: it lists the fits whose
``repr`` digits differ with the relative change of their objective (B against A) and the
largest relative change of a parameter, counts the fits whose parameters moved by more than
1e-6, and exits with 1 when some objective of B is worse than A's by more than 1e-9.

The 99 cases: ``bench_gmwm``'s signal at 2e5 and 2e6 samples fitted with the five
``bench_select`` candidates (and 2*GM+WN with the optimal weighting at 2e5); three
replications of each ``mc_gmwm`` case without AR, with the diagonal and the optimal
weightings; the default 64-candidate lattice on 5e4 samples of GM+WN+RW (objective and
criterion of every candidate, the selected model's parameters). About 20-40 s.
"""

from __future__ import annotations

import json
import sys
import warnings
from pathlib import Path

import numpy as np
from bench_gmwm import FREQ, simulated
from bench_select import CANDIDATES

# the Monte Carlo cases of the GMWM study are part of the digits checked
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "studies"))

import mc_gmwm

import stochmod
from stochmod.fit.gmwm import gmwm
from stochmod.fit.selection import select

REPS = 3
#: A case whose objective is higher than the reference's by more than this (relative) is worse.
WORSE = 1e-9
#: A fit whose parameters moved by more than this (relative) counts as moved.
MOVED = 1e-6


def _digits(fit) -> dict:
    return {"v": [repr(float(v)) for v in fit.model.vector()], "obj": repr(float(fit.objective))}


def dump(path: str) -> None:
    """Fit every case and write the digits to `path` (JSON)."""
    out: dict[str, dict] = {}
    for n in (200_000, 2_000_000):
        x = simulated(n)
        for spec in CANDIDATES:
            out[f"bench{n}/{spec}"] = _digits(gmwm(x, spec, FREQ))
        if n == 200_000:
            out[f"bench{n}/2*GM+WN/opt"] = _digits(gmwm(x, "2*GM+WN", FREQ, weighting="optimal"))
    for case in mc_gmwm.CASES:
        if case.name.startswith("AR") or "2^20" in case.name:
            continue
        truth = stochmod.model_from_spec(case.spec, FREQ)
        for r in range(REPS):
            seed = np.random.SeedSequence(mc_gmwm.SEED, spawn_key=(case.seed_key, r))
            x = truth.simulate(case.n, np.random.default_rng(seed))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out[f"mc/{case.name}/{r}"] = _digits(gmwm(x, truth.freed(), FREQ))
                out[f"mc/{case.name}/{r}/opt"] = _digits(gmwm(x, truth.freed(), FREQ, weighting="optimal"))
    truth = stochmod.model_from_spec("GM(beta=0.5, sigma2=1e-6) + WN(sigma2=3e-6) + RW(sigma2=1e-11)", FREQ)
    res = select(truth.simulate(50_000, rng=7), FREQ, progress=False)
    for row in res.ranking:
        out[f"lattice/{row.model}"] = {"obj": repr(float(row.objective)), "crit": repr(float(row.criterion))}
    out["lattice/best"] = {"v": [repr(float(v)) for v in res.best.model.vector()]}
    out["lattice/order"] = {"models": [row.model for row in res.ranking]}
    with open(path, "w") as f:
        json.dump(out, f, indent=0)


def compare(path_a: str, path_b: str) -> int:
    """Print the cases whose digits differ, each objective's relative change (B over A) and the
    largest relative change of a parameter; return how many cases have B's objective worse
    than A's by more than :data:`WORSE` (relative)."""
    with open(path_a) as f:
        a = json.load(f)
    with open(path_b) as f:
        b = json.load(f)
    differ, moved, worse, worst, obj_low, obj_high = 0, 0, 0, 0.0, 0.0, 0.0
    for key, ea in a.items():
        eb = b.get(key)
        if ea == eb:
            continue
        differ += 1
        if eb is None:
            print(f"{key}: missing in {path_b}")
            worse += 1
            continue
        parts = []
        if "obj" in ea and "obj" in eb:
            change = (float(eb["obj"]) - float(ea["obj"])) / abs(float(ea["obj"]))
            obj_low, obj_high = min(obj_low, change), max(obj_high, change)
            worse += change > WORSE
            parts.append(f"objective {change:+.3g}{' WORSE' if change > WORSE else ''}")
        if "v" in ea and "v" in eb:
            rel = max(abs(float(p) - float(q)) / abs(float(p)) for p, q in zip(ea["v"], eb["v"]))
            worst = max(worst, rel)
            moved += rel > MOVED
            parts.append(f"largest relative parameter change {rel:.3g}")
        print(f"{key}: " + "; ".join(parts or [f"{ea} -> {eb}"]))
    print(f"{len(a) - differ} of {len(a)} identical; objective relative change from {obj_low:+.3g} "
          f"to {obj_high:+.3g}, {worse} worse by more than {WORSE:g}; {moved} fits with a "
          f"parameter moved by more than {MOVED:g} (relative), largest {worst:.3g}")
    return worse


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "dump":
        dump(sys.argv[2])
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        sys.exit(1 if compare(sys.argv[2], sys.argv[3]) else 0)
    else:
        sys.exit(__doc__)
