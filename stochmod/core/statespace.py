"""State-space blocks of processes, exact re-discretisation, and their block-diagonal assembly.

A process contributes a :class:`StateSpaceBlock` to a navigation Kalman filter: its states,
transition ``Phi`` and process-noise covariance ``Q`` over a step ``dt``, its output row ``H``
(how the states add to the sensor reading), a white feed-through variance (WN, QN), and the
initial covariance ``P0``. Where a continuous-time form ``dx = F x dt + G dW`` with
``E[dW dW'] = Qc dt`` exists, re-discretisation at any ``dt`` is exact (Van Loan, 1978).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import attrs
import numpy as np
from scipy.linalg import block_diag, expm

from stochmod.core.errors import InputError

__all__ = [
    "ContinuousBlock",
    "StateSpaceBlock",
    "van_loan",
    "compose_steps",
    "stack_blocks",
]


def _matrix(value: object) -> np.ndarray:
    return np.atleast_2d(np.asarray(value, dtype=np.float64))


@attrs.frozen
class ContinuousBlock:
    """Continuous-time linear SDE ``dx = F x dt + G dW``, ``E[dW dW^T] = Qc dt``.

    Attributes
    ----------
    F : ndarray (k, k)
        Dynamics matrix, 1/s.
    G : ndarray (k, r)
        Noise input matrix.
    Qc : ndarray (r, r)
        Spectral density of the driving white noise, state unit^2 / s (u^2 s for a state in u/s ...).
    """

    F: np.ndarray = attrs.field(converter=_matrix)
    G: np.ndarray = attrs.field(converter=_matrix)
    Qc: np.ndarray = attrs.field(converter=_matrix)


def van_loan(block: ContinuousBlock, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation of a continuous block over `dt` seconds (Van Loan, 1978).

    Returns
    -------
    Phi, Q : ndarray
        ``Phi = expm(F dt)`` and ``Q = int_0^dt expm(F s) G Qc G^T expm(F^T s) ds``.

    Notes
    -----
    Van Loan's block matrix holds ``expm(-F dt)``, which overflows when ``F dt`` is large
    (a fast Gauss-Markov process over a long filter step). The step is therefore split into
    ``2^s`` sub-steps with ``||F dt / 2^s|| <= 1`` that are composed exactly by repeated
    squaring (:func:`compose_steps`).
    """
    k = block.F.shape[0]
    gqg = block.G @ block.Qc @ block.G.T
    norm = float(np.abs(block.F).sum(axis=1).max(initial=0.0)) * dt
    squarings = max(0, math.ceil(math.log2(norm))) if norm > 1 else 0
    h = dt / 2.0**squarings
    M = np.zeros((2 * k, 2 * k))
    M[:k, :k] = -block.F
    M[:k, k:] = gqg
    M[k:, k:] = block.F.T
    E = expm(M * h)
    Phi = expm(block.F * h)  # on its own: exact zeros where F's structure has them
    Q = Phi @ E[:k, k:]
    Q = 0.5 * (Q + Q.T)
    return compose_steps(Phi, Q, 2**squarings) if squarings else (Phi, Q)


