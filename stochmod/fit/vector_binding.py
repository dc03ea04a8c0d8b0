"""The analytic binding function of eq. 20 evaluated from parameter vectors, without Process
objects.

An optimizer asks for the model's Haar wavelet variance ``phi(theta)`` and its Jacobian a few
hundred times per fit, and a multi-start screen asks for it at many points at once. Through
Process objects each evaluation rebuilds every component (domain checks, attrs instances) and
evaluates each one's closed form separately. :class:`VectorBinding` maps the unconstrained
vector to parameter values with the domains' own maps and membership tests, and asks each
family for all its components (and all the points) in one call of
:meth:`~stochmod.core.vectorised_wv.VectorisedWV.haar_wv_rows`. The numbers are the same, bit for bit, as
``model.from_unconstrained(theta).wv(J)`` and ``wv_jacobian(J)``: the same elementwise
operations, the components summed in the model's order.

It applies when every component's family declares the vectorised-WV protocol
(:class:`~stochmod.core.vectorised_wv.VectorisedWV`, its rows in force) and is rebuilt by the
fast path of :meth:`~stochmod.core.process.Process.from_unconstrained` (scalar parameters of
built-in domains, no further checks: :func:`~stochmod.core.vectorised_wv.wv_rows_domains`):
the built-ins WN, RW, GM, QN and RR. Any other model keeps the Process path.
"""

from __future__ import annotations

import numpy as np

from stochmod.core.model import Model
from stochmod.core.params import Domain, scalar_contains
from stochmod.core.process import Process
from stochmod.core.vectorised_wv import wv_kernel, wv_rows_domains

__all__ = ["VectorBinding"]


class VectorBinding:
    """Haar WV and Jacobian of a model at rows of full unconstrained parameter vectors.

    Build it with :meth:`of` (None when a component's family has no vector form).

    Parameters
    ----------
    template : Model
        The model (bound to its sampling frequency); only its structure is used.
    levels : int
        Number of levels J.
    domains : list of Domain
        The domain of each entry of ``template.vector()``.
    """

    def __init__(self, template: Model, levels: int, domains: list[Domain]):
        self.freq = float(template.freq)
        self.levels = int(levels)
        self.n_params = len(domains)
        ends = np.cumsum([p.n_params for p in template.processes])
        #: each component's columns of the parameter vector, in model order
        self.slices = [slice(int(e) - p.n_params, int(e)) for e, p in zip(ends, template.processes)]
        # entries of the vector per domain (one map and one check per domain, not per entry)
        self._domains: list[tuple[Domain, np.ndarray]] = []
        for d in dict.fromkeys(domains):
            self._domains.append((d, np.array([i for i, di in enumerate(domains) if di is d])))
        # components per family: (a template instance, positions of its components in the model)
        groups: dict[type[Process], list[int]] = {}
        for k, p in enumerate(template.processes):
            groups.setdefault(type(p), []).append(k)
        self._families = [(template.processes[ks[0]], ks) for ks in groups.values()]
        # one point (:meth:`point`): each domain's membership test
        self._tests = [(scalar_contains(d.name), cols) for d, cols in self._domains]
        # the components' kernels (VectorisedWV.haar_wv_kernel), when every one has one
        kernels = [wv_kernel(type(p)) for p in template.processes]
        self._kernels = None if any(k is None for k in kernels) else list(zip(kernels, self.slices))
        self._m = 2.0 ** np.arange(self.levels)
        self._m.flags.writeable = False  # as the families' own half-widths: one compiled variant

    @classmethod
    def of(cls, template: Model, levels: int) -> VectorBinding | None:
        """The vector binding of `template`, or None when a component's family needs its
        Process objects (:func:`~stochmod.core.vectorised_wv.wv_rows_domains`)."""
        domains: list[Domain] = []
        for p in template.processes:
            found = wv_rows_domains(type(p))
            if found is None:
                return None
            domains.extend(found)
        if any(d.elementwise_derivative is None or scalar_contains(d.name) is None for d in domains):
            return None
        return cls(template, levels, domains)

    def values(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Natural parameter values at rows of `theta` (P, n) and whether each row lies in
        its domains (the verdict of :meth:`~stochmod.core.process.Process.from_unconstrained`)."""
        valid = np.ones(theta.shape[0], dtype=bool)
        if len(self._domains) == 1:  # one map for the whole vector (all positive, say)
            values = self._domains[0][0].from_unconstrained(theta)
            parts = [(self._domains[0][0], values)]
        else:
            values = np.empty_like(theta)
            parts = []
            for domain, cols in self._domains:
                values[:, cols] = v = domain.from_unconstrained(theta[:, cols])
                parts.append((domain, v))
        for domain, v in parts:
            inside = scalar_contains(domain.name)  # the fast path's own test, value by value
            if all(map(inside, v.ravel().tolist())):  # every row at once
                continue
            for i, row in enumerate(v.tolist()):
                if valid[i] and not all(map(inside, row)):
                    valid[i] = False
        return values, valid

    def point(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """The model's WV (J,), unit^2, and its Jacobian with respect to the natural parameter
        vector (J, n) at one unconstrained vector `theta` (n,), or None when it leaves its
        domains: :meth:`values` and :meth:`evaluate` for one row, the same numbers, with the
        domain tests done value by value; by the components' kernels
        (:attr:`~stochmod.core.vectorised_wv.VectorisedWV.haar_wv_kernel`) when every one has
        one (the same digits again)."""
        if len(self._domains) == 1:
            values = self._domains[0][0].from_unconstrained(theta)
        else:
            values = np.empty_like(theta)
            for domain, cols in self._domains:
                values[cols] = domain.from_unconstrained(theta[cols])
        for inside, cols in self._tests:
            if not all(map(inside, values[cols].tolist())):
                return None
        if self._kernels is not None:  # one kernel call per component, in model order
            wv = np.zeros(self.levels)
            jac = np.empty((self.levels, self.n_params))
            if all(kernel(values[s], self._m, self.freq, wv, jac[:, s])
                   for kernel, s in self._kernels):
                return wv, jac
        wv, jac = self.evaluate(values[None, :])
        return wv[0], jac[0]

    def derivatives(self, theta: np.ndarray) -> np.ndarray:
        """``d value / d theta`` of every entry of one unconstrained vector `theta` (n,): the
        diagonal of :meth:`~stochmod.core.process.Process.transform_jacobian`."""
        if len(self._domains) == 1:  # one map for the whole vector
            return self._domains[0][0].elementwise_derivative(theta)
        d = np.empty_like(theta)
        for domain, cols in self._domains:
            d[cols] = domain.elementwise_derivative(theta[cols])
        return d

    def evaluate(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The model's WV (P, J), unit^2, and its Jacobian with respect to the natural
        parameter vector (P, J, n) at rows of `values` (P, n), all inside their domains."""
        P = values.shape[0]
        parts: list[np.ndarray | None] = [None] * len(self.slices)
        jac = np.empty((P, self.levels, self.n_params))
        for proto, ks in self._families:
            if len(ks) == 1:
                rows = values[:, self.slices[ks[0]]]
            else:
                rows = np.concatenate([values[:, self.slices[k]] for k in ks])
            wv, dwv = proto.haar_wv_rows(rows, self.levels, self.freq)
            for i, k in enumerate(ks):
                parts[k] = wv[i * P : (i + 1) * P]
                jac[:, :, self.slices[k]] = dwv[i * P : (i + 1) * P]
        total = parts[0].copy()
        for part in parts[1:]:  # in model order: the digits of Model.wv's sum
            total += part
        return total, jac
