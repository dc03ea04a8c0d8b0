"""Datasheet units <-> SI, and the discrete-time values of noise coefficients.

stochmod works in SI internally: rad/s for gyroscopes, m/s^2 for accelerometers, s, Hz.
For a signal of unit ``u`` (rad/s or m/s^2) the sensor-independent coefficients are

====  ===============================  ==================  ========================
name  meaning                          SI unit             Allan variance
====  ===============================  ==================  ========================
N     white noise density (ARW, VRW)   u*sqrt(s)           N^2 / tau
B     bias instability                 u                   (2 ln2 / pi) B^2 (floor)
K     rate / acceleration random walk  u / sqrt(s)         K^2 tau / 3
Q     quantization                     u*s                 3 Q^2 / tau^2
R     rate ramp                        u / s               R^2 tau^2 / 2
Tc    Gauss-Markov correlation time    s                   --
====  ===============================  ==================  ========================

Unit strings are parsed, not looked up: ``"deg/h/sqrt(Hz)"``, ``"deg/rt-hr"``, ``"m/s/h^1.5"``,
``"ug/sqrt(Hz)"``, ``"(deg/s)^2/Hz"`` ... are products and powers of the names in
:data:`UNIT_NAMES`; each parsed unit carries its dimension (angle, length, time) and hence its
kind (``"angle_random_walk"``, ``"rate"`` ...), which :func:`to_si` checks against the coefficient
asked for (``kind="N"`` refuses ``"deg/h"``).  ``u/sqrt(Hz)`` and ``u*sqrt(s)`` are the same
unit: the density is the square root of the *two-sided* PSD, as in IEEE Std 952 and
Gonzalez et al. (2015) eq. 2.  ``g``, ``mg``, ``ug`` are multiples of standard gravity
:data:`STANDARD_GRAVITY` (9.80665 m/s^2, a conventional constant, not the local gravity).

The second half turns coefficients into per-sample values at a sampling frequency ``fs``
(Quinchia et al. 2013, eqs. 2-4 and 27-30): white noise variance, random-walk increment
variance, and the first-order Gauss-Markov (GM) transition and innovation variance, exactly or
in the first-order forms the seed papers use.  :func:`cep_to_sigma` is Gonzalez eq. 7.
"""

from __future__ import annotations

import difflib
import math
import re
from fractions import Fraction
from functools import lru_cache
from typing import Literal

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.checks import check_freq, checked_values, scalar_or_array
from stochmod.core.errors import InputError
from stochmod.core.tables import format_table

__all__ = [
    "SENSORS",
    "sensor_unit",
    "signal_unit",
    "kind_from_name",
    "si_unit_of",
    "STANDARD_GRAVITY",
    "DEG",
    "MINUTE",
    "HOUR",
    "BI_FACTOR",
    "BI_FACTOR_IEEE",
    "CEP_FACTOR",
    "UNIT_NAMES",
    "KINDS",
    "Unit",
    "parse_unit",
    "to_si",
    "from_si",
    "convert",
    "wn_variance",
    "wn_density",
    "rw_variance",
    "rw_density",
    "two_sided_density",
    "one_sided_density",
    "bi_floor",
    "bi_from_floor",
    "cep_to_sigma",
    "sigma_to_cep",
]

#: Standard gravity g0 in m/s^2 (CGPM 1901, exact by definition); the unit ``g`` of datasheets.
STANDARD_GRAVITY = 9.80665
#: Radians per degree (pi / 180).
DEG = math.pi / 180.0
#: Seconds per minute.
MINUTE = 60.0
#: Seconds per hour.
HOUR = 3600.0
#: Ratio of the flat Allan-deviation floor to the bias instability B: sqrt(2 ln 2 / pi) = 0.66428...
BI_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
#: The same ratio rounded as in IEEE Std 952 and Quinchia et al. (2013) eqs. 18 and 29.
BI_FACTOR_IEEE = 0.664
#: CEP / sigma of a circular 2-D normal error: sqrt(2 ln 2) = 1.17741 (Gonzalez eq. 7: 1/0.8493).
CEP_FACTOR = math.sqrt(2.0 * math.log(2.0))

Dims = tuple[Fraction, Fraction, Fraction]  # exponents of (angle, length, time)
_ZERO = Fraction(0)


