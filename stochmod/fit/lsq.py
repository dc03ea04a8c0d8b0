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

import numpy as np
from scipy.linalg import lapack
from scipy.optimize import OptimizeResult

from stochmod.errors import EstimationError

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
#: The first trust region, in the variables scaled by the Jacobian's column norms (scipy's trf
#: starts from the scaled start's norm, often 10-100 here, whose first steps overshoot by
#: orders of magnitude: over bench/fit_digits.py's 99 cases 1.0 takes 18 % fewer evaluations).
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
        Non-finite residuals or Jacobian at the start.
    """
    lo, hi = float(bounds[0]), float(bounds[1])
    x = np.minimum(np.maximum(np.asarray(x0, dtype=np.float64), lo), hi)
    r = np.asarray(fun(x), dtype=np.float64)
    J = np.asarray(jac(x), dtype=np.float64)
    nfev, njev = 1, 1
    cost = 0.5 * float(r @ r)
    if not (math.isfinite(cost) and math.isfinite(float(J.sum()))):
        raise ValueError("residuals or Jacobian are not finite at the start")
    scale = _column_norms(J, None)
    radius = _FIRST_RADIUS
    status = None
    while status is None:
        Js = J / scale
        gs = Js.T @ r  # the gradient of the cost in the scaled variables
        free = None
        if float(x.min()) <= lo or float(x.max()) >= hi:
            # coordinates on a bound that the descent direction -g would leave are held there
            free = ~(((x <= lo) & (gs > 0)) | ((x >= hi) & (gs < 0)))
            Js, gs = Js[:, free], gs[free]
        if float(np.abs(gs).max(initial=0.0)) < gtol:  # the projected gradient
            status = 1
            break
        U, s, Vt, info = _gesdd(Js, full_matrices=0)
        if info != 0:
            raise np.linalg.LinAlgError("SVD of the Jacobian did not converge")
        ur = U.T @ r
        if not s[-1] > _RANK * s[0]:  # the numerically null directions take no step
            live = s > _RANK * s[0]
            s, ur, Vt = s[live], ur[live], Vt[live]
        s2, sur, ur2 = s * s, s * ur, ur * ur
        gn = sur / s2  # the Gauss-Newton step in the SVD's basis
        gn_norm = math.sqrt(float(gn @ gn))
        g_norm = math.sqrt(float(gs @ gs))
        x_norm = math.sqrt(float(x @ x))
        while True:  # trust regions at this point until a step is accepted or the search ends
            mu = 0.0 if gn_norm <= radius else _damping(s2, sur, radius, g_norm)
            coef = gn if mu == 0.0 else sur / (s2 + mu)
            step_s = -(Vt.T @ coef)
            step_s_norm = math.sqrt(float(coef @ coef))  # V is orthonormal
            if free is None:
                step = step_s / scale
                x_new = x + step
                inside = float(x_new.min()) >= lo and float(x_new.max()) <= hi
            else:
                step = np.zeros_like(x)
                step[free] = step_s / scale[free]
                inside = False
            if inside:  # the model's decrease along the step, from the SVD
                if mu == 0.0:
                    predicted = 0.5 * float(ur2.sum())
                else:
                    f = s2 / (s2 + mu)
                    predicted = float(f @ ur2) - 0.5 * float((f * f) @ ur2)
            else:  # clipped to the box: from the step itself
                x_new = np.minimum(np.maximum(x + step, lo), hi)
                step = x_new - x
                Jstep = J @ step
                predicted = -(float(J.T @ r @ step) + 0.5 * float(Jstep @ Jstep))
            step_norm = math.sqrt(float(step @ step))
            r_new = _trial(fun, x_new)
            nfev += 1
            cost_new = math.inf if r_new is None else 0.5 * float(r_new @ r_new)
            actual = cost - cost_new if math.isfinite(cost_new) else -math.inf
            ratio = actual / predicted if predicted > 0 else -1.0
            if ratio < 0.25:
                radius = 0.25 * step_s_norm
            elif ratio > 0.75 and step_s_norm > 0.95 * radius:
                radius *= 2.0
            status = _termination(actual, cost, step_norm, x_norm, ratio, ftol, xtol)
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


def _damping(s2: np.ndarray, sur: np.ndarray, radius: float, g_norm: float) -> float:
    """The Levenberg-Marquardt parameter mu > 0 whose step ``p_i = s_i (U'r)_i / (s_i^2 + mu)``
    (in the SVD's basis) has norm `radius`, when the Gauss-Newton step is longer: More's
    (1978) safeguarded Newton iteration on ``1/||p(mu)|| - 1/radius``, to 10 % of the radius.

    `s2` are the squared singular values (all positive), `sur` = ``s U'r`` and `g_norm` =
    ``||J'r||``, whose ratio to the radius bounds mu from above."""
    low, high = 0.0, g_norm / radius
    mu = max(1e-3 * high, math.sqrt(low * high))
    for _ in range(10):
        if not low < mu < high:
            mu = max(1e-3 * high, math.sqrt(low * high))
        d = s2 + mu
        p = sur / d
        norm = math.sqrt(float(p @ p))
        if abs(norm - radius) <= 0.1 * radius:
            break
        dnorm = -float((p * p) @ (1.0 / d)) / norm  # d ||p|| / d mu
        if norm < radius:
            high = mu
        else:
            low = mu
        mu -= (norm - radius) / dnorm * norm / radius
    else:  # no iterate within 10 %: the last one, kept inside the bracket
        if not low < mu < high:
            mu = max(1e-3 * high, math.sqrt(low * high))
    return mu


def _column_norms(J: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
    """The variables' scales: the Jacobian's column norms (1 for a zero column), never below
    the previous scales."""
    norms = np.sqrt((J * J).sum(axis=0))
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
    return out if math.isfinite(float(out.sum())) else None


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
