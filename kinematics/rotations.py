"""Batched rotation conversions in numpy (no scipy import on the validator's path).

Conventions: quaternions are (x, y, z, w) like scipy and Pinocchio's configuration, and
are returned with w >= 0; rotation vectors r have |r| in [0, pi]; roll/pitch/yaw is the
fixed-axis URDF convention R = Rz(yaw) Ry(pitch) Rx(roll).  tests/test_rotations.py
checks every function against scipy.spatial.transform.Rotation.
"""

from __future__ import annotations

import numpy as np


def skew(v: np.ndarray) -> np.ndarray:
    """(..., 3, 3) [v]x, the cross-product matrices of vectors (..., 3)."""
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def matrix_from_rotvec(r: np.ndarray) -> np.ndarray:
    """(n, 3, 3) R = exp([r]x) (Rodrigues) of rotation vectors (n, 3) [rad].

    Near r = 0 the coefficients sin(t)/t and (1 - cos t)/t^2 use their Taylor series
    (below t^2 = 1e-8, where the closed forms lose digits)."""
    r = np.atleast_2d(np.asarray(r, dtype=float))
    t2 = np.sum(r * r, axis=1)
    t = np.sqrt(t2)
    small = t2 < 1e-8
    safe = np.where(small, 1.0, t)
    a = np.where(small, 1 - t2 / 6 + t2 * t2 / 120, np.sin(safe) / safe)
    b = np.where(small, 0.5 - t2 / 24 + t2 * t2 / 720, (1 - np.cos(safe)) / safe**2)
    K = skew(r)
    return np.eye(3) + a[:, None, None] * K + b[:, None, None] * (K @ K)


def quat_from_matrix(R: np.ndarray) -> np.ndarray:
    """(n, 4) unit quaternions (x, y, z, w), w >= 0, of rotation matrices (n, 3, 3)
    (Shepperd's method: the largest of the four squared components first)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    n = len(R)
    tr = np.trace(R, axis1=1, axis2=2)
    diag = np.stack([R[:, 0, 0], R[:, 1, 1], R[:, 2, 2], tr], axis=1)
    k = np.argmax(diag, axis=1)
    q = np.empty((n, 4))
    # k = 3: w is largest
    m = k == 3
    if m.any():
        s = np.sqrt(1.0 + tr[m]) * 2
        q[m, 3] = 0.25 * s
        q[m, 0] = (R[m, 2, 1] - R[m, 1, 2]) / s
        q[m, 1] = (R[m, 0, 2] - R[m, 2, 0]) / s
        q[m, 2] = (R[m, 1, 0] - R[m, 0, 1]) / s
    for i in range(3):
        m = k == i
        if not m.any():
            continue
        j, l = (i + 1) % 3, (i + 2) % 3
        s = np.sqrt(1.0 + R[m, i, i] - R[m, j, j] - R[m, l, l]) * 2
        q[m, i] = 0.25 * s
        q[m, 3] = (R[m, l, j] - R[m, j, l]) / s
        q[m, j] = (R[m, j, i] + R[m, i, j]) / s
        q[m, l] = (R[m, l, i] + R[m, i, l]) / s
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return np.where(q[:, 3:4] < 0, -q, q)


def matrix_from_quat(q: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotation matrices of quaternions (n, 4) (x, y, z, w), normalised first."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    x, y, z, w = q.T
    R = np.empty((len(q), 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - z * w)
    R[:, 0, 2] = 2 * (x * z + y * w)
    R[:, 1, 0] = 2 * (x * y + z * w)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - x * w)
    R[:, 2, 0] = 2 * (x * z - y * w)
    R[:, 2, 1] = 2 * (y * z + x * w)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def rotvec_from_quat(q: np.ndarray) -> np.ndarray:
    """(n, 3) rotation vectors, |r| <= pi, of quaternions (n, 4) (x, y, z, w), the
    package's one rotation-vector function.  Quaternions need not be unit: each is
    normalised, and one of norm <= 1e-9 or with a non-finite entry gives the zero vector
    (such a vector only seeds a Newton solve, e.g. from an untrusted file's columns; a
    caller that needs a valid rotation checks the quaternion itself)."""
    q = np.array(np.atleast_2d(q), dtype=float)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    good = np.isfinite(norm) & (norm > 1e-9)
    q = np.where(good, q / np.where(good, norm, 1.0), [0.0, 0.0, 0.0, 1.0])
    q = np.where(q[:, 3:4] < 0, -q, q)
    v = q[:, :3]
    s = np.linalg.norm(v, axis=1)
    angle = 2 * np.arctan2(s, q[:, 3])
    # angle / s -> 2 / w as s -> 0 (series: 2/w (1 - s^2 / (3 w^2)))
    small = s < 1e-8
    scale = np.where(small, 2.0 / q[:, 3] * (1 - s**2 / (3 * q[:, 3] ** 2)),
                     angle / np.where(small, 1.0, s))
    return v * scale[:, None]


def rotvec_from_matrix(R: np.ndarray) -> np.ndarray:
    """(n, 3) rotation vectors of rotation matrices (n, 3, 3)."""
    return rotvec_from_quat(quat_from_matrix(R))


def matrix_from_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """(3, 3) R = Rz(yaw) Ry(pitch) Rx(roll) [rad] (URDF fixed-axis convention)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])