def _dims(angle: float = 0, length: float = 0, time: float = 0) -> Dims:
    return (Fraction(angle), Fraction(length), Fraction(time))


# name -> (SI value of one unit, dimension).  Case-sensitive: "mg" is milli-g, "ms" millisecond.
_ANGLE, _LENGTH, _TIME, _FREQ = _dims(angle=1), _dims(length=1), _dims(time=1), _dims(time=-1)
_ACCEL = _dims(length=1, time=-2)
_BASE: dict[str, tuple[float, Dims]] = {
    "rad": (1.0, _ANGLE),
    "mrad": (1e-3, _ANGLE),
    "urad": (1e-6, _ANGLE),
    "deg": (DEG, _ANGLE),
    "mdeg": (1e-3 * DEG, _ANGLE),
    "arcmin": (DEG / 60.0, _ANGLE),
    "arcsec": (DEG / 3600.0, _ANGLE),
    "m": (1.0, _LENGTH),
    "cm": (1e-2, _LENGTH),
    "mm": (1e-3, _LENGTH),
    "km": (1e3, _LENGTH),
    "s": (1.0, _TIME),
    "ms": (1e-3, _TIME),
    "us": (1e-6, _TIME),
    "ns": (1e-9, _TIME),
    "min": (MINUTE, _TIME),
    "h": (HOUR, _TIME),
    "Hz": (1.0, _FREQ),
    "kHz": (1e3, _FREQ),
    "g": (STANDARD_GRAVITY, _ACCEL),
    "mg": (STANDARD_GRAVITY / 1e3, _ACCEL),
    "ug": (STANDARD_GRAVITY / 1e6, _ACCEL),
}
_ALIASES = {
    "degree": "deg", "degrees": "deg", "radian": "rad", "radians": "rad",
    "sec": "s", "second": "s", "seconds": "s", "hr": "h", "hour": "h", "hours": "h",
    "mins": "min", "minute": "min", "minutes": "min", "hz": "Hz", "khz": "kHz",
    "meter": "m", "metre": "m", "meters": "m", "metres": "m",
}
# Whole-word abbreviations replaced by an expression before parsing.
_MACROS = {"dps": "(deg/s)", "dph": "(deg/h)", "rps": "(rad/s)"}

#: Every unit name the parser accepts (aliases included), with its SI value.
UNIT_NAMES: dict[str, float] = {
    **{k: v[0] for k, v in _BASE.items()},
    **{k: _BASE[v][0] for k, v in _ALIASES.items()},
}

# Physical kinds by dimension, with the SI unit stochmod uses for each.
_KIND_BY_DIMS: dict[Dims, tuple[str, str]] = {
    _dims(): ("dimensionless", "1"),
    _ANGLE: ("angle", "rad"),
    _LENGTH: ("length", "m"),
    _TIME: ("time", "s"),
    _FREQ: ("frequency", "Hz"),
    _dims(length=1, time=-1): ("velocity", "m/s"),
    _dims(angle=1, time=-1): ("rate", "rad/s"),
    _ACCEL: ("acceleration", "m/s^2"),
    _dims(angle=1, time=Fraction(-1, 2)): ("angle_random_walk", "rad/s/sqrt(Hz)"),
    _dims(length=1, time=Fraction(-3, 2)): ("velocity_random_walk", "m/s^2/sqrt(Hz)"),
    _dims(angle=1, time=Fraction(-3, 2)): ("rate_random_walk", "rad/s/sqrt(s)"),
    _dims(length=1, time=Fraction(-5, 2)): ("accel_random_walk", "m/s^2/sqrt(s)"),
    _dims(angle=1, time=-2): ("rate_ramp", "rad/s^2"),
    _dims(length=1, time=-3): ("accel_ramp", "m/s^3"),
}
_PHYSICAL = {name: dims for dims, (name, _) in _KIND_BY_DIMS.items()}

