"""Models from the coefficients of the classical readings, through the registry.

The readings in :mod:`stochmod.empirical` return coefficients (names of
:data:`stochmod.core.coefficients.COEFFICIENTS`); here each group of coefficients is matched with
the registered family that declares it (:attr:`stochmod.core.process.Process.ieee952`) and built
by that family's :meth:`~stochmod.core.process.Process.from_ieee952`. No family is named: without a
plugin the matching group fails with an error that says which coefficients nothing builds.

==============================  ======================================  ====================
reading                         groups (in model order)                 first-party families
==============================  ======================================  ====================
:class:`AllanReading`           (Q), (N), (B, Tc), (K), (R)             QN, WN, GM, RW, RR
:class:`PSDReading`             (N), (B, Tc) or (B, fc), (K)            WN, GM or BI, RW
:class:`GMAcfFit`               (rate, variance)                        GM
:class:`ARFit`                  (ar, innovation)                        AR
==============================  ======================================  ====================
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from stochmod.core.checks import check_freq, check_positive
from stochmod.core.coefficients import COEFFICIENTS
from stochmod.core.errors import EstimationError, InputError, SpecError
from stochmod.core.model import Model
from stochmod.core.process import Process
from stochmod.plugin.registry import processes
from stochmod.empirical.acf import GMAcfFit
from stochmod.empirical.allan_reading import TERMS as ALLAN_TERMS
from stochmod.empirical.allan_reading import AllanReading
from stochmod.empirical.ar_fit import ARFit
from stochmod.empirical.psd import PSDReading

__all__ = [
    "family_for",
    "model_from_coefficients",
    "allan_model",
    "psd_reading_model",
    "acf_model",
    "ar_model",
    "reading_model",
    "BIAS_OPTIONS",
]

#: ``bias`` options of :func:`psd_reading_model`: the coefficient that comes with B.
BIAS_OPTIONS: dict[str, str] = {"gm": "Tc", "bi": "fc"}


def family_for(names: Sequence[str]) -> type[Process]:
    """The registered family built from exactly the coefficients `names`.

    Raises
    ------
    SpecError
        No registered family declares them (the plugin that would is not installed), or
        several do.
    """
    key = tuple(names)
    table = processes()
    found = [cls for cls in table.values() if any(set(s) == set(key) for s in cls.ieee952)]
    if not found:
        what = "; ".join(f"{n}: {COEFFICIENTS.get(n, '?')}" for n in key)
        raise SpecError(
            f"no registered process family is built from the coefficients {key} ({what}); "
            f"registered families: {', '.join(table) or 'none'}. Install or register the plugin "
            "whose family declares them (Process.ieee952)")
    if len(found) > 1:
        raise SpecError(f"several registered families are built from the coefficients {key}: "
                        f"{', '.join(c.family for c in found)}")
    return found[0]


def model_from_coefficients(groups: Sequence[Mapping[str, Any]], freq: float,
                            options: Sequence[Mapping[str, Any]] | None = None) -> Model:
    """The composite model, bound to `freq` Hz, of one process per coefficient group.

    Parameters
    ----------
    groups : sequence of mapping
        Each ``{name: value}`` (e.g. ``{"B": 1e-4, "Tc": 30.0}``), in model order.
    freq : float
        Sampling frequency, Hz.
    options : sequence of mapping, optional
        Keyword options per group for its family's ``from_ieee952`` (GM's ``convention``).

    Raises
    ------
    EstimationError
        No group (the reading identified nothing).
    SpecError
        A group no registered family is built from.
    """
    freq = check_freq(freq)
    if not groups:
        raise EstimationError("the reading identified no coefficient: no model to build")
    options = [{}] * len(groups) if options is None else list(options)
    procs = tuple(family_for(tuple(g)).from_ieee952(g, freq, **o) for g, o in zip(groups, options))
    return Model(procs, freq)


def allan_model(reading: AllanReading, freq: float | None = None) -> Model:
    """The model of an Allan slope reading: one process per identified term, in the order
    Q, N, B (with Tc), K, R; B's family gets ``convention=reading.gm``.

    ``reading.gm`` "quinchia" (Quinchia et al. 2013 eqs. 19-20, 27-30): the GM of ``beta = 1 /
    Tc`` whose sigma is the flat deviation level 0.664 B; "matched": the GM whose Allan peak
    sits on that level at Tc (see the GM plugin's ``from_ieee952``).
    """
    fs = reading.freq if freq is None else check_freq(freq)
    values = reading.coefficient_values()
    groups, options = [], []
    for name in ALLAN_TERMS:
        if name not in values or (name == "B" and "Tc" not in values):
            continue
        if name == "B":
            groups.append({"B": values["B"], "Tc": values["Tc"]})
            options.append({"convention": reading.gm})
        else:
            groups.append({name: values[name]})
            options.append({})
    if not groups:
        raise EstimationError("the Allan variance reading identified no coefficient")
    return model_from_coefficients(groups, fs, options)


def psd_reading_model(reading: PSDReading, freq: float | None = None, *, bias: str | None = "gm",
                      bias_tc: float | None = None, bias_fc: float | None = None) -> Model:
    """The model of a PSD slope reading: N, B according to `bias`, K (in that order).

    `bias`:

    * ``"gm"`` (default, Quinchia eq. 28-29): B with the correlation time `bias_tc` (s),
      which the PSD does not give (required when B was found): the family built from
      (B, Tc), with the first-party plugins a GM of ``sigma = 0.664 B``, ``beta = 1 / Tc``;
    * ``"bi"``: B above the corner ``fc`` (Hz): `bias_fc`, else ``1 / (2 pi bias_tc)``, else the
      lowest frequency of the fitted B region; the family built from (B, fc) (BI);
    * None: leave B out.

    Raises
    ------
    InputError
        A bad `bias`, `bias_tc` or `bias_fc`; B found with ``"gm"`` and no `bias_tc`.
    EstimationError
        No term.
    """
    fs = reading.freq if freq is None else check_freq(freq)
    if bias is not None and bias not in BIAS_OPTIONS:
        raise InputError(f"bias must be 'gm', 'bi' or None, got {bias!r}")
    tc = None if bias_tc is None else check_positive(bias_tc, name="bias_tc (s)")
    values = reading.coefficient_values()
    groups: list[dict[str, float]] = []
    if "N" in values:
        groups.append({"N": values["N"]})
    if "B" in values and bias == "gm":
        if tc is None:
            raise InputError(
                "bias instability B was read but its correlation time is unknown: pass "
                "bias_tc (s) to model it as GM(B) (Quinchia eq. 28-29), bias='bi' or bias=None")
        groups.append({"B": values["B"], "Tc": tc})
    elif "B" in values and bias == "bi":
        if bias_fc is not None:
            fc = check_positive(bias_fc, name="bias_fc (Hz)")
        else:
            fc = reading.B.f_low if tc is None else 1.0 / (2.0 * math.pi * tc)
        groups.append({"B": values["B"], "fc": fc})
    if "K" in values:
        groups.append({"K": values["K"]})
    if not groups:
        raise EstimationError("the PSD reading identified no term: no model to build")
    return model_from_coefficients(groups, fs)


def acf_model(fit: GMAcfFit, freq: float | None = None, *, use_ls: bool = False) -> Model:
    """The model of an autocorrelation fit: the family built from (rate, variance) (GM)."""
    fs = fit.freq if freq is None else check_freq(freq)
    return model_from_coefficients([fit.coefficient_values(use_ls=use_ls)], fs)


def ar_model(fit: ARFit, freq: float | None = None) -> Model:
    """The model of an AR fit: the family built from (ar, innovation) (AR(p))."""
    fs = fit.freq if freq is None else check_freq(freq)
    return model_from_coefficients([fit.coefficient_values()], fs)


def reading_model(reading: Any, freq: float | None = None, **options: Any) -> Model:
    """The model of any classical reading (Allan, PSD, ACF or AR); `options` go to the
    reading's builder (:func:`psd_reading_model`'s `bias` ..., :func:`acf_model`'s `use_ls`)."""
    builders = {AllanReading: allan_model, PSDReading: psd_reading_model, GMAcfFit: acf_model,
                ARFit: ar_model}
    for cls, build in builders.items():
        if isinstance(reading, cls):
            return build(reading, freq, **options)
    raise InputError(f"reading must be an AllanReading, PSDReading, GMAcfFit or ARFit; got "
                     f"{type(reading).__name__}")
