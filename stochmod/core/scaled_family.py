"""The base of families whose Haar wavelet variance is one scale parameter times a factor.

White noise (``sigma2 / 2^j``), a random walk (``sigma2 (2 m^2 + 1) / (12 m)``) and
quantization noise (``3 Q2 / (2 m^2)``) have a Haar WV linear in their one parameter:
``wv_j = scale * factor_j(freq)``. A family of that shape subclasses :class:`ScaledFamily`
and declares :meth:`~ScaledFamily.haar_factor`; the base gives ``wv``, ``wv_jacobian``, the
vectorised rows of :class:`~stochmod.core.vectorised_wv.VectorisedWV` and a compiled kernel,
all with the same digits: each is ``scale * factor`` elementwise, the Jacobian the factor.
"""

from __future__ import annotations

import abc
import functools
from collections.abc import Callable
from typing import Any, ClassVar

import attrs
import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.checks import check_freq, check_positive_int
from stochmod.core.jit import AVAILABLE as _COMPILED
from stochmod.core.jit import compiled
from stochmod.core.process import Process
from stochmod.core.vectorised_wv import VectorisedWV

__all__ = ["ScaledFamily"]


@compiled(fastmath=frozenset())
def _add_scaled(values: np.ndarray, factor: np.ndarray, wv: np.ndarray,
                jac: np.ndarray) -> bool:  # pragma: no cover - compiled
    """``values[0] * factor`` added to `wv`, `factor` into ``jac[:, 0]``: one product and one
    sum per level, the operations of :meth:`ScaledFamily.haar_wv_rows` on one row."""
    scale = values[0]
    for j in range(factor.size):
        wv[j] += scale * factor[j]
        jac[j, 0] = factor[j]
    return True


@functools.lru_cache(maxsize=256)
def _factor(cls: type[ScaledFamily], levels: int, freq: float) -> np.ndarray:
    """``cls.haar_factor(levels, freq)`` as a read-only float array of shape (levels,),
    computed once per family, number of levels and sampling frequency."""
    factor = np.array(cls.haar_factor(levels, freq), dtype=np.float64)
    if factor.shape != (levels,):
        raise TypeError(f"{cls.__name__}.haar_factor({levels}, {freq}) has shape "
                        f"{factor.shape}, expected {(levels,)}")
    factor.flags.writeable = False
    return factor


@functools.cache
def _kernel_of(cls: type[ScaledFamily]) -> Callable[..., bool]:
    def kernel(values: np.ndarray, m: np.ndarray, freq: float, wv: np.ndarray,
               jac: np.ndarray) -> bool:
        return _add_scaled(values, _factor(cls, m.size, freq), wv, jac)

    kernel.__qualname__ = f"{cls.__qualname__}.haar_wv_kernel"
    kernel.__doc__ = (f":class:`~stochmod.core.vectorised_wv.VectorisedWV` kernel of "
                      f"{cls.__name__}: its factor times the scale, compiled")
    return kernel


class _ScaledKernel:
    """The class attribute ``ScaledFamily.haar_wv_kernel``: the compiled kernel of the class
    it is read from (its own :meth:`~ScaledFamily.haar_factor`), None without the compiler."""

    def __get__(self, instance: object, owner: type[ScaledFamily]) -> Any:
        return _kernel_of(owner) if _COMPILED else None


@attrs.frozen
class ScaledFamily(Process, VectorisedWV):
    """Base of families with one parameter whose Haar WV is ``scale * haar_factor(levels, freq)``.

    A subclass declares, besides what every family declares, one scalar parameter (the WV
    is linear in it: its role is ``"variance"``) and :meth:`haar_factor`, the Haar WV at unit
    scale. The base provides :meth:`wv` (Haar; other wavelets by the generic fallback unless
    :attr:`factor_for_every_wavelet`), :meth:`wv_jacobian` (the factor), the rows of
    :class:`~stochmod.core.vectorised_wv.VectorisedWV` and its compiled kernel, each
    ``scale * factor`` elementwise, so they agree bit for bit. A subclass that changes
    :meth:`haar_factor` keeps them in force; one that changes :meth:`wv` or
    :meth:`wv_jacobian` loses them (the protocol's rule).

    Attributes
    ----------
    factor_for_every_wavelet : bool
        Whether :meth:`haar_factor` is the unit-scale WV for every wavelet filter, not only
        Haar (white noise: the level-j MODWT filter has energy ``2^-j``). Default False.
    """

    factor_for_every_wavelet: ClassVar[bool] = False
    haar_wv_kernel: ClassVar[Any] = _ScaledKernel()

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        specs = cls.parameter_specs
        if specs and not (len(specs) == 1 and specs[0].size == 1):
            raise TypeError(f"{cls.__name__}: a ScaledFamily has one scalar parameter, got "
                            f"{[(s.name, s.size) for s in specs]}")

    @classmethod
    @abc.abstractmethod
    def haar_factor(cls, levels: int, freq: float) -> np.ndarray:
        """The Haar WV at unit scale, levels 1..`levels` at `freq` Hz: shape (levels,),
        dimensionless, a function of `levels` and `freq` only (it is computed once)."""

    def _scale(self) -> float:
        return getattr(self, self.parameter_specs[0].name)

    def wv(self, levels: int, freq: float, wavelet: str = "haar") -> np.ndarray:
        """``scale * haar_factor(levels, freq)`` (u^2); other wavelets: the generic fallback
        (or the same product when :attr:`factor_for_every_wavelet`)."""
        if wavelet != "haar" and not self.factor_for_every_wavelet:
            return super().wv(levels, freq, wavelet)
        self.require_values()
        levels = check_positive_int(levels, name="levels")
        return self._scale() * _factor(type(self), levels, check_freq(freq))

    def wv_jacobian(self, levels: int, freq: float) -> np.ndarray:
        """``d wv / d scale = haar_factor(levels, freq)``, shape (levels, 1)."""
        levels = check_positive_int(levels, name="levels")
        return _factor(type(self), levels, check_freq(freq))[:, None].copy()

    def haar_wv_rows(self, values: ArrayLike, levels: int,
                     freq: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`wv` and :meth:`wv_jacobian` at rows ``(scale,)`` of `values` (K, 1), bit
        for bit: shapes (K, J) in u^2 and (K, J, 1)."""
        values = np.asarray(values, dtype=np.float64).reshape(-1, 1)
        levels = check_positive_int(levels, name="levels")
        factor = _factor(type(self), levels, check_freq(freq))
        jac = np.broadcast_to(factor[:, None], (values.shape[0], levels, 1)).copy()
        return values * factor, jac
