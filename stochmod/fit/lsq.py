"""A lean bounded Levenberg-Marquardt solver for the small least-squares problems of the GMWM.

A GMWM fit has a handful of free parameters (2 to 10) and about 20 residuals (one per level).
At that size ``scipy.optimize.least_squares`` (trf) spends more time in its own per-iteration
machinery (Coleman-Li scaling and reflective bounds, generic checks and wrappers) than in the
model itself. :func:`levenberg_marquardt` keeps trf's trust-region logic and drops the rest:

- variables scaled by the Jacobian's column norms, never decreasing (More, 1978; scipy's
  ``x_scale="jac"``), and a first trust region of radius 1 in them;
- one thin SVD of the scaled Jacobian per accepted point (LAPACK gesdd), so that each trust
  region tried there costs a few operations on vectors of the parameters' length: the
  Levenberg-Marquardt parameter whose step fills the region, by More's safeguarded Newton
  iteration (the Gauss-Newton step when it fits);
- the region quartered after a poor step (gain ratio below 1/4), doubled after a good one that
  reached its edge (above 3/4), as scipy's trf;
- box bounds by projection: a coordinate on a bound that the gradient pushes outwards is held
  there, the others take the step, which is clipped to the box;
- scipy's stopping rules (``ftol``, ``xtol``, ``gtol``, ``max_nfev``) and its result fields, so
  that callers switch between the two without other changes.

A trial point where the residuals cannot be evaluated (non-finite, or one of the failures a
model raises outside its reach) is a rejected step: the region shrinks and the search backs off.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from scipy.linalg import lapack

from stochmod.core.errors import EstimationError

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult

__all__ = ["levenberg_marquardt"]

#: What a trial point may raise when it leaves a model's reach: the step is rejected.
_TRIAL_FAILURES = (ArithmeticError, ValueError, np.linalg.LinAlgError, EstimationError)
_MESSAGES = {
    -2: "stopped by the callback",
    0: "the maximum number of function evaluations is exceeded",
    1: "gtol termination condition is satisfied",
    2: "ftol termination condition is satisfied",
    3: "xtol termination condition is satisfied",
    4: "both ftol and xtol termination conditions are satisfied",
}
_gesdd = lapack.dgesdd  # the thin SVD, without numpy's per-call checks (tiny matrices)
_add = np.add.reduce  # ndarray.sum without its Python wrapper (the same reduction)
#: The first trust region, in the variables scaled by the Jacobian's column norms (scipy's trf
#: starts from the scaled start's norm, often 10-100 here, whose first steps overshoot by
#: orders of magnitude; a unit radius needs fewer evaluations over bench/fit_digits.py's cases).
_FIRST_RADIUS = 1.0
_RANK = 1e-15  # singular values below this fraction of the largest are null directions


def levenberg_marquardt(
    fun: Callable[[np.ndarray], np.ndarray],
    jac: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    bounds: tuple[float, float],
    *,
    ftol: float,
    xtol: float,
    gtol: float,
    max_nfev: int,
    callback: Callable[[OptimizeResult], object] | None = None,
) -> OptimizeResult:
    """Minimise ``0.5 ||fun(x)||^2`` over the box ``bounds[0] <= x <= bounds[1]``.

    Parameters
    ----------
    fun : callable
        Residuals at x, shape (M,).
    jac : callable
        Their Jacobian at x, shape (M, N).
    x0 : ndarray (N,)
        Start (clipped to the box).
    bounds : (float, float)
        Lower and upper bound of every coordinate.
    ftol, xtol, gtol : float
        scipy's tolerances: relative decrease of the cost on a step whose gain ratio exceeds
        0.25; step norm relative to ``xtol + ||x||``; largest scaled gradient component.
    max_nfev : int
        Evaluations of `fun` allowed (the start included).
    callback : callable, optional
        Called after each accepted step with an ``OptimizeResult`` holding ``x`` and ``cost``;
        raising ``StopIteration`` ends the search there (status -2).

    Returns
    -------
    OptimizeResult
        ``x``, ``cost`` (half the sum of squares), ``fun``, ``jac``, ``nfev``, ``njev``,
        ``status`` (as scipy's least_squares: -2 callback, 0 budget, 1 gtol, 2 ftol, 3 xtol,
        4 ftol and xtol), ``success`` (status > 0 or -2) and ``message``.

    Raises
    ------
    ValueError
        A start that is not finite, or non-finite residuals or Jacobian there.
    """
    from scipy.optimize import OptimizeResult  # here: scipy.optimize is slow to import

    lo, hi = float(bounds[0]), float(bounds[1])
    x = np.minimum(np.maximum(np.asarray(x0, dtype=np.float64), lo), hi)
    if not all(map(math.isfinite, x.tolist())):
        raise ValueError("the start is not finite")
    r = np.asarray(fun(x), dtype=np.float64)
    J = np.asarray(jac(x), dtype=np.float64)
    nfev, njev = 1, 1
    cost = 0.5 * float(r @ r)
    if not (math.isfinite(cost) and math.isfinite(float(_add(J, axis=None)))):
        raise ValueError("residuals or Jacobian are not finite at the start")
    scale = _column_norms(J, None)
    radius = _FIRST_RADIUS
    status = None
    while status is None:
        lin = _Linearisation(x, r, J, scale, lo, hi)
        if lin.gradient_max < gtol:  # the projected gradient
            status = 1
            break
        lin.decompose()
        while True:  # trust regions at this point until a step is accepted or the search ends
            x_new, step_s_norm, step_norm, predicted = lin.step(radius)
            r_new = _trial(fun, x_new)
            nfev += 1
            cost_new = math.inf if r_new is None else 0.5 * float(r_new @ r_new)
            actual = cost - cost_new if math.isfinite(cost_new) else -math.inf
            ratio = actual / predicted if predicted > 0 else -1.0
            radius = _next_radius(radius, ratio, step_s_norm)
            status = _termination(actual, cost, step_norm, lin.x_norm, ratio, ftol, xtol)
            if ratio > 0:
                break
            if status is None and nfev >= max_nfev:
                status = 0
            if status is not None:
                break
        if ratio <= 0:  # the search ended on a rejected step: the point stays
            break
        J_new = _trial(jac, x_new)
        if J_new is None:  # no Jacobian there: keep the last point
            status = 3 if status is None else status
            break
        x, r, cost, J = x_new, r_new, cost_new, J_new
        njev += 1
        scale = _column_norms(J, scale)
        if callback is not None:
            try:
                callback(OptimizeResult(x=x.copy(), cost=cost))
            except StopIteration:
                status = -2
        if status is None and nfev >= max_nfev:
            status = 0
    return OptimizeResult(x=x, cost=cost, fun=r, jac=J, nfev=nfev, njev=njev, status=status,
                          success=status > 0 or status == -2, message=_MESSAGES[status])


class _Linearisation:
    """The model of the cost at an accepted point x (finite): the gradient in the variables
    scaled by `scale`, the coordinates held on a bound, and (:meth:`decompose`) the thin SVD
    of the scaled Jacobian over the free coordinates, from which :meth:`step` gives the step
    that fills a trust region and its predicted decrease, for any radius."""

    __slots__ = ("x", "r", "J", "scale", "lo", "hi", "free", "Js", "gs", "gradient_max",
                 "s2", "sur", "ur2", "gn", "Vt", "gn_norm", "g_norm", "x_norm")

    def __init__(self, x: np.ndarray, r: np.ndarray, J: np.ndarray, scale: np.ndarray,
                 lo: float, hi: float):
        self.x, self.r, self.J, self.scale, self.lo, self.hi = x, r, J, scale, lo, hi
        Js = J / scale
        gs = Js.T @ r  # the gradient of the cost in the scaled variables
        free = None
        xs = x.tolist()
        if min(xs) <= lo or max(xs) >= hi:
            # coordinates on a bound that the descent direction -g would leave are held there
            free = ~(((x <= lo) & (gs > 0)) | ((x >= hi) & (gs < 0)))
            Js, gs = Js[:, free], gs[free]
        self.free, self.Js, self.gs = free, Js, gs
        gl = gs.tolist()
        # numpy's max: nan when a component is nan (then never below gtol)
        self.gradient_max = math.nan if any(map(math.isnan, gl)) else max(map(abs, gl), default=0.0)

    def decompose(self) -> None:
        """The thin SVD of the scaled Jacobian, the Gauss-Newton step in its basis and the
        norms the trust-region steps need."""
        U, s, Vt, info = _gesdd(self.Js, full_matrices=0)
        if info != 0:
            raise np.linalg.LinAlgError("SVD of the Jacobian did not converge")
        ur = U.T @ self.r
        if not s[-1] > _RANK * s[0]:  # the numerically null directions take no step
            live = s > _RANK * s[0]
            s, ur, Vt = s[live], ur[live], Vt[live]
        self.s2, self.sur, self.ur2 = s * s, s * ur, ur * ur
        self.gn = self.sur / self.s2  # the Gauss-Newton step in the SVD's basis
        self.Vt = Vt
        self.gn_norm = math.sqrt(float(self.gn @ self.gn))
        self.g_norm = math.sqrt(float(self.gs @ self.gs))
        self.x_norm = math.sqrt(float(self.x @ self.x))

    def step(self, radius: float) -> tuple[np.ndarray, float, float, float]:
        """The trial point for a trust region of `radius` (scaled variables), the step's
        scaled norm, its norm, and the model's predicted decrease of the cost."""
        x, lo, hi, scale = self.x, self.lo, self.hi, self.scale
        mu = 0.0 if self.gn_norm <= radius else _damping(self.s2, self.sur, radius, self.g_norm)
        coef = self.gn if mu == 0.0 else self.sur / (self.s2 + mu)
        step_s = -(self.Vt.T @ coef)
        step_s_norm = math.sqrt(float(coef @ coef))  # V is orthonormal
        if self.free is None:
            step = step_s / scale
            x_new = x + step
            inside = all(lo <= v <= hi for v in x_new.tolist())  # (False for a nan)
        else:
            step = np.zeros_like(x)
            step[self.free] = step_s / scale[self.free]
            inside = False
        if inside:  # the model's decrease along the step, from the SVD
            if mu == 0.0:
                predicted = 0.5 * float(_add(self.ur2))
            else:
                f = self.s2 / (self.s2 + mu)
                predicted = float(f @ self.ur2) - 0.5 * float((f * f) @ self.ur2)
        else:  # clipped to the box: from the step itself
            x_new = np.minimum(np.maximum(x + step, lo), hi)
            step = x_new - x
            Jstep = self.J @ step
            predicted = -(float(self.J.T @ self.r @ step) + 0.5 * float(Jstep @ Jstep))
        step_norm = math.sqrt(float(step @ step))
        return x_new, step_s_norm, step_norm, predicted


