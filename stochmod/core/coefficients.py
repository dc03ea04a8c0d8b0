"""The coefficient vocabulary shared by the classical readings and the process families.

The readings in :mod:`stochmod.empirical` (Allan and PSD slope readings, the autocorrelation
decay, AR fits) return *coefficients*: numbers with the names below, in SI for a signal of
unit ``u``. A process family declares which sets of coefficients it is built from
(:attr:`stochmod.core.process.Process.ieee952`) and builds itself with
:meth:`~stochmod.core.process.Process.from_ieee952`; :mod:`stochmod.fit.classical` turns a reading into a
model through the registry, so neither the readings nor the core name a family.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from stochmod.core.errors import InputError

__all__ = ["COEFFICIENTS", "check_coefficients"]

#: name -> meaning and SI unit. Q, N, B, K, R are the IEEE Std 952 coefficients of an Allan
#: (or PSD) slope reading; the others come with them or from the other readings.
COEFFICIENTS: dict[str, str] = {
    "Q": "quantization, u*s (Allan variance 3 Q^2 / tau^2)",
    "N": "white-noise density, u*sqrt(s) = u/sqrt(Hz) (Allan variance N^2 / tau)",
    "B": "bias instability, u (flat Allan deviation sqrt(2 ln 2 / pi) B)",
    "K": "random-walk coefficient, u/sqrt(s) (Allan variance K^2 tau / 3)",
    "R": "rate ramp, u/s (Allan variance R^2 tau^2 / 2)",
    "Tc": "correlation time read with B, s",
    "fc": "corner frequency of a 1/f law, Hz",
    "rate": "decay rate of an exponential autocorrelation, 1/s",
    "variance": "variance of the exponentially correlated part, u^2",
    "ar": "AR coefficients phi_1..phi_p of x_t = sum phi_i x_(t-i) + e_t (dimensionless)",
    "innovation": "innovation variance per sample of an AR fit, u^2",
}


def check_coefficients(coefficients: Mapping[str, Any], names: Iterable[str],
                       who: str) -> dict[str, Any]:
    """The coefficients `names` from `coefficients`, checked: present, finite, positive
    (``"ar"``: a finite sequence, returned as a tuple of floats).

    Raises
    ------
    InputError
        A name outside :data:`COEFFICIENTS`, a missing coefficient or a bad value; the message
        starts with `who` (e.g. ``"GM.from_ieee952"``).
    """
    out: dict[str, Any] = {}
    for name in names:
        if name not in COEFFICIENTS:
            raise InputError(f"{who}: {name!r} is not a coefficient name; known: {list(COEFFICIENTS)}")
        if name not in coefficients:
            raise InputError(f"{who} needs the coefficient {name!r} ({COEFFICIENTS[name]}); "
                             f"got {sorted(coefficients)}")
        value = coefficients[name]
        if name == "ar":
            arr = np.atleast_1d(np.asarray(value, dtype=np.float64)).reshape(-1)
            if not (arr.size and np.all(np.isfinite(arr))):
                raise InputError(f"{who}: ar must be a non-empty sequence of finite numbers, "
                                 f"got {value!r}")
            out[name] = tuple(float(c) for c in arr)
            continue
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise InputError(f"{who}: {name} must be a positive number, got {value!r}") from None
        if not (math.isfinite(v) and v > 0):
            raise InputError(f"{who}: {name} must be a positive, finite number, got {value!r}")
        out[name] = v
    return out