def compose_steps(Phi: np.ndarray, Q: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Compose `k` steps of ``x <- Phi x + w``, ``w ~ N(0, Q)``: returns ``(Phi^k, sum Phi^i Q Phi^i')``.

    Uses repeated squaring, so the cost is O(log k) matrix products.
    """
    if k < 1:
        raise InputError(f"number of steps must be >= 1, got {k}")
    n = Phi.shape[0]
    acc_P, acc_Q = np.eye(n), np.zeros((n, n))
    pw_P, pw_Q = Phi.copy(), Q.copy()
    while k:
        if k & 1:
            acc_Q = pw_P @ acc_Q @ pw_P.T + pw_Q
            acc_P = pw_P @ acc_P
        k >>= 1
        if k:
            pw_Q = pw_P @ pw_Q @ pw_P.T + pw_Q
            pw_P = pw_P @ pw_P
    return acc_P, 0.5 * (acc_Q + acc_Q.T)


@attrs.frozen
class StateSpaceBlock:
    """A process's (or a composite model's) state augmentation at filter step `dt`.

    Attributes
    ----------
    state_names : tuple of str
        One name per state.
    Phi : ndarray (k, k)
        Transition over `dt`.
    Q : ndarray (k, k)
        Discrete process-noise covariance over `dt`.
    H : ndarray (k,)
        Output row: the process's contribution to the sensor reading is ``H @ x``.
    P0 : ndarray (k, k)
        Initial (stationary where it exists) state covariance.
    white_var : float
        Variance of the white feed-through added to each reading, signal unit^2 per sample
        at the model's sampling frequency (WN, QN).
    dt : float
        Step in seconds.
    continuous : ContinuousBlock or None
        The continuous-time form when one exists (not for AR(p)).
    """

    state_names: tuple[str, ...] = attrs.field(converter=tuple)
    Phi: np.ndarray = attrs.field(converter=_matrix)
    Q: np.ndarray = attrs.field(converter=_matrix)
    H: np.ndarray = attrs.field(converter=lambda v: np.asarray(v, dtype=np.float64).reshape(-1))
    P0: np.ndarray = attrs.field(converter=_matrix)
    white_var: float = 0.0
    dt: float = 1.0
    continuous: ContinuousBlock | None = None

    def __attrs_post_init__(self) -> None:
        k = len(self.state_names)
        if k == 0:  # feed-through only: keep 0x0 matrices, not 1x0 from atleast_2d
            for name in ("Phi", "Q", "P0"):
                object.__setattr__(self, name, np.zeros((0, 0)))
        for name in ("Phi", "Q", "P0"):
            if getattr(self, name).shape != (k, k):
                raise InputError(f"{name} has shape {getattr(self, name).shape}, expected {(k, k)}")
        if self.H.shape != (k,):
            raise InputError(f"H has shape {self.H.shape}, expected {(k,)}")

    @property
    def n_states(self) -> int:
        """Number of states."""
        return len(self.state_names)

    @property
    def F(self) -> np.ndarray | None:
        """Continuous dynamics matrix, or None."""
        return None if self.continuous is None else self.continuous.F

    @property
    def G(self) -> np.ndarray | None:
        """Continuous noise input matrix, or None."""
        return None if self.continuous is None else self.continuous.G

    @property
    def Qc(self) -> np.ndarray | None:
        """Continuous driving-noise spectral density, or None."""
        return None if self.continuous is None else self.continuous.Qc

    def renamed(self, prefix: str) -> StateSpaceBlock:
        """Return the block with every state name prefixed by ``prefix + '.'``."""
        return attrs.evolve(self, state_names=tuple(f"{prefix}.{s}" for s in self.state_names))


def stack_blocks(blocks: Sequence[StateSpaceBlock], dt: float) -> StateSpaceBlock:
    """Assemble independent blocks into one: block-diagonal Phi, Q, P0 (and F, G, Qc when
    every block has them), concatenated output rows, summed white feed-through."""
    if not blocks:
        raise InputError("no blocks to stack")
    names = tuple(n for b in blocks for n in b.state_names)
    if len(set(names)) != len(names):
        raise InputError(f"duplicate state names in {names}")

    def diag(mats: list[np.ndarray]) -> np.ndarray:
        mats = [m for m in mats if m.size]
        return block_diag(*mats) if mats else np.zeros((0, 0))

    stateful = [b for b in blocks if b.n_states]
    continuous = None
    if stateful and all(b.continuous is not None for b in stateful):
        continuous = ContinuousBlock(
            diag([b.continuous.F for b in stateful]),
            diag([b.continuous.G for b in stateful]),
            diag([b.continuous.Qc for b in stateful]),
        )
    return StateSpaceBlock(
        state_names=names,
        Phi=diag([b.Phi for b in blocks]),
        Q=diag([b.Q for b in blocks]),
        H=np.concatenate([b.H for b in blocks]) if names else np.zeros(0),
        P0=diag([b.P0 for b in blocks]),
        white_var=float(sum(b.white_var for b in blocks)),
        dt=dt,
        continuous=continuous,
    )
