"""Inverse-variance weighting with static weights from each sensor's noise level.

``w_i = v_i^-1 / sum_k v_k^-1``, the minimum-variance weights for independent sensors (eq. 1
with unequal ``sigma_i``), and the synthetic signal's variance ``1 / sum_i v_i^-1``. The level
``v_i`` of sensor i is, in order of preference:

- from its fitted stochmod model (``models=``, or the models of ``calibration.json`` files
  written by ``stochmod calibrate``, ``calibrations=``): the white-noise variance per sample
  (the model's white feed-through, ``model.augment().white_var``), or with ``tau=`` its
  theoretical Haar wavelet variance at averaging time ``tau`` seconds;
- from the data when no model is given (``n >= 3``): the Haar wavelet variance at ``tau`` (or at
  level 1) of each sensor's error, recovered from the residuals ``r_i = x_i - mean_k x_k`` by the
  "three-cornered hat" identity for independent sensors,
  ``E[nu(r_i)] = nu_i (1 - 2/n) + sum_k nu_k / n^2``, solved exactly for the ``nu_i``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

import attrs
import numpy as np

from stochmod.sdk import (
    CombinationResult,
    EstimationError,
    InputError,
    Model,
    as_sensor_array,
    check_freq,
    hookimpl,
    model_from_spec,
    residuals_from_mean,
    wvar,
)

__all__ = ["InverseVariance", "calibration_models", "three_cornered_hat", "stochmod_combiners"]


def three_cornered_hat(residual_levels: np.ndarray) -> np.ndarray:
    """Each sensor's own level from the levels of the residuals from the mean (axis 0: sensors).

    For ``n >= 3`` independent sensors, ``v(r_i) = v_i (1 - 2/n) + S / n^2`` with
    ``S = sum_k v_k = n / (n - 1) sum_k v(r_k)``.
    """
    n = residual_levels.shape[0]
    if n < 3:
        raise InputError("separating the sensors' levels from their residuals needs at least 3 "
                         "sensors; give each sensor's model (models= or calibrations=)")
    total = n / (n - 1) * residual_levels.sum(axis=0)
    return (residual_levels - total / n**2) / (1.0 - 2.0 / n)


def calibration_models(calibration: str | Path | dict, columns: Sequence[str] | None) -> list[Model]:
    """The models of `columns` from a ``calibration.json`` (path or its parsed content)."""
    if not isinstance(calibration, dict):
        path = Path(calibration)
        try:
            calibration = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise InputError(f"cannot read the calibration file {path}: {exc}") from None
    table = calibration.get("columns") if isinstance(calibration, dict) else None
    if not isinstance(table, dict) or not table:
        raise InputError("a calibration has a non-empty 'columns' table (as written by "
                         "`stochmod calibrate`)")
    if columns is None:
        if len(table) != 1:
            raise InputError(f"the calibration has columns {sorted(table)}: say which with columns=")
        columns = list(table)
    missing = [c for c in columns if c not in table]
    if missing:
        raise InputError(f"the calibration has no column(s) {missing}; it has {sorted(table)}")
    return [model_from_spec(table[c]["model"]) for c in columns]


def _model_level(model: Any, tau: float | None, freq: float | None) -> float:
    model = model_from_spec(model, freq) if not isinstance(model, Model) else model
    if model.freq is None and freq is not None:
        model = model.bind(check_freq(freq))
    if tau is None:
        level = float(model.augment().white_var)
        if not level > 0:
            raise InputError(f"model {model.name} has no white-noise component: pass tau= (s) to "
                             "weight by its wavelet variance")
        return level
    if model.freq is None:
        raise InputError(f"model {model.name} is not bound to a sampling frequency: tau needs one")
    freq = float(model.freq)
    j = int(round(np.log2(tau * freq))) + 1
    if j < 1 or not np.isclose(2.0 ** (j - 1) / freq, tau, rtol=1e-9):
        raise InputError(f"tau = {tau} s is not a dyadic averaging time 2^(j-1)/freq of {model.name} "
                         f"at {freq} Hz")
    return float(model.wv(j)[-1])


@attrs.frozen
class InverseVariance:
    """Static weights ``1 / v_i`` from each sensor's model or its three-cornered-hat level."""

    name: ClassVar[str] = "inverse-variance"
    description: ClassVar[str] = ("static weights 1/v_i from each sensor's fitted model (white-noise "
                                  "level or wavelet variance at tau) or a three-cornered hat")
    assumes: ClassVar[str] = ("independent sensors whose error levels are constant in time "
                              "(known from their models or separable from the residuals)")

    def combine(self, x: Any, *, models: Sequence[Any] | None = None,
                calibrations: Sequence[Any] | None = None, columns: Sequence[str] | None = None,
                tau: float | None = None, freq: float | None = None) -> CombinationResult:
        """Weight by the inverse of each sensor's level.

        Parameters
        ----------
        x : array_like, shape (n, T) or (n, T, 3)
            Time-aligned sensors, unit u.
        models : sequence, optional
            One model (``stochmod.Model`` or spec) per sensor; for triads one sequence of 3 per sensor.
        calibrations : sequence, optional
            One ``calibration.json`` (path or dict) per sensor; `columns` names the column(s)
            used (one for (n, T), three for triads).
        columns : sequence of str, optional
            Columns of the calibrations.
        tau : float, optional
            Averaging time (s) of the wavelet variance used as level; default: the white-noise
            variance per sample (models) or the level-1 wavelet variance (data).
        freq : float, optional
            Sampling frequency (Hz) of `x`; needed with `tau` when no model is given, and binds
            models given without one.
        """
        x = as_sensor_array(x, min_length=4)
        n, axes = x.shape[0], (x.shape[2] if x.ndim == 3 else None)
        if models is not None and calibrations is not None:
            raise InputError("give models= or calibrations=, not both")
        if calibrations is not None:
            if len(calibrations) != n:
                raise InputError(f"{len(calibrations)} calibration(s) for {n} sensors")
            models = [calibration_models(c, columns) for c in calibrations]
            if not axes:
                models = [ms[0] for ms in models]
        info: dict[str, Any] = {}
        if models is not None:
            if len(models) != n:
                raise InputError(f"{len(models)} model(s) for {n} sensors")
            if axes:
                levels = np.array([[_model_level(m, tau, freq) for m in ms] for ms in models])
                if levels.shape != (n, axes):
                    raise InputError(f"triads need {axes} models per sensor")
            else:
                levels = np.array([_model_level(m, tau, freq) for m in models])
            info["source"] = "models"
        else:
            r = residuals_from_mean(x)
            if not np.any(r):
                levels = np.ones((n,) + x.shape[2:])
                info["note"] = "identical sensors"
            else:
                level = 1 if tau is None else int(round(np.log2(tau * check_freq(freq)))) + 1
                if level < 1:
                    raise InputError(f"tau = {tau} s is shorter than one sample at {freq} Hz")
                cols = r.reshape(n, r.shape[1], -1)
                wv = np.array([[wvar(cols[i, :, a], 1.0, levels=level).wv[-1]
                                for a in range(cols.shape[2])] for i in range(n)])
                levels = three_cornered_hat(wv).reshape((n,) + x.shape[2:])
                if level == 1:
                    levels = 2.0 * levels  # Haar level 1 of white noise is sigma2 / 2
                if np.any(levels <= 0):
                    raise EstimationError(
                        f"the three-cornered hat gave non-positive levels {levels.ravel()}: the "
                        "sensors are not independent, or one is far better than the others; give "
                        "their models instead")
                info["source"] = f"three-cornered hat at level {level}"
        inv = 1.0 / levels
        w = inv / inv.sum(axis=0)
        weights = np.broadcast_to(w[:, None] if x.ndim == 2 else w[:, None, :], x.shape).copy()
        var = np.zeros(x.shape[2:]) if info.get("note") else 1.0 / inv.sum(axis=0)
        return CombinationResult(
            signal=np.sum(weights * x, axis=0), weights=weights,
            variance=np.broadcast_to(var, x.shape[1:]).copy(), method=self.name,
            assumes=self.assumes,
            sensor_variance=np.zeros_like(levels) if info.get("note") else levels, info=info)


@hookimpl
def stochmod_combiners() -> list[Any]:
    return [InverseVariance()]
