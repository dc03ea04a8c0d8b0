"""Bias instability (BI): the stochmod plugin for the family ``BI(B, fc)``.

Flicker (1/f) noise of bias instability ``B`` (u) between a corner frequency ``fc`` (Hz) and
the Nyquist frequency, built as a log-uniform mixture of Gauss-Markov processes (see
:class:`BI`). Its state-space form is a fitted sum of GMs (:meth:`BI.gm_approximation`).
"""

from __future__ import annotations

from stochmod.sdk import Process, hookimpl

from ._circulant import circulant_embedding
from ._gm_approx import GMApproximation
from .bi import BI, DEFAULT_N_GM, HALF_FLOOR_TAU_FC

__all__ = ["BI", "GMApproximation", "DEFAULT_N_GM", "HALF_FLOOR_TAU_FC", "circulant_embedding",
           "stochmod_processes"]


@hookimpl
def stochmod_processes() -> list[type[Process]]:
    """Register BI."""
    return [BI]