#: Accepted ``kind`` names: coefficient kinds (one per sensor type) and physical kinds.
KINDS: dict[str, tuple[str, ...]] = {
    "N": ("angle_random_walk", "velocity_random_walk"),
    "B": ("rate", "acceleration"),
    "K": ("rate_random_walk", "accel_random_walk"),
    "Q": ("angle", "velocity"),
    "R": ("rate_ramp", "accel_ramp"),
    "Tc": ("time",),
    "fs": ("frequency",),
    **{name: (name,) for name in _PHYSICAL},
}
_NONNEGATIVE_KINDS = {"N", "B", "K", "Q"}
_POSITIVE_KINDS = {"Tc", "fs"}


@attrs.frozen
class Unit:
    """A parsed unit string.

    Attributes
    ----------
    text : str
        The string as given.
    scale : float
        The SI value of one unit (``to_si(1, text)``), in :attr:`si`.
    dims : tuple of Fraction
        Exponents of (angle, length, time); ``Hz`` is time^-1, ``g`` is length time^-2.
    """

    text: str
    scale: float
    dims: Dims

    @property
    def kind(self) -> str:
        """Physical kind (``"rate"``, ``"angle_random_walk"`` ...) or ``"other"``."""
        return _KIND_BY_DIMS.get(self.dims, ("other", ""))[0]

    @property
    def si(self) -> str:
        """The SI unit stochmod uses for this kind, e.g. ``"rad/s/sqrt(Hz)"``."""
        known = _KIND_BY_DIMS.get(self.dims)
        if known is not None:
            return known[1]
        parts = [
            f"{name}^{exp}" if exp != 1 else name
            for name, exp in zip(("rad", "m", "s"), self.dims)
            if exp != 0
        ]
        return "*".join(parts) or "1"

    def summary(self) -> str:
        """One-row table: unit, kind, SI unit and SI value of one unit."""
        return format_table(
            ["unit", "kind", "SI unit", "1 unit in SI"],
            [[self.text, self.kind, self.si, self.scale]],
            digits=12,
        )


# ---------------------------------------------------------------- parsing

_TOKEN = re.compile(
    r"\s*(?:(?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)|(?P<name>[A-Za-z_]+)|(?P<op>[*/^()+\-]))"
)
_SQRT_WORD = r"(?:rt-?|sqrt-?|√\s*)"


def _normalise(text: str) -> str:
    s = text.strip()
    for old, new in (("°", "deg"), ("µ", "u"), ("μ", "u"), ("²", "^2"), ("³", "^3"),
                     ("**", "^"), ("·", "*"), ("⋅", "*"), ("×", "*")):
        s = s.replace(old, new)
    # "deg/rt-hr", "deg/√h", "deg/sqrt-h", "ug/rtHz" -> sqrt(...)
    s = re.sub(r"(?<![A-Za-z])" + _SQRT_WORD + r"\(\s*([A-Za-z]+)\s*\)", r"sqrt(\1)", s)
    s = re.sub(r"(?<![A-Za-z])" + _SQRT_WORD + r"([A-Za-z]+)", r"sqrt(\1)", s)
    for word, expr in _MACROS.items():
        s = re.sub(rf"\b{word}\b", expr, s)
    return s


