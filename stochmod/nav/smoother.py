"""Fixed-interval smoothing of the closed-loop error-state filter (Rauch-Tung-Striebel).

The seeds use the smoothed INS/GNSS solution as their reference trajectory (Stebler et al.
2014, Section VI-B) without giving its equations; these are Rauch, Tung & Striebel (1965),
"Maximum likelihood estimates of linear dynamic systems", AIAA J. 3(8), 1445-1450, in the
gain form of Groves (2013), Chapter 3 (Kalman smoothing), carried into the feedback filter's
error coordinates.

Nodes. The forward pass (:mod:`stochmod.nav.filter`) keeps one node per filter epoch (one
more where a recovery scales the covariance between two updates of the same epoch). At node
``j`` it holds the error of its corrected nominal state, ``e_j`` (estimate minus truth, reset to
zero after the feedback), with covariance ``P_j`` (after the updates). The step to node ``j+1``
predicts ``u_{j+1} = Phi_j e_j + w_j`` with ``P^-_{j+1} = Phi_j P_j Phi_j' + Q_j`` (Gonzalez et
al. 2015, Alg. 1 line 7); a recovery is a step with ``Phi = I`` and ``P^- = lam P``. The
updates at ``j+1`` apply ``delta_{j+1}`` (the sum of the fed-back estimates ``K y`` in the
pre-update coordinates) and the resets ``G``, so ``u_{j+1} = A^-1 e_{j+1} + delta_{j+1}``
with ``A = G_k ... G_1`` (identity for the psi model; for modified-phi ``I + E`` with ``E``
the ``[Delta v x]`` block of the velocity-attitude resets, ``A^-1 = I - E``).

Backward pass. With the smoothed mean and covariance of ``e_{j+1}``, ``(s_{j+1}, S_{j+1})``,
and ``s_N = 0``, ``S_N = P_N`` at the last node, RTS gives for node ``j``

- ``C_j = P_j Phi_j' (P^-_{j+1})^-1`` (the smoother gain),
- ``s_j = C_j (delta_{j+1} + A^-1 s_{j+1})`` (the predicted mean of ``u_{j+1}`` is zero),
- ``S_j = P_j + C_j (A^-1 S_{j+1} A^-T - P^-_{j+1}) C_j' = M_j + C_j A^-1 S_{j+1} A^-T C_j'``
  with ``M_j = P_j - C_j Phi_j P_j`` (since ``P^-_{j+1} C_j' = Phi_j P_j``).

So the forward pass stores only ``C_j`` and ``M_j`` (two n x n float64 arrays a node, in
preallocated blocks), ``delta_j`` and the reset's ``Delta v``. The smoothed state at a node is
its nominal state corrected by ``s_j`` as the filter's feedback would (Gonzalez Alg. 2 lines
28-30, eq. 26); between two nodes the error is interpolated linearly in time between
``s_j`` and the pre-update ``u_{j+1}`` (no update lies between them), second order in the
filter step like the covariance step itself.
"""

from __future__ import annotations

import math

import numpy as np

from stochmod.core.jit import compiled
from stochmod.nav import earth, frames

__all__ = ["SmootherStore", "correct_rows", "interpolate_errors", "node_ranges"]


