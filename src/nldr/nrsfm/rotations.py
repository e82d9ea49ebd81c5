"""Rotations of orthographic cameras: the nearest camera, its completion to a rotation, quaternions.

An orthographic camera R_f (2, 3) is the first two rows of a rotation Q_f = [R_f; r_f1 x r_f2]
(:func:`complete_rotations`). The camera LM and the joint kernel step parameterise rotations by
quaternions q = (w, x, y, z), scalar first, as the paper does ("parameterising each R_i with
quaternions"); any non-zero q is valid (the rotation is that of q / |q|). :func:`quaternion_rotation`
is the one map from quaternions to rotations, with its Jacobian; the inverse map and every other
operation on rotations go through :class:`scipy.spatial.transform.Rotation`.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .reprojection import check_cameras

__all__ = ["nearest_orthonormal_rows", "complete_rotations", "quaternion_rotation", "camera_to_quaternion"]


def nearest_orthonormal_rows(A) -> np.ndarray:
    """Per frame, the 2x3 matrix with orthonormal rows nearest in Frobenius norm (polar factor U V^T).

    Parameters
    ----------
    A : array, shape (F, 2, 3)

    Returns
    -------
    R : array, shape (F, 2, 3)
        R_f R_f^T = I_2.
    """
    A = check_cameras(A, name="A")
    U, _, Vt = np.linalg.svd(A, full_matrices=False)
    return U @ Vt


def complete_rotations(R, *, project: bool = True) -> np.ndarray:
    """Rotations Q (F, 3, 3) whose first two rows are the cameras R (F, 2, 3) and whose third row is
    their cross product (det Q = +1 for orthonormal rows).

    ``project=True`` first replaces R by :func:`nearest_orthonormal_rows`; ``project=False`` completes
    R as given (a basis when its rows are independent, used by :class:`~nldr.nrsfm.CameraFrameVariables`).
    """
    R = check_cameras(R)
    if project:
        R = nearest_orthonormal_rows(R)
    return np.concatenate([R, np.cross(R[:, 0], R[:, 1])[:, None]], axis=1)


def quaternion_rotation(q, jacobian: bool = False):
    """Rotation matrices A(q) (F, 3, 3) of the quaternions q / |q| (q: (F, 4), (w, x, y, z), any
    non-zero length) and, if ``jacobian``, dA/dq (F, 3, 3, 4), else None. No validation (inner loops).

    A = H(q) / |q|^2 with every entry of H a quadratic form in q, so the map is invariant to the scale
    of q and the Jacobian satisfies J q = 0 (the camera LM penalises that direction). The first two
    rows are the orthographic camera of q.
    """
    q = np.asarray(q, dtype=float)
    w, x, y, z = q.T
    n = np.einsum("fi,fi->f", q, q)
    H = np.stack(
        [
            np.stack([w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], -1),
        ],
        axis=1,
    )  # (F, 3, 3), H = |q|^2 A
    A = H / n[:, None, None]
    if not jacobian:
        return A, None
    # dH/dq: every entry of H is a quadratic form in q; its derivative is linear in q
    dH = np.empty(H.shape + (4,))
    dH[:, 0, 0] = 2 * np.stack([w, x, -y, -z], -1)
    dH[:, 0, 1] = 2 * np.stack([-z, y, x, -w], -1)
    dH[:, 0, 2] = 2 * np.stack([y, z, w, x], -1)
    dH[:, 1, 0] = 2 * np.stack([z, y, x, w], -1)
    dH[:, 1, 1] = 2 * np.stack([w, -x, y, -z], -1)
    dH[:, 1, 2] = 2 * np.stack([-x, -w, z, y], -1)
    dH[:, 2, 0] = 2 * np.stack([-y, z, -w, x], -1)
    dH[:, 2, 1] = 2 * np.stack([x, w, z, y], -1)
    dH[:, 2, 2] = 2 * np.stack([w, -x, -y, z], -1)
    # d(H / n) = dH / n - H (2 q^T) / n^2
    J = dH / n[:, None, None, None] - A[..., None] * (2 * q / n[:, None])[:, None, None, :]
    return A, J


def camera_to_quaternion(R) -> np.ndarray:
    """Unit quaternions (w, x, y, z), w >= 0, of orthographic cameras R (F, 2, 3), completed to
    rotations by :func:`complete_rotations` (projected to orthonormal rows first).

    ``quaternion_rotation(q)[0][:, :2]`` reproduces ``nearest_orthonormal_rows(R)``.
    """
    q = Rotation.from_matrix(complete_rotations(R)).as_quat()[:, [3, 0, 1, 2]]  # scipy: scalar last
    q[q[:, 0] < 0] *= -1
    return q