def _next_radius(radius: float, ratio: float, step_s_norm: float) -> float:
    """The trust region after a step of scaled norm `step_s_norm` with gain ratio `ratio`:
    a quarter of the step after a poor one (below 1/4), doubled after a good one (above 3/4)
    that reached the region's edge, else unchanged."""
    if ratio < 0.25:
        return 0.25 * step_s_norm
    if ratio > 0.75 and step_s_norm > 0.95 * radius:
        return radius * 2.0
    return radius


def _damping(s2: np.ndarray, sur: np.ndarray, radius: float, g_norm: float) -> float:
    """The Levenberg-Marquardt parameter mu > 0 whose step ``p_i = s_i (U'r)_i / (s_i^2 + mu)``
    (in the SVD's basis) has norm `radius`, when the Gauss-Newton step is longer: More's
    (1978) safeguarded Newton iteration on ``1/||p(mu)|| - 1/radius``, to 10 % of the radius.

    `s2` are the squared singular values (all positive), `sur` = ``s U'r`` and `g_norm` =
    ``||J'r||``, whose ratio to the radius bounds mu from above."""
    low, high = 0.0, g_norm / radius
    mu = max(1e-3 * high, _geometric_mean(low, high))
    for _ in range(10):
        if not low < mu < high:
            mu = max(1e-3 * high, _geometric_mean(low, high))
        d = s2 + mu
        norm, dnorm = _norm_and_slope(sur / d, d)
        if abs(norm - radius) <= 0.1 * radius:
            break
        if norm < radius:
            high = mu
        else:
            low = mu
        # Newton's step; without a slope (underflow at the edge of the doubles) the next
        # iterate bisects the bracket
        mu = mu - (norm - radius) / dnorm * norm / radius if dnorm < 0.0 else -1.0
    else:  # no iterate within 10 %: the last one, kept inside the bracket
        if not low < mu < high:
            mu = max(1e-3 * high, _geometric_mean(low, high))
    return mu