class SmootherStore:
    """What the backward pass needs from the forward pass, in preallocated float64 blocks.

    Parameters
    ----------
    n : int
        Number of error states.
    capacity : int
        Expected number of nodes (grown by half when exceeded).
    """

    def __init__(self, n: int, capacity: int) -> None:
        cap = max(int(capacity), 2)
        self.n = n
        self.C = np.empty((cap, n, n))
        self.M = np.empty((cap, n, n))
        self.delta = np.zeros((cap, n))
        self.dv = np.zeros((cap, 3))
        self.epoch = np.zeros(cap, dtype=np.int64)
        self.j = 0  # the open node
        self.P_last: np.ndarray | None = None

    @property
    def nbytes(self) -> int:
        """Bytes held by the stored arrays."""
        return sum(a.nbytes for a in (self.C, self.M, self.delta, self.dv, self.epoch))

    def _open(self, epoch: int) -> None:
        self.j += 1
        if self.j >= self.C.shape[0]:
            grow = max(self.C.shape[0] // 2, 16)
            for name in ("C", "M", "delta", "dv", "epoch"):
                a = getattr(self, name)
                extra = np.zeros((grow, *a.shape[1:]), dtype=a.dtype)
                setattr(self, name, np.concatenate([a, extra]))
        self.delta[self.j] = 0.0
        self.dv[self.j] = 0.0
        self.epoch[self.j] = epoch

    def step(self, P: np.ndarray, Phi: np.ndarray, P_pred: np.ndarray, epoch: int) -> None:
        """Close the open node (covariance `P`) with the step ``Phi`` to the prediction
        `P_pred` of the node it opens for `epoch`: ``C = P Phi' P_pred^-1``, ``M = P - C Phi P``."""
        j = self.j
        if not _gain(P, Phi, P_pred, self.C[j], self.M[j]):  # P_pred not positive definite
            PhiP = Phi @ P
            C = np.linalg.lstsq(P_pred, PhiP, rcond=None)[0].T
            M = P - C @ PhiP
            self.C[j] = C
            self.M[j] = 0.5 * (M + M.T)
        self._open(epoch)

    def inflate(self, P: np.ndarray, lam: float, epoch: int) -> None:
        """Close the open node before the covariance `P` is scaled by `lam` (a recovery): a
        step with ``Phi = I`` and ``P^- = lam P``, so ``C = I / lam``, ``M = (1 - 1/lam) P``."""
        j = self.j
        self.C[j] = np.eye(self.n) / lam
        self.M[j] = (1.0 - 1.0 / lam) * P
        self._open(epoch)

    def correct(self, dx: np.ndarray) -> None:
        """Add a fed-back estimate `dx` to the open node's ``delta`` (in its pre-update
        coordinates: the resets so far at this node undone, ``(I - E) dx``)."""
        j = self.j
        add = dx.copy()
        if self.dv[j].any():
            add[3:6] -= np.cross(self.dv[j], dx[6:9])
        self.delta[j] += add

    def reset(self, dv_applied: np.ndarray) -> None:
        """Record a modified-phi reset ``G = I + [Delta v x]`` (velocity rows, attitude
        columns) at the open node."""
        self.dv[self.j] += dv_applied

    def finish(self, P: np.ndarray) -> None:
        """Keep the covariance of the last node."""
        self.P_last = P.copy()

    def backward(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The backward pass (module notes).

        Returns
        -------
        s : ndarray (J, n)
            Smoothed error of each node's corrected nominal state.
        u : ndarray (J, n)
            Smoothed error of each node's pre-update nominal state.
        sd : ndarray (J, n)
            Smoothed 1-sigma of each state.
        nav_cov : ndarray (J, 9, 9)
            Smoothed covariance of the 9 navigation states (of all states when fewer).
        """
        J, n = self.j + 1, self.n
        k = min(n, 9)
        s = np.zeros((J, n))
        u = np.zeros((J, n))
        sd = np.empty((J, n))
        nav = np.empty((J, k, k))
        S = self.P_last
        sd[-1] = np.sqrt(np.clip(np.diag(S), 0.0, None))
        nav[-1] = S[:k, :k]
        u[-1] = self.delta[J - 1] + _undo_resets(self.dv[J - 1], s[-1])
        for j in range(J - 2, -1, -1):
            dv = self.dv[j + 1]
            if dv.any():  # A^-1 S A^-T
                S = S.copy()
                E = frames.skew(dv)
                S[3:6] -= E @ S[6:9]
                S[:, 3:6] -= S[:, 6:9] @ E.T
            C = self.C[j]
            s[j] = C @ u[j + 1]
            S = self.M[j] + C @ S @ C.T
            S = 0.5 * (S + S.T)
            sd[j] = np.sqrt(np.clip(np.diag(S), 0.0, None))
            nav[j] = S[:k, :k]
            u[j] = self.delta[j] + _undo_resets(self.dv[j], s[j])
        return s, u, sd, nav


@compiled(fastmath=frozenset())
def _gain(P: np.ndarray, Phi: np.ndarray, P_pred: np.ndarray, C: np.ndarray,
          M: np.ndarray) -> bool:
    """The smoother gain ``C = P Phi' P_pred^-1`` and ``M = P - C Phi P`` (symmetrised) into
    `C` and `M`, by the Cholesky factor of `P_pred` scaled to unit diagonal (state variances
    span 20 decades); False, with `C` and `M` unset, when that is not positive definite."""
    n = P.shape[0]
    PhiP = np.zeros((n, n))
    for i in range(n):
        for k in range(n):
            a = Phi[i, k]
            if a != 0.0:
                for j in range(n):
                    PhiP[i, j] += a * P[k, j]
    d = np.empty(n)
    for i in range(n):
        v = math.sqrt(P_pred[i, i]) if P_pred[i, i] > 0.0 else 0.0
        d[i] = v if v > 0.0 else 1.0
    L = np.zeros((n, n))  # lower Cholesky factor of P_pred / (d d')
    for j in range(n):
        acc = P_pred[j, j] / (d[j] * d[j])
        for k in range(j):
            acc -= L[j, k] * L[j, k]
        if not acc > 0.0:
            return False
        ljj = math.sqrt(acc)
        L[j, j] = ljj
        for i in range(j + 1, n):
            acc = P_pred[i, j] / (d[i] * d[j])
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            L[i, j] = acc / ljj
    X = np.empty((n, n))  # (P_pred / (d d')) X = PhiP / d, column by column
    for c in range(n):
        for i in range(n):
            acc = PhiP[i, c] / d[i]
            for k in range(i):
                acc -= L[i, k] * X[k, c]
            X[i, c] = acc / L[i, i]
        for i in range(n - 1, -1, -1):
            acc = X[i, c]
            for k in range(i + 1, n):
                acc -= L[k, i] * X[k, c]
            X[i, c] = acc / L[i, i]
    for i in range(n):
        for c in range(n):
            C[c, i] = X[i, c] / d[i]  # C = (P_pred^-1 Phi P)'
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += C[i, k] * PhiP[k, j]
            M[i, j] = P[i, j] - acc
    for i in range(n):
        for j in range(i + 1, n):
            u = 0.5 * (M[i, j] + M[j, i])
            M[i, j] = u
            M[j, i] = u
    return True


def _undo_resets(dv: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``A^-1 e`` with ``A^-1 = I - E``, ``E`` the ``[dv x]`` block (rows 3:6, columns 6:9)."""
    if not dv.any():
        return e
    out = e.copy()
    out[3:6] -= np.cross(dv, e[6:9])
    return out


def correct_rows(rows: np.ndarray, err: np.ndarray, error_model: str) -> np.ndarray:
    """Navigation rows corrected by their estimated errors, as the filter's feedback does.

    Parameters
    ----------
    rows : ndarray (k, 10)
        ``(lat rad, lon rad, h m, vn, ve, vd m/s, q0..q3)``.
    err : ndarray (k, 9)
        Errors (estimate minus truth): position NED m, velocity m/s (``dv`` for the psi model,
        ``dv'`` for modified-phi), psi rad.
    error_model : {"psi", "modified-phi"}

    Returns
    -------
    ndarray (k, 10)
        The corrected rows (Gonzalez Alg. 2 lines 28-30, eq. 26 in multiplicative form).
    """
    out = rows.copy()
    lat, h = rows[:, 0], rows[:, 2]
    sl = np.sin(lat)
    w = 1.0 - earth.E2 * sl * sl
    re = earth.A / np.sqrt(w)
    rn = re * (1.0 - earth.E2) / w
    out[:, 0] = lat - err[:, 0] / (rn + h)
    out[:, 1] = rows[:, 1] - err[:, 1] / ((re + h) * np.cos(out[:, 0]))
    out[:, 2] = h + err[:, 2]
    psi = err[:, 6:9]
    v = rows[:, 3:6]
    if error_model == "modified-phi":
        rot = frames.quat_to_dcm(frames.rotvec_to_quat(psi))
        out[:, 3:6] = np.einsum("kij,kj->ki", rot, v - err[:, 3:6] + np.cross(v, psi))
    else:
        out[:, 3:6] = v - err[:, 3:6]
    q = frames.quat_multiply(frames.rotvec_to_quat(psi), rows[:, 6:10])
    out[:, 6:10] = q / np.linalg.norm(q, axis=1)[:, None]
    return out


def interpolate_errors(times: np.ndarray, epoch_rows: np.ndarray, epoch_time: np.ndarray,
                       first_node: np.ndarray, last_node: np.ndarray, s: np.ndarray,
                       u: np.ndarray) -> np.ndarray:
    """Smoothed error at every row: ``s`` of the epoch's last node at an epoch row, linear in
    time between that and the next epoch's pre-update ``u`` in between (module notes).

    Parameters
    ----------
    times : ndarray (R,)
        Row times, s.
    epoch_rows : ndarray (E,)
        Row of each epoch (increasing; the last row is an epoch).
    epoch_time : ndarray (E,)
        Time of each epoch, s.
    first_node, last_node : ndarray (E,)
        Nodes of each epoch.
    s, u : ndarray (J, n)
        From :meth:`SmootherStore.backward`.
    """
    R = times.size
    e = np.searchsorted(epoch_rows, np.arange(R), side="right") - 1
    at_epoch = epoch_rows[e] == np.arange(R)
    nxt = np.minimum(e + 1, epoch_rows.size - 1)
    span = epoch_time[nxt] - epoch_time[e]
    wgt = np.where(at_epoch | (span <= 0), 0.0,
                   (times - epoch_time[e]) / np.where(span > 0, span, 1.0))[:, None]
    a = s[last_node[e], :9]
    b = u[first_node[nxt], :9]
    return (1.0 - wgt) * a + wgt * b


def node_ranges(epoch: np.ndarray, n_epochs: int) -> tuple[np.ndarray, np.ndarray]:
    """First and last node of each epoch from the (non-decreasing) epoch index of every node."""
    k = np.arange(n_epochs)
    first = np.searchsorted(epoch, k, side="left")
    last = np.searchsorted(epoch, k, side="right") - 1
    if np.any(last < first):  # pragma: no cover - every epoch has a node
        raise RuntimeError("an epoch without a smoother node")
    return first, last
