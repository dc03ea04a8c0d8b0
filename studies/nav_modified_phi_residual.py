"""What was left between stochmod's ``error_model="modified-phi"`` and pyins on the n380 drive
(docs/navigation_real_drive.md, "The residual of modified-phi").

With the modified-phi reset stochmod reproduced pyins' covariance recursion along pyins' own
linearisation points (bench/nav_n380_stepwise.py), yet over the ten cached seeded starts it was
still +1.8 m worse than pyins in outage 1. This script emulates, one at a time, pyins' choice of
each remaining implementation difference in stochmod's filter (a subclass of the filter's inner
loop, here, not in the library) and reruns the ensemble of bench/nav_n380_ensemble.py, so each
choice's share of the residual is measured on the same seeds:

- ``linear``: the velocity feedback stochmod's modified-phi filter had before (``v <- v_hat -
  dv_hat``, ``dv_hat = dv'_hat + v_hat x psi_hat``), instead of the exact injection of the
  modified error ``v <- Exp(psi_hat) (v_hat - dv'_hat)`` that the library now does, as pyins'
  ``InsErrorModel.correct_pva`` does. The two differ by ``-psi_hat x dv_hat`` and
  ``O(psi_hat^2 v)``: the first-order one leaves the corrected state off the estimate at
  second order (a defect, fixed; tests/nav/test_error_model.py). The hold uses the velocity
  change actually applied either way.
- ``before``: pyins' update timing. pyins applies a fix at time ``tm`` with the covariance and
  the state of the last IMU epoch before ``tm`` (the measurement itself predicted to ``tm``),
  and propagates the last sample afterwards; stochmod propagates over the sample that contains
  ``tm`` first. Emulated by deferring that sample's propagation to the next step.
- ``mid``: pyins' linearisation point, the PVA in the middle of the covariance step (stochmod:
  the end of the step).

The emulations start from the filter as it was when this was measured: F at the END of each
covariance step and a fix taken as the error at the IMU epoch after it (``linearisation="end",
timing="epoch"``). The library now linearises at the middle and refers each fix to its own time
(``"midpoint"``, ``"fix"``, chosen on numerical grounds: tests/nav/test_linearisation.py); the
``library`` variant runs those defaults.

Run ``python bench/nav_modified_phi_residual.py [--seeds 10] [--variants base linear before mid
before+mid library]`` (~45 s per variant for 10 seeds on a quiet machine); prints, per variant,
the paired difference stochmod - pyins per outage (mean +- standard error).
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
from collections.abc import Iterator

import numpy as np

from nav_n380_ensemble import load_cache, stochmod_runs, summary
from _n380 import load_n380

from stochmod.nav import filter as nav_filter

VARIANTS = ("base", "linear", "before", "mid", "before+mid", "library")


class _PyinsChoices(nav_filter._Run):
    """The filter's inner loop with some of pyins' implementation choices (`choices`)."""

    choices: frozenset = frozenset()

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._deferred = 0.0
        self._next_event = 0
        self._last = None

    def _feedback(self, dx: np.ndarray) -> None:
        v_old = np.array(self.mech.v)
        super()._feedback(dx)
        if "linear" not in self.choices or self.flt.error_model != "modified-phi":
            return
        target = v_old - dx[3:6]
        extra = target - np.array(self.mech.v)
        self.mech.v = tuple(float(x) for x in target)
        # the hold composes additively in the (velocity, attitude) block
        self._reset(slice(3, 6), slice(3, 9), np.hstack([np.eye(3), nav_filter._skew(extra)]))

    def _propagate(self, dt: float, m: int, f_n: tuple[float, float, float]) -> None:
        dt += self._deferred
        self._deferred = 0.0
        if "before" in self.choices:
            ev = self.events
            while self._next_event < len(ev) and ev[self._next_event][0] <= self.t_prev + 1e-9:
                self._next_event += 1
            if self._next_event < len(ev) and ev[self._next_event][0] <= self.t_now + 1e-9:
                self._next_event += 1
                while self._next_event < len(ev) and ev[self._next_event][0] <= self.t_now + 1e-9:
                    self._next_event += 1
                self._deferred = self.t_now - self.t_prev
                dt -= self._deferred
                if dt <= 1e-9:
                    return
        if "mid" in self.choices and self._last is not None:
            with self._at_middle():
                super()._propagate(dt, m, f_n)
        else:
            super()._propagate(dt, m, f_n)

    @contextlib.contextmanager
    def _at_middle(self) -> Iterator[None]:
        mech = self.mech
        now = (mech.lat, mech.h, mech.v, mech.q)
        lat, h, v, q = self._last
        qm = np.array(q) + np.array(now[3]) * (1.0 if np.dot(q, now[3]) >= 0 else -1.0)
        mech.lat, mech.h = 0.5 * (lat + now[0]), 0.5 * (h + now[1])
        mech.v = tuple(0.5 * (np.array(v) + np.array(now[2])))
        mech.q = tuple(qm / math.sqrt(qm @ qm))
        try:
            yield
        finally:
            mech.lat, mech.h, mech.v, mech.q = now

    def _record(self, epochs: list, epoch_rows: list, nav_P: list, row: int) -> None:
        mech = self.mech
        self._last = (mech.lat, mech.h, mech.v, mech.q)
        super()._record(epochs, epoch_rows, nav_P, row)


@contextlib.contextmanager
def pyins_choices(choices: set[str]) -> Iterator[None]:
    """Run the filter with the `choices` (``linear``, ``before``, ``mid``) inside."""
    variant = type("Variant", (_PyinsChoices,), {"choices": frozenset(choices)})
    original = nav_filter._Run
    nav_filter._Run = variant
    try:
        yield
    finally:
        nav_filter._Run = original


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS))
    parser.add_argument("--error-model", default="modified-phi")
    args = parser.parse_args(argv)
    drive = load_n380()
    cache = load_cache()
    cache["runs"] = {s: r for s, r in cache["runs"].items() if int(s) < args.seeds}
    for name in args.variants:
        choices = set() if name in ("base", "library") else set(name.split("+"))
        before = {} if name == "library" else {"linearisation": "end", "timing": "epoch"}
        with pyins_choices(choices):
            ours = stochmod_runs(drive, cache, error_model=args.error_model, **before)
        s = summary({k: o[0] for k, o in ours.items()}, cache)
        print(f"{args.error_model:12s} {name:18s} stochmod - pyins per outage: " + ", ".join(
            f"{m:+6.2f} +- {e:.2f}" for m, e in zip(s["difference_mean"], s["difference_se"]))
              + " m", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
