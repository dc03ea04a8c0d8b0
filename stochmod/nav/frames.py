"""Rotations: quaternions (scalar first), direction cosine matrices, roll/pitch/heading.

Conventions (Gonzalez et al. 2015, Section III-A2, and DESIGN.md "Navigation"):

- ``C_nb`` maps body-frame vectors (x forward, y right, z down) into the local-level NED frame,
  ``v_n = C_nb @ v_b``, and ``C_nb = Rz(heading) @ Ry(pitch) @ Rx(roll)``.
- A quaternion ``q = (q0, q1, q2, q3)`` stores the scalar FIRST (the seed's eq. 12 stores it last;
  eq. 14 is the same matrix with the indices shifted) and represents the same rotation as
  ``C_nb``: ``quat_to_dcm(q) == C_nb``.
- Roll, pitch and heading are in **degrees** at the public edge (:func:`rph_to_dcm`,
  :func:`dcm_to_rph`); every other function works in radians.

All functions are vectorised over leading dimensions (``(..., 3)``, ``(..., 4)``, ``(..., 3, 3)``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "skew",
    "quat_multiply",
    "quat_conjugate",
    "quat_normalize",
    "quat_to_dcm",
    "dcm_to_quat",
    "rotvec_to_quat",
    "quat_to_rotvec",
    "dcm_to_rotvec",
    "rotvec_to_dcm",
    "rph_to_dcm",
    "dcm_to_rph",
    "rph_to_quat",
    "quat_to_rph",
]


def skew(v: ArrayLike) -> np.ndarray:
    """Cross-product matrix ``[v x]`` with ``skew(a) @ b == cross(a, b)``; shape (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    if v.ndim == 1:  # the common case, without the stacking overhead
        x, y, w = v.tolist()
        return np.array([[0.0, -w, y], [w, 0.0, -x], [-y, x, 0.0]])
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack(
        [np.stack([z, -w, y], -1), np.stack([w, z, -x], -1), np.stack([-y, x, z], -1)], -2
    )


def quat_multiply(p: ArrayLike, q: ArrayLike) -> np.ndarray:
    """Hamilton product ``p * q`` (scalar first): the rotation ``q`` followed by ``p`` when
    both map the same way (``dcm(p * q) == dcm(p) @ dcm(q)``)."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    p0, p1, p2, p3 = np.moveaxis(p, -1, 0)
    q0, q1, q2, q3 = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
            p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
            p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
            p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0,
        ],
        -1,
    )


def quat_conjugate(q: ArrayLike) -> np.ndarray:
    """Conjugate (the inverse rotation of a unit quaternion)."""
    q = np.array(q, dtype=float)
    q[..., 1:] *= -1.0
    return q


def quat_normalize(q: ArrayLike) -> np.ndarray:
    """Unit quaternion with a non-negative scalar part (Gonzalez eq. 13h)."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def quat_to_dcm(q: ArrayLike) -> np.ndarray:
    """Direction cosine matrix of a unit quaternion (Gonzalez eq. 14a-14i, scalar first)."""
    if isinstance(q, tuple):  # one quaternion, in the filter's loop: without the stacking
        q0, q1, q2, q3 = q
        return np.array([
            [q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3),
             2 * (q1 * q3 + q0 * q2)],
            [2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3,
             2 * (q2 * q3 - q0 * q1)],
            [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1),
             q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3]])
    q0, q1, q2, q3 = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack(
        [
            np.stack([q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3),
                      2 * (q1 * q3 + q0 * q2)], -1),
            np.stack([2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3,
                      2 * (q2 * q3 - q0 * q1)], -1),
            np.stack([2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1),
                      q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3], -1),
        ],
        -2,
    )


def dcm_to_quat(C: ArrayLike) -> np.ndarray:
    """Unit quaternion (scalar first, ``q0 >= 0``) of a rotation matrix.

    Uses the largest of the four squared components (Shepperd's method), so it is accurate for
    every rotation, including 180 degrees.
    """
    C = np.asarray(C, dtype=float)
    tr = C[..., 0, 0] + C[..., 1, 1] + C[..., 2, 2]
    cand = np.stack([tr, C[..., 0, 0], C[..., 1, 1], C[..., 2, 2]], -1)
    k = np.argmax(cand, axis=-1)
    s = np.sqrt(np.maximum(1.0 + 2.0 * np.take_along_axis(cand, k[..., None], -1)[..., 0] - tr,
                           0.0))  # = 4 |q_k| / 2 = 2|q_k|
    d32, d13, d21 = C[..., 2, 1] - C[..., 1, 2], C[..., 0, 2] - C[..., 2, 0], C[..., 1, 0] - C[..., 0, 1]
    s32, s13, s21 = C[..., 2, 1] + C[..., 1, 2], C[..., 0, 2] + C[..., 2, 0], C[..., 1, 0] + C[..., 0, 1]
    rows = [
        np.stack([s * s, d32, d13, d21], -1),
        np.stack([d32, s * s, s21, s13], -1),
        np.stack([d13, s21, s * s, s32], -1),
        np.stack([d21, s13, s32, s * s], -1),
    ]
    q = np.choose(k[..., None], rows) / (2.0 * s[..., None])
    return quat_normalize(q)


