"""The optional vectorised wavelet-variance protocol of process families.

Every family declares its Haar wavelet variance and Jacobian for one parameter vector
(:meth:`~stochmod.core.process.Process.wv`, :meth:`~stochmod.core.process.Process.wv_jacobian`).
A family that can also evaluate them at many parameter vectors at once, without building
Process objects, says so by inheriting :class:`VectorisedWV`; the GMWM binding
(:mod:`stochmod.fit.vector_binding`) then evaluates models of such families from parameter
vectors alone, a few hundred times per fit. :func:`wv_rows_domains` and :func:`wv_kernel`
tell the binding whether, and how, it may do so for a family class.
"""

from __future__ import annotations

import abc
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike

from stochmod.core.params import Domain
from stochmod.core.process import Process, scalar_domains

__all__ = ["VectorisedWV", "declares_wv_rows", "wv_kernel", "wv_rows_domains"]


class VectorisedWV(abc.ABC):
    """Mixin of a family whose Haar WV and Jacobian come at many parameter vectors at once.

    A family opts in by inheriting it next to :class:`~stochmod.core.process.Process`
    (``class GM(Process, VectorisedWV)``) and implementing :meth:`haar_wv_rows`; it may also
    declare the compiled one-point form :attr:`haar_wv_kernel`. Both must give the digits of
    ``wv`` and ``wv_jacobian`` bit for bit: the optimizer uses them in their place.

    The rows are in force only in the class that defines :meth:`haar_wv_rows` and below it
    as long as no subclass changes ``wv`` or ``wv_jacobian``: the class of the MRO that
    defines :meth:`haar_wv_rows` must be the one that defines ``wv`` and ``wv_jacobian``, or
    a subclass of it (:func:`declares_wv_rows`). A subclass that changes its WV without its
    own rows is thus evaluated through Process objects, never by its parent's rows. Likewise
    a kernel is in force only when declared in the class that defines the rows in force, or
    below (:func:`wv_kernel`).

    Attributes
    ----------
    haar_wv_kernel : callable or None
        Optional fast form of :meth:`haar_wv_rows` for one component (compiled, or a thin
        wrapper of compiled code), declared as a ``staticmethod``:
        ``kernel(values, m, freq, wv, jac) -> bool`` adds the component's Haar WV at the
        parameter values `values` (n_params,) to `wv` (J,), writes its Jacobian into `jac`
        (J, n_params; may be a strided view) and returns True, with the digits of
        :meth:`haar_wv_rows`; it returns False (leaving `wv` unspecified) where it does not
        apply. `m` holds the half-widths ``1, 2, 4, ..., 2^(J-1)`` (read-only), `freq` is in
        Hz. The optimizer calls it when every component of the model has one; None (the
        default): not offered.
    """

    __slots__ = ()

    haar_wv_kernel: ClassVar[Any] = None

    @abc.abstractmethod
    def haar_wv_rows(self, values: ArrayLike, levels: int,
                     freq: float) -> tuple[np.ndarray, np.ndarray]:
        """Haar ``wv`` and ``wv_jacobian`` at many parameter vectors of this family at once.

        Parameters
        ----------
        values : array_like, shape (K, n_params)
            Parameter vectors (``vector()`` order, natural units), each inside its domains.
        levels : int
            Number of levels J.
        freq : float
            Sampling frequency, Hz.

        Returns
        -------
        wv : ndarray (K, J)
            Row k: ``self.from_vector(values[k]).wv(levels, freq)``, u^2, bit for bit.
        jacobian : ndarray (K, J, n_params)
            Row k: ``self.from_vector(values[k]).wv_jacobian(levels, freq)``, bit for bit.

        Notes
        -----
        The same elementwise operations as ``wv`` and ``wv_jacobian``, vectorised over the
        rows; a sum is never regrouped.
        """


def _owner(cls: type, name: str) -> type:
    """The class of `cls`'s MRO that defines attribute `name`."""
    return next(c for c in cls.__mro__ if name in vars(c))


def declares_wv_rows(cls: type) -> bool:
    """Whether the family class `cls` declares :class:`VectorisedWV` rows in force: it
    inherits the protocol, and the class that defines its
    :meth:`~VectorisedWV.haar_wv_rows` is the one that defines its ``wv`` and
    ``wv_jacobian`` or a subclass of it (see :class:`VectorisedWV`)."""
    if not (isinstance(cls, type) and issubclass(cls, VectorisedWV)):
        return False
    rows = _owner(cls, "haar_wv_rows")
    return all(issubclass(rows, _owner(cls, name)) for name in ("wv", "wv_jacobian"))


def wv_rows_domains(cls: type[Process]) -> tuple[Domain, ...] | None:
    """The domains of `cls`'s parameters, in order, when a binding may evaluate the family
    from parameter vectors alone: its rows are in force (:func:`declares_wv_rows`) and its
    instances are nothing more than their scalar values checked against those domains
    (:func:`~stochmod.core.process.scalar_domains`); None otherwise. The binding then has the
    same domain checks and the same numbers as through Process objects."""
    return scalar_domains(cls) if declares_wv_rows(cls) else None


def wv_kernel(cls: type[Process]) -> Any:
    """`cls`'s :attr:`~VectorisedWV.haar_wv_kernel` when the family has a vector form
    (:func:`wv_rows_domains`) and declares the kernel in the class that defines its
    :meth:`~VectorisedWV.haar_wv_rows`, or below (a subclass that changes the rows does not
    inherit its parent's kernel); None otherwise."""
    if wv_rows_domains(cls) is None:
        return None
    kernel = cls.haar_wv_kernel
    if kernel is None or not issubclass(_owner(cls, "haar_wv_kernel"), _owner(cls, "haar_wv_rows")):
        return None
    return kernel
