"""Parameter declarations and their domains, with the maps to an unconstrained space.

A family declares its parameters as :class:`Parameter` objects; each names a domain from
:data:`DOMAINS`. Estimators optimise over the unconstrained image (as arch and statsmodels
do), so any vector of reals maps back to admissible values.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import attrs
import numpy as np
from scipy.special import expit

from stochmod.core.errors import DomainError

__all__ = ["Parameter", "Domain", "DOMAINS", "ROLES", "SCALE_POWERS", "get_domain", "pacf_to_ar",
           "ar_to_pacf", "scalar_contains"]

#: What a parameter is to its family (declared by ``Parameter(..., role=...)``). The core reads
#: rules from the roles instead of probing the family (docs/plugin_contract.md, "Roles"):
ROLES: dict[str, str] = {
    "variance": "scale, u^2: the family's wavelet variance is proportional to it",
    "amplitude": "scale, u: the family's wavelet variance is proportional to its square",
    "rate": "inverse time scale (1/s, Hz or per sample): where the process lives in tau",
    "shape": "dimensionless form of the correlation (AR or MA coefficients ...)",
}
#: Power d of a scale role: the wavelet variance is proportional to ``value ** d``.
SCALE_POWERS: dict[str, int] = {"variance": 1, "amplitude": 2}


def pacf_to_ar(r: np.ndarray) -> np.ndarray:
    """Map partial autocorrelations in (-1, 1) to the coefficients of a stationary AR(p).

    Durbin-Levinson recursion (Barndorff-Nielsen & Schou, 1973): a bijection between
    ``(-1, 1)^p`` and the stationarity region of ``X_t = sum_i phi_i X_{t-i} + e_t``.
    """
    r = np.asarray(r, dtype=np.float64)
    phi = np.zeros(0)
    for k, rk in enumerate(r):
        phi = np.append(phi - rk * phi[::-1], rk) if k else np.array([rk])
    return phi


def ar_to_pacf(phi: np.ndarray) -> np.ndarray:
    """Inverse of :func:`pacf_to_ar`; raises :class:`DomainError` if `phi` is not stationary."""
    phi = np.atleast_1d(np.asarray(phi, dtype=np.float64)).reshape(-1).copy()
    p = phi.size
    r = np.empty(p)
    for k in range(p, 0, -1):
        rk = phi[k - 1]
        if not abs(rk) < 1:
            raise DomainError(
                f"AR coefficients {phi.tolist()} are not stationary (partial autocorrelation "
                f"{rk:.6g} at lag {k} is not in (-1, 1))"
            )
        r[k - 1] = rk
        if k > 1:
            head = phi[: k - 1]
            phi = (head + rk * head[::-1]) / (1.0 - rk * rk)
    return r


@attrs.frozen
class Domain:
    """A parameter domain and its smooth bijection with an unconstrained space.

    Attributes
    ----------
    name : str
        Identifier used in :class:`Parameter` declarations.
    description : str
        Human-readable statement of the domain.
    contains : callable
        ``contains(value) -> bool``.
    to_unconstrained, from_unconstrained : callable
        The bijection and its inverse (elementwise, or on the whole vector).
    elementwise_derivative : callable or None
        ``d value / d theta`` elementwise, when the map acts elementwise.
    vector : bool
        Whether values are always sequences, even of length one (AR coefficients).
    """

    name: str
    description: str
    contains: Callable[[np.ndarray], bool]
    to_unconstrained: Callable[[np.ndarray], np.ndarray]
    from_unconstrained: Callable[[np.ndarray], np.ndarray]
    elementwise_derivative: Callable[[np.ndarray], np.ndarray] | None = None
    vector: bool = False

    def jacobian(self, theta: np.ndarray) -> np.ndarray:
        """Jacobian ``d value / d theta`` of :attr:`from_unconstrained` at `theta` (square matrix)."""
        theta = np.atleast_1d(np.asarray(theta, dtype=np.float64))
        if self.elementwise_derivative is not None:
            return np.diag(np.atleast_1d(self.elementwise_derivative(theta)))
        step = 1e-6 * np.maximum(1.0, np.abs(theta))
        cols = []
        for i in range(theta.size):
            e = np.zeros_like(theta)
            e[i] = step[i]
            hi = np.atleast_1d(self.from_unconstrained(theta + e))
            lo = np.atleast_1d(self.from_unconstrained(theta - e))
            cols.append((hi - lo) / (2 * step[i]))
        return np.column_stack(cols)


def _all(pred: Callable[[np.ndarray], np.ndarray]) -> Callable[[np.ndarray], bool]:
    def check(value: np.ndarray) -> bool:
        v = np.asarray(value, dtype=np.float64)
        return bool(np.all(np.isfinite(v)) and np.all(pred(v)))

    return check


_PACF_MAX = 1.0 - 2.0**-40


def _is_stationary(phi: np.ndarray) -> bool:
    try:
        ar_to_pacf(phi)
    except DomainError:
        return False
    return bool(np.all(np.isfinite(phi)))


DOMAINS: dict[str, Domain] = {
    d.name: d
    for d in (
        Domain(
            "positive", "x > 0", _all(lambda v: v > 0), np.log, np.exp, np.exp,
        ),
        Domain(
            "real", "any real x", _all(lambda v: np.ones_like(v, dtype=bool)),
            lambda v: np.asarray(v, dtype=np.float64), lambda t: np.asarray(t, dtype=np.float64),
            np.ones_like,
        ),
        Domain(
            "correlation", "-1 < x < 1", _all(lambda v: np.abs(v) < 1), np.arctanh, np.tanh,
            lambda t: 1.0 / np.cosh(t) ** 2,
        ),
        Domain(
            "unit_interval", "0 < x < 1", _all(lambda v: (v > 0) & (v < 1)),
            lambda v: np.log(v) - np.log1p(-v), expit,
            lambda t: 0.25 / np.cosh(t / 2) ** 2,
        ),
        Domain(
            "stationary_ar", "coefficients of a stationary AR(p) (all roots outside the unit circle)",
            _is_stationary,
            lambda v: np.arctanh(ar_to_pacf(v)),
            # keep |pacf| < 1 strictly: tanh rounds to +-1 for |t| > 19
            lambda t: pacf_to_ar(np.clip(np.tanh(t), -_PACF_MAX, _PACF_MAX)),
            vector=True,
        ),
    )
}


#: Scalar forms of :attr:`Domain.contains` for the built-in scalar domains (plain float
#: comparisons, no numpy call): the same verdict on one float, used where a value is rebuilt
#: many times (:meth:`stochmod.core.process.Process.from_unconstrained` in an optimizer).
_SCALAR_CONTAINS: dict[str, Callable[[float], bool]] = {
    "positive": lambda v: 0.0 < v < math.inf,
    "real": math.isfinite,
    "correlation": lambda v: -1.0 < v < 1.0,
    "unit_interval": lambda v: 0.0 < v < 1.0,
}


def scalar_contains(name: str) -> Callable[[float], bool] | None:
    """The scalar membership test of the built-in scalar domain `name` (a plain-float form of
    its :attr:`Domain.contains`), or None for a vector or unknown domain."""
    return _SCALAR_CONTAINS.get(name)


def get_domain(name: str) -> Domain:
    """Return the :class:`Domain` called `name`."""
    try:
        return DOMAINS[name]
    except KeyError:
        raise DomainError(f"unknown parameter domain {name!r}; known: {sorted(DOMAINS)}") from None


@attrs.frozen
class Parameter:
    """Declaration of one (scalar or vector) parameter of a process family.

    Attributes
    ----------
    name : str
        Canonical name used in specs (e.g. ``"sigma2"``).
    domain : str
        Name of a :class:`Domain` in :data:`DOMAINS`.
    unit : str
        Physical unit in terms of the signal unit ``u`` (e.g. ``"u^2"``, ``"1/s"``).
    description : str
        One line for tables and ``stochmod processes``.
    size : int
        Number of scalars (``p`` for AR(p) coefficients).
    role : str or None
        One of :data:`ROLES` (keyword only): ``"variance"`` or ``"amplitude"`` for the scale
        parameter (the family's wavelet variance is proportional to the value, or to its
        square), ``"rate"`` for an inverse time scale, ``"shape"`` for a dimensionless form.
        None means undeclared: the conformance kit (:mod:`stochmod.testing`) refuses it.
    """

    name: str
    domain: str = attrs.field(validator=attrs.validators.in_(DOMAINS))
    unit: str
    description: str = ""
    size: int = 1
    role: str | None = attrs.field(
        default=None, kw_only=True, validator=attrs.validators.optional(attrs.validators.in_(ROLES)))

    def check(self, value: object, family: str) -> np.ndarray | float:
        """Validate `value` against the domain; return it as float (scalar) or float array."""
        if value.__class__ is float and self.size == 1:  # a plain float: the scalar test
            inside = _SCALAR_CONTAINS.get(self.domain)  # (the same verdict; a value outside
            if inside is not None and inside(value):  # goes on to the error below)
                return value
        arr = np.asarray(value, dtype=np.float64) if not isinstance(value, str) else None
        if arr is None or arr.dtype == object:
            raise DomainError(f"{family}.{self.name} must be numeric, got {value!r}")
        if self.size == 1 and arr.ndim != 0 and arr.size != 1:
            raise DomainError(f"{family}.{self.name} must be a scalar, got shape {arr.shape}")
        if self.size != 1 and arr.reshape(-1).size != self.size:
            raise DomainError(
                f"{family}.{self.name} must have {self.size} value(s), got {arr.reshape(-1).size}"
            )
        if not get_domain(self.domain).contains(arr):
            raise DomainError(
                f"{family}.{self.name} = {value!r} is outside its domain "
                f"({get_domain(self.domain).description})"
            )
        return float(arr.reshape(-1)[0]) if self.size == 1 else arr.reshape(-1).copy()