class _Parser:
    """Recursive descent over: expr := term {('*'|'/'|juxtaposition) term};
    term := atom ['^' exponent]; atom := name | '1' | 'sqrt' '(' expr ')' | '(' expr ')'."""

    def __init__(self, text: str, original: str) -> None:
        self.original = original
        self.tokens: list[tuple[str, str]] = []
        pos = 0
        while pos < len(text):
            m = _TOKEN.match(text, pos)
            if m is None or m.end() == pos:
                if text[pos:].strip() == "":
                    break
                raise self.error(f"unexpected character {text[pos]!r}")
            kind = m.lastgroup
            assert kind is not None
            self.tokens.append((kind, m.group(kind)))
            pos = m.end()
        self.i = 0

    def error(self, problem: str) -> InputError:
        return InputError(
            f"unit {self.original!r} cannot be parsed: {problem}; write units like "
            "'deg/sqrt(h)', 'deg/h/sqrt(Hz)', 'm/s/h^1.5', 'ug/sqrt(Hz)' "
            "(see stochmod.core.units.UNIT_NAMES)"
        )

    def peek(self) -> tuple[str, str] | None:
        return self.tokens[self.i] if self.i < len(self.tokens) else None

    def take(self) -> tuple[str, str]:
        tok = self.peek()
        if tok is None:
            raise self.error("it ends too early")
        self.i += 1
        return tok

    def expect(self, op: str) -> None:
        if self.peek() is None:
            raise self.error(f"expected {op!r} before the end")
        tok = self.take()
        if tok != ("op", op):
            raise self.error(f"expected {op!r}, found {tok[1]!r}")

    def parse(self) -> tuple[float, Dims]:
        if not self.tokens:
            raise self.error("it is empty")
        value = self.expr()
        if self.peek() is not None:
            raise self.error(f"unexpected {self.peek()[1]!r}")  # type: ignore[index]
        return value

    def expr(self) -> tuple[float, Dims]:
        scale, dims = self.term()
        while (tok := self.peek()) is not None and tok != ("op", ")"):
            sign = 1
            if tok[0] == "op" and tok[1] in "*/":
                sign = -1 if tok[1] == "/" else 1
                self.i += 1
            s2, d2 = self.term()
            scale = scale * s2 if sign > 0 else scale / s2
            dims = tuple(a + sign * b for a, b in zip(dims, d2))  # type: ignore[assignment]
        return scale, dims

    def term(self) -> tuple[float, Dims]:
        scale, dims = self.atom()
        if self.peek() == ("op", "^"):
            self.i += 1
            exp = self.exponent()
            scale = _power(scale, exp)
            dims = tuple(d * exp for d in dims)  # type: ignore[assignment]
        return scale, dims

    def atom(self) -> tuple[float, Dims]:
        kind, val = self.take()
        if kind == "op" and val == "(":
            out = self.expr()
            self.expect(")")
            return out
        if kind == "num":
            if float(val) != 1.0:
                raise self.error(f"a bare number ({val}) is not a unit")
            return 1.0, _dims()
        if kind == "name":
            if val == "sqrt":
                self.expect("(")
                scale, dims = self.expr()
                self.expect(")")
                half = Fraction(1, 2)
                return math.sqrt(scale), tuple(d * half for d in dims)  # type: ignore[return-value]
            name = _ALIASES.get(val, val)
            if name not in _BASE:
                close = difflib.get_close_matches(val, list(UNIT_NAMES), n=3)
                hint = f" (did you mean {', '.join(map(repr, close))}?)" if close else ""
                raise InputError(
                    f"unknown unit {val!r} in {self.original!r}{hint}; known names: "
                    f"{', '.join(sorted(UNIT_NAMES))}"
                )
            return _BASE[name]
        raise self.error(f"unexpected {val!r}")

    def exponent(self) -> Fraction:
        paren = self.peek() == ("op", "(")
        if paren:
            self.i += 1
        sign = 1
        if self.peek() in (("op", "-"), ("op", "+")):
            sign = -1 if self.take()[1] == "-" else 1
        kind, val = self.take()
        if kind != "num":
            raise self.error(f"expected an exponent after '^', found {val!r}")
        exp = Fraction(val)
        # "h^3/2" and "h^(3/2)": a unit is never divided by a bare number, so this is a fraction.
        nxt = self.tokens[self.i: self.i + 2]
        if len(nxt) == 2 and nxt[0] == ("op", "/") and nxt[1][0] == "num":
            exp /= Fraction(nxt[1][1])
            self.i += 2
        if paren:
            self.expect(")")
        return sign * exp


def _power(scale: float, exp: Fraction) -> float:
    """``scale ** exp``, exact for integer and half-integer exponents where floats allow."""
    if exp.denominator == 2:
        return math.sqrt(scale) ** exp.numerator
    return scale ** float(exp)


@lru_cache(maxsize=512)
def parse_unit(unit: str) -> Unit:
    """Parse a unit string into its SI scale and dimension.

    Parameters
    ----------
    unit : str
        Products, quotients and powers of the names in :data:`UNIT_NAMES` (``*``, ``/``,
        juxtaposition, ``^`` with integer, decimal or fractional exponents, ``sqrt(...)``,
        parentheses).  Also accepted: ``rt-hr``, ``rtHz``, ``√h``, ``°``, ``µg``, ``h^3/2``
        (read as ``h^(3/2)``), ``dps`` (deg/s), ``dph`` (deg/h).  ``a/b/c`` is ``(a/b)/c``.

    Returns
    -------
    Unit

    Raises
    ------
    InputError
        If the string is not a str, is empty, malformed, or names an unknown unit.
    """
    if not isinstance(unit, str):
        raise InputError(f"unit must be a string such as 'deg/sqrt(h)', got {unit!r}")
    scale, dims = _Parser(_normalise(unit), unit).parse()
    return Unit(text=unit, scale=float(scale), dims=dims)