def _geometric_mean(low: float, high: float) -> float:
    """``sqrt(low * high)``, also where the product overflows (a region near 1e-150)."""
    product = low * high
    return math.sqrt(product) if product < math.inf else math.sqrt(low) * math.sqrt(high)


def _norm_and_slope(p: np.ndarray, d: np.ndarray) -> tuple[float, float]:
    """``||p||`` and its derivative ``-sum(p_i^2 / d_i) / ||p||`` in mu (``p = sur / d``,
    ``d = s^2 + mu``); in units of the largest ``|p_i|`` where the squares underflow (a trust
    region shrunk to ~1e-100 by many rejected steps), so that the derivative stays negative."""
    norm = math.sqrt(float(p @ p))
    if norm > 0.0:
        slope = -float((p * p) @ (1.0 / d)) / norm
        if slope < 0.0:
            return norm, slope
    c = float(np.max(np.abs(p)))
    if not c > 0.0:
        return 0.0, 0.0
    u = p / c
    un = math.sqrt(float(u @ u))
    return c * un, -float((u * u) @ (1.0 / d)) * (c / un)


def _column_norms(J: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
    """The variables' scales: the Jacobian's column norms (1 for a zero column), never below
    the previous scales."""
    norms = np.sqrt(_add(J * J, axis=0))
    if previous is not None:
        return np.maximum(norms, previous)
    norms[norms == 0] = 1.0
    return norms


def _trial(fn: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray | None:
    """``fn(x)`` as floats, or None where it raises a model's failure or is not finite."""
    try:
        out = np.asarray(fn(x), dtype=np.float64)
    except _TRIAL_FAILURES:
        return None
    return out if math.isfinite(float(_add(out, axis=None))) else None


def _termination(actual: float, cost: float, step_norm: float, x_norm: float, ratio: float,
                 ftol: float, xtol: float) -> int | None:
    """scipy's test after a trial step: 2 ftol, 3 xtol, 4 both, None to go on."""
    f_ok = actual < ftol * cost and ratio > 0.25
    x_ok = step_norm < xtol * (xtol + x_norm)
    if f_ok and x_ok:
        return 4
    if f_ok:
        return 2
    if x_ok:
        return 3
    return None