def rotvec_to_quat(phi: ArrayLike) -> np.ndarray:
    """Quaternion of the rotation by angle ``|phi|`` (rad) about ``phi / |phi|``
    (Gonzalez eq. 13b-13f; series near zero)."""
    phi = np.asarray(phi, dtype=float)
    a = np.linalg.norm(phi, axis=-1)
    half = 0.5 * a
    small = a < 1e-6
    k = np.where(small, 0.5 - a * a / 48.0, np.sin(half) / np.where(small, 1.0, a))
    return np.concatenate([np.cos(half)[..., None], k[..., None] * phi], -1)


def quat_to_rotvec(q: ArrayLike) -> np.ndarray:
    """Rotation vector (rad) of a unit quaternion; angle in [0, pi]."""
    q = quat_normalize(q)
    s = np.linalg.norm(q[..., 1:], axis=-1)
    angle = 2.0 * np.arctan2(s, q[..., 0])
    small = s < 1e-12
    k = np.where(small, 2.0, angle / np.where(small, 1.0, s))
    return k[..., None] * q[..., 1:]


def rotvec_to_dcm(phi: ArrayLike) -> np.ndarray:
    """Rotation matrix of one rotation vector `phi` (3,), rad, by Rodrigues' formula
    ``I + (sin a / a) [phi x] + ((1 - cos a) / a^2) [phi x]^2``, ``a = |phi|`` (series near
    zero); the matrix of :func:`rotvec_to_quat` (the filter's small per-fix rotations,
    without the arrays of the quaternion path)."""
    x, y, z = (float(c) for c in np.asarray(phi, dtype=float).reshape(3))
    a2 = x * x + y * y + z * z
    if a2 < 1e-12:
        s, c = 1.0 - a2 / 6.0, 0.5 - a2 / 24.0
    else:
        a = math.sqrt(a2)
        s, c = math.sin(a) / a, (1.0 - math.cos(a)) / a2
    return np.array([
        [1.0 - c * (y * y + z * z), c * x * y - s * z, c * x * z + s * y],
        [c * x * y + s * z, 1.0 - c * (x * x + z * z), c * y * z - s * x],
        [c * x * z - s * y, c * y * z + s * x, 1.0 - c * (x * x + y * y)]])


def dcm_to_rotvec(C: ArrayLike) -> np.ndarray:
    """Rotation vector (rad) of a rotation matrix."""
    return quat_to_rotvec(dcm_to_quat(C))


def rph_to_dcm(rph: ArrayLike) -> np.ndarray:
    """``C_nb = Rz(heading) Ry(pitch) Rx(roll)`` from roll, pitch, heading in **degrees**."""
    r, p, h = np.moveaxis(np.radians(np.asarray(rph, dtype=float)), -1, 0)
    cr, sr, cp, sp, ch, sh = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(h), np.sin(h)
    return np.stack(
        [
            np.stack([ch * cp, ch * sp * sr - sh * cr, ch * sp * cr + sh * sr], -1),
            np.stack([sh * cp, sh * sp * sr + ch * cr, sh * sp * cr - ch * sr], -1),
            np.stack([-sp, cp * sr, cp * cr], -1),
        ],
        -2,
    )


def dcm_to_rph(C: ArrayLike) -> np.ndarray:
    """Roll, pitch, heading in **degrees** (Gonzalez eq. 15a-15c); heading in (-180, 180]."""
    C = np.asarray(C, dtype=float)
    roll = np.arctan2(C[..., 2, 1], C[..., 2, 2])
    pitch = np.arcsin(np.clip(-C[..., 2, 0], -1.0, 1.0))
    heading = np.arctan2(C[..., 1, 0], C[..., 0, 0])
    return np.degrees(np.stack([roll, pitch, heading], -1))


def rph_to_quat(rph: ArrayLike) -> np.ndarray:
    """Quaternion of ``C_nb`` from roll, pitch, heading in degrees."""
    return dcm_to_quat(rph_to_dcm(rph))


def quat_to_rph(q: ArrayLike) -> np.ndarray:
    """Roll, pitch, heading in degrees of a unit quaternion."""
    return dcm_to_rph(quat_to_dcm(q))