# ---------------------------------------------------------------- conversion

def _positive_scalar(x: float, name: str) -> float:
    arr, scalar = checked_values(x, name, sign="pos")
    if not scalar:
        raise InputError(f"{name} must be a single number, got {x!r}")
    return float(arr)


def _checked_unit(unit: str, kind: str | None) -> Unit:
    parsed = parse_unit(unit)
    if kind is None:
        return parsed
    if kind not in KINDS:
        raise InputError(f"kind must be one of {', '.join(KINDS)}; got {kind!r}")
    allowed = KINDS[kind]
    if parsed.kind not in allowed:
        wanted = " or ".join(f"{k} ({_KIND_BY_DIMS[_PHYSICAL[k]][1]})" for k in allowed)
        raise InputError(
            f"unit {unit!r} is a {parsed.kind} ({parsed.si}), but kind {kind!r} needs {wanted}"
        )
    return parsed


def _sign_for(kind: str | None) -> Literal["any", "nonneg", "pos"]:
    if kind in _POSITIVE_KINDS:
        return "pos"
    return "nonneg" if kind in _NONNEGATIVE_KINDS else "any"


def to_si(value: ArrayLike, unit: str, kind: str | None = None) -> float | np.ndarray:
    """Convert a value in `unit` to stochmod's SI unit of the same kind.

    Parameters
    ----------
    value : float or array_like
        The value(s), in `unit`.
    unit : str
        A unit string (see :func:`parse_unit`), e.g. ``"deg/sqrt(h)"``, ``"ug/sqrt(Hz)"``.
    kind : str, optional
        What the value is: ``"N"``, ``"B"``, ``"K"``, ``"Q"``, ``"R"``, ``"Tc"``, ``"fs"`` or a
        physical kind (see :data:`KINDS`).  When given, a unit of another dimension is refused
        (``to_si(2.4, "deg/h", kind="N")`` raises) and N, B, K, Q must be >= 0, Tc and fs > 0.

    Returns
    -------
    float or ndarray
        The value in SI (``Unit.si``: rad/s, m/s^2, rad/s/sqrt(Hz) ...); a float for a scalar.

    Raises
    ------
    InputError
        Unknown or malformed unit, kind mismatch, non-finite value or wrong sign.
    """
    parsed = _checked_unit(unit, kind)
    arr, scalar = checked_values(value, "value", sign=_sign_for(kind))
    return scalar_or_array(arr * parsed.scale, scalar)


def from_si(value: ArrayLike, unit: str, kind: str | None = None) -> float | np.ndarray:
    """Convert a value in SI to `unit` (the inverse of :func:`to_si`; same arguments)."""
    parsed = _checked_unit(unit, kind)
    arr, scalar = checked_values(value, "value", sign=_sign_for(kind))
    return scalar_or_array(arr / parsed.scale, scalar)


def convert(value: ArrayLike, from_unit: str, to_unit: str, kind: str | None = None
            ) -> float | np.ndarray:
    """Convert `value` from `from_unit` to `to_unit`; both must have the same dimension.

    ``convert(2.42, "deg/sqrt(h)", "deg/h/sqrt(Hz)")`` gives 145.2.
    """
    src = _checked_unit(from_unit, kind)
    dst = _checked_unit(to_unit, kind)
    if src.dims != dst.dims:
        raise InputError(
            f"cannot convert {from_unit!r} ({src.kind}, {src.si}) "
            f"to {to_unit!r} ({dst.kind}, {dst.si})"
        )
    arr, scalar = checked_values(value, "value", sign=_sign_for(kind))
    return scalar_or_array(arr * (src.scale / dst.scale), scalar)


# ---------------------------------------------------------------- per-sample values

