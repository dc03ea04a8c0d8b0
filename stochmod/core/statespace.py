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
    "discretise",
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


def discretise(F: np.ndarray, W: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation of ``dx = F x dt + dw``, ``E[dw dw'] = W dt`` over `dt`.

    ``Phi = expm(F dt)`` and ``Q = int_0^dt expm(F s) W expm(F s)' ds`` (Van Loan's pair) by
    scaling and squaring: over the sub-step ``h = dt / 2^s`` with ``||F h||_1 <= 1/2`` both are
    summed to double precision by their power series in scaled form, ``Phi = sum A^k / k!`` and
    ``Q = sum T_k / (k + 1)`` with ``A = F h``, ``T_0 = W h``, ``T_k = (A T_(k-1) + T_(k-1) A')
    / k`` (every term bounded by ``||W h|| / k!``, so a Gauss-Markov pole far faster than
    ``1/dt`` cannot overflow it), and the ``2^s`` sub-steps are composed back exactly by
    repeated squaring. Van Loan's own block matrix holds ``expm(-F dt)``, which overflows on
    such a pole; this form never grows. The squarings carry ``Phi - I`` rather than ``Phi`` (``(I + E)^2 = I + 2E + E^2``), so the decay of a slow
    mode stays exact to rounding however many squarings a fast pole demands.

    Parameters
    ----------
    F : ndarray, shape (n, n)
        Continuous dynamics, 1/s.
    W : ndarray, shape (n, n)
        Spectral density of the driving noise (``G Qc G'``), state unit^2 per s.
    dt : float
        Step, s.

    Returns
    -------
    Phi, Q : ndarray, shape (n, n)

    Raises
    ------
    InputError
        If `F` or `W` holds a non-finite value.
    """
    n = F.shape[0]
    norm = float(np.abs(F).sum(axis=0).max(initial=0.0)) * dt
    if not (math.isfinite(norm) and np.isfinite(W).all()):
        raise InputError("the continuous model to discretise holds a non-finite value "
                         "(a model parameter is infinite or NaN)")
    s = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    h = math.ldexp(dt, -s)
    a = 2.0 * math.ldexp(norm, -s)  # >= ||A|| + ||A'||, at most 1
    # terms up to order K: the remainder of both series is below (a^K / (K + 1)!) ~ 1e-17
    K, bound = 1, a / 2.0
    while bound > 1e-17:
        K += 1
        bound *= a / (K + 1)
    A = F * h
    # X_k = [A^k | U_(k-1)] with U_0 = W h, U_j = A U_(j-1) + U_(j-1) A': Phi = sum A^k / k!
    # and Q = sum U_j / (j + 1)!, so both halves of X_k take the coefficient 1 / k!, and one
    # product A @ X_k advances both (A^k commutes with A)
    X = np.empty((n, 2 * n))
    X[:, :n] = A
    X[:, n:] = W * h
    acc = X.copy()
    c = 1.0
    for k in range(2, K + 1):
        X = A @ X
        U = X[:, n:]
        X[:, n:] = U + U.T
        c /= k
        acc += X * c
    E, Q = acc[:, :n], acc[:, n:]  # Phi - I: squaring it keeps a slow mode's decay exact
    for _ in range(s):  # (Phi, Q) over 2h from h: Phi^2 = I + 2E + E^2, Q <- Phi Q Phi' + Q
        EQ = E @ Q
        Q = 2.0 * Q + EQ + EQ.T + EQ @ E.T
        E = 2.0 * E + E @ E
    E[np.diag_indices(n)] += 1.0
    return E, 0.5 * (Q + Q.T)


def van_loan(block: ContinuousBlock, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation of a continuous block over `dt` seconds (Van Loan, 1978).

    Returns
    -------
    Phi, Q : ndarray
        ``Phi = expm(F dt)`` and ``Q = int_0^dt expm(F s) G Qc G^T expm(F^T s) ds``.

    Notes
    -----
    Van Loan's block matrix holds ``expm(-F dt)``, which overflows when ``F dt`` is large
    (a fast Gauss-Markov process over a long filter step).  Unlike :func:`discretise`, which
    carries ``Phi - I`` to keep a slow mode's decay exact, this form keeps a deep decay
    (``exp(-beta dt)`` far below 1e-16) exact, as a family's own block needs. The step is therefore split into
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
