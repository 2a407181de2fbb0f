"""The numpy rotation conversions against scipy's Rotation (an independent implementation),
at random rotations and at the edge cases (identity, tiny angles, half turns)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from sixplus3.kinematics import rotations as rot


def samples() -> Rotation:
    rng = np.random.default_rng(11)
    axes = rng.normal(size=(40, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.r_[rng.uniform(0, np.pi, 30), 0.0, 1e-12, 1e-9, 1e-6, 1e-4,
                   np.pi, np.pi - 1e-9, np.pi - 1e-6, np.pi / 2, 3.0]
    return Rotation.from_rotvec(axes * angles[:, None])


def test_conversions_agree_with_scipy() -> None:
    R = samples()
    M = R.as_matrix()
    np.testing.assert_allclose(rot.matrix_from_rotvec(R.as_rotvec()), M, atol=1e-14)
    q = rot.quat_from_matrix(M)
    assert np.all(q[:, 3] >= 0)
    np.testing.assert_allclose(np.abs(np.einsum("ni,ni->n", q, R.as_quat())), 1.0,
                               atol=1e-12)
    np.testing.assert_allclose(rot.matrix_from_quat(q), M, atol=1e-14)
    r = rot.rotvec_from_matrix(M)
    np.testing.assert_allclose(rot.matrix_from_rotvec(r), M, atol=1e-12)
    assert np.all(np.linalg.norm(r, axis=1) <= np.pi + 1e-12)
    ref = R.as_rotvec()
    small = np.linalg.norm(ref, axis=1) < np.pi - 1e-3  # the half turn has two rotvecs
    np.testing.assert_allclose(r[small], ref[small], atol=1e-12)
    for rpy in ([0.1, -0.2, 0.3], [np.pi / 2, 0.0, 0.0], [1.0, 1.4, -2.0]):
        np.testing.assert_allclose(rot.matrix_from_rpy(*rpy),
                                   Rotation.from_euler("xyz", rpy).as_matrix(), atol=1e-15)