def wn_variance(n: ArrayLike, fs: float) -> float | np.ndarray:
    """Per-sample variance of white noise of density N sampled at `fs`: ``N^2 * fs``.

    Parameters
    ----------
    n : float or array_like
        Two-sided white noise density N in u*sqrt(s) = u/sqrt(Hz) (u = rad/s or m/s^2), >= 0.
    fs : float
        Sampling frequency in Hz, > 0.

    Returns
    -------
    float or ndarray
        Variance in u^2.  Quinchia et al. (2013) eq. 27 is this with ``N^2/3600`` (N in
        m/s/sqrt(h)) and ``1/dt = fs``; Gonzalez et al. (2015) divide the PSD ``n^2`` by dt alike.
    """
    fs = check_freq(fs, name="fs")
    arr, scalar = checked_values(n, "N", sign="nonneg")
    return scalar_or_array(arr * arr * fs, scalar)


def wn_density(sigma2: ArrayLike, fs: float) -> float | np.ndarray:
    """White noise density N (u/sqrt(Hz)) from its per-sample variance `sigma2` (u^2) at `fs` Hz."""
    fs = check_freq(fs, name="fs")
    arr, scalar = checked_values(sigma2, "sigma2", sign="nonneg")
    return scalar_or_array(np.sqrt(arr / fs), scalar)


def rw_variance(k: ArrayLike, fs: float) -> float | np.ndarray:
    """Per-sample increment variance of a random walk of coefficient K at `fs`: ``K^2 / fs``.

    Parameters
    ----------
    k : float or array_like
        Rate/acceleration random walk K in u/sqrt(s), >= 0.
    fs : float
        Sampling frequency in Hz, > 0.

    Returns
    -------
    float or ndarray
        Increment variance in u^2: ``x[k] = x[k-1] + w[k]``, ``var w = K^2 / fs``.  Quinchia
        eq. 30 is this with K in m/s/h^1.5, i.e. ``K^2 dt / 3600^3``.
    """
    fs = check_freq(fs, name="fs")
    arr, scalar = checked_values(k, "K", sign="nonneg")
    return scalar_or_array(arr * arr / fs, scalar)


def rw_density(q: ArrayLike, fs: float) -> float | np.ndarray:
    """Random walk coefficient K (u/sqrt(s)) from its increment variance `q` (u^2) at `fs` Hz."""
    fs = check_freq(fs, name="fs")
    arr, scalar = checked_values(q, "q", sign="nonneg")
    return scalar_or_array(np.sqrt(arr * fs), scalar)


def two_sided_density(one_sided: ArrayLike) -> float | np.ndarray:
    """N from a density quoted as the square root of a *one-sided* PSD: ``d / sqrt(2)``.

    stochmod's N (and IEEE's, and Gonzalez eq. 2) is the square root of the two-sided PSD.
    A spectrum-analyser reading ``d`` (one-sided, u/sqrt(Hz)) of the same noise is ``sqrt(2) N``.
    """
    arr, scalar = checked_values(one_sided, "one_sided", sign="nonneg")
    return scalar_or_array(arr / math.sqrt(2.0), scalar)


def one_sided_density(n: ArrayLike) -> float | np.ndarray:
    """Root of the one-sided PSD of white noise of (two-sided) density N: ``sqrt(2) N``."""
    arr, scalar = checked_values(n, "N", sign="nonneg")
    return scalar_or_array(arr * math.sqrt(2.0), scalar)


def bi_floor(b: ArrayLike, factor: float = BI_FACTOR) -> float | np.ndarray:
    """Flat Allan-deviation floor of a bias instability B: ``factor * B`` (u, like B).

    The default factor is exact, ``sqrt(2 ln 2 / pi) = 0.66428``; Quinchia et al. (2013) use
    :data:`BI_FACTOR_IEEE` = 0.664 (eq. 18) and take this floor as the stationary sigma of the
    first-order GM that models B (eq. 29, ``sigma_GM = 0.664 B``).
    """
    arr, scalar = checked_values(b, "B", sign="nonneg")
    return scalar_or_array(arr * _positive_scalar(factor, "factor"), scalar)


def bi_from_floor(floor: ArrayLike, factor: float = BI_FACTOR) -> float | np.ndarray:
    """Bias instability B from the flat Allan-deviation floor: ``floor / factor`` (u).

    Quinchia eq. 18: a floor of 29.57 deg/h with factor 0.664 gives B = 44.533 deg/h.
    """
    arr, scalar = checked_values(floor, "floor", sign="nonneg")
    return scalar_or_array(arr / _positive_scalar(factor, "factor"), scalar)


# ---------------------------------------------------------------- GNSS accuracy

def _radial_factor(p: float) -> float:
    p_val = _positive_scalar(p, "p")
    if p_val >= 1.0:
        raise InputError(f"p must be a probability in (0, 1), got {p!r}")
    return math.sqrt(-2.0 * math.log1p(-p_val))


def cep_to_sigma(cep: ArrayLike, p: float = 0.5) -> float | np.ndarray:
    """Per-axis standard deviation from a circular error radius (Gonzalez et al. 2015, eq. 7).

    Parameters
    ----------
    cep : float or array_like
        Radius (m) of the circle centred on the truth that holds a fraction `p` of the
        horizontal errors; p = 0.5 is the CEP.  >= 0.
    p : float
        Probability in (0, 1); 0.95 gives the R95 radius.

    Returns
    -------
    float or ndarray
        sigma (m) of each horizontal axis, for a circular normal error with equal sigmas:
        ``cep / sqrt(-2 ln(1 - p))``; for the CEP, ``cep / sqrt(2 ln 2) = 0.849322 cep``
        (Gonzalez prints 0.8493).
    """
    arr, scalar = checked_values(cep, "cep", sign="nonneg")
    return scalar_or_array(arr / _radial_factor(p), scalar)


def sigma_to_cep(sigma: ArrayLike, p: float = 0.5) -> float | np.ndarray:
    """Circular error radius (m) holding a fraction `p` of the errors, from per-axis sigma (m)."""
    arr, scalar = checked_values(sigma, "sigma", sign="nonneg")
    return scalar_or_array(arr * _radial_factor(p), scalar)


#: Sensor kinds and the SI unit of their signal.
SENSORS: dict[str, str] = {"gyro": "rad/s", "accel": "m/s^2"}

_U = re.compile(r"\bu\b")
_NAME_HINTS = (("gyro", ("gyr", "omega", "rate", "ang_vel", "angular")),
               ("accel", ("acc", "specific_force", "lin_acc", "linear")))


def sensor_unit(sensor: str) -> str:
    """SI signal unit of a sensor kind (``"gyro"`` -> rad/s, ``"accel"`` -> m/s^2).

    A unit string of a rate or an acceleration (``"rad/s"``, ``"m/s^2"``) is accepted as is.
    """
    if sensor in SENSORS:
        return SENSORS[sensor]
    try:
        kind = parse_unit(sensor).kind
    except InputError:
        kind = ""
    if kind == "rate":
        return "rad/s"
    if kind == "acceleration":
        return "m/s^2"
    raise InputError(f"sensor must be 'gyro' or 'accel' (or a rate or acceleration unit), "
                     f"got {sensor!r}")


def kind_from_name(column: str) -> str | None:
    """The sensor kind a column's name tells (``gyro_x``, ``omega_z`` -> ``"gyro"``;
    ``accel_y``, ``acc_z`` -> ``"accel"``), or None."""
    low = column.lower()
    for kind, hints in _NAME_HINTS:
        if any(h in low for h in hints):
            return kind
    return None


def signal_unit(column: str, sensor: str | None = None) -> str:
    """SI unit of a column: from `sensor` when given, else from the column's name
    (``gyro_x``, ``omega_z`` -> rad/s; ``accel_y``, ``acc_z`` -> m/s^2).

    Raises
    ------
    InputError
        The name does not tell, and no sensor was given.
    """
    if sensor is not None:
        return sensor_unit(sensor)
    kind = kind_from_name(column)
    if kind is not None:
        return SENSORS[kind]
    raise InputError(f"cannot tell whether column {column!r} is a gyroscope or an accelerometer "
                     "from its name: give the sensor kind ('gyro' or 'accel')")


def si_unit_of(template: str, unit: str) -> str:
    """A unit template in the signal unit ``u`` (``"u*sqrt(s)"``) written in `unit`
    (``"(rad/s)*sqrt(s)"``)."""
    return _U.sub(f"({unit})", template)
