"""Rotations of orthographic cameras: the nearest camera, its completion to a rotation, quaternions.

An orthographic camera R_f (2, 3) is the first two rows of a rotation Q_f = [R_f; r_f1 x r_f2]
(:func:`complete_rotations`). The camera LM and the joint kernel step parameterise rotations by
quaternions q = (w, x, y, z), scalar first, as the paper does ("parameterising each R_i with
quaternions"); any non-zero q is valid (the rotation is that of q / |q|). :func:`quaternion_rotation`
is the one map from quaternions to rotations, with its Jacobian; the inverse map and every other
operation on rotations go through :class:`scipy.spatial.transform.Rotation`.
:class:`CameraFrameVariables` writes each 3D point in its camera's rotation frame, the change of variables
``minimize_regularized(variables=...)`` takes with known cameras (docs/REPRODUCTION.md#table-3-solver).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .._validation import check_positive
from ._reprojection import check_cameras

__all__ = [
    "nearest_orthonormal_rows",
    "complete_rotations",
    "quaternion_rotation",
    "camera_to_quaternion",
    "CameraFrameVariables",
]


def nearest_orthonormal_rows(A) -> np.ndarray:
    """Per frame, the 2x3 matrix with orthonormal rows nearest in Frobenius norm (polar factor U V^T).

    A (F, 2, 3) -> R (F, 2, 3) with R_f R_f^T = I_2."""
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


def _quadratic_forms() -> np.ndarray:
    """E (3, 3, 4, 4), symmetric in its last two axes, with H(q)_ck = q^T E_ck q for the homogeneous
    rotation H(q) = |q|^2 A(q) of q = (w, x, y, z) (so dH/dq = 2 E q), by polarisation of scipy's
    rotation: E_ii = H(e_i), E_ij = (H(e_i + e_j) - H(e_i - e_j)) / 4. The entries are 0 and +-1 (rounded)."""

    def H(q):  # scipy's quaternions are scalar last
        return np.dot(q, q) * Rotation.from_quat(np.r_[q[1:], q[0]]).as_matrix()

    e = np.eye(4)
    E = np.empty((3, 3, 4, 4))
    for i in range(4):
        for j in range(4):
            E[:, :, i, j] = H(e[i]) if i == j else (H(e[i] + e[j]) - H(e[i] - e[j])) / 4
    return np.round(E)


_H_FORMS = _quadratic_forms()
_H_FORM_ROWS = _H_FORMS.reshape(36, 4)  # rows (c, k, i): E q for every entry is one (F, 4) x (4, 36) product


def quaternion_rotation(q, jacobian: bool = False, rows: int = 3):
    """Rotation matrices A(q) of the quaternions q / |q| (q: (F, 4), (w, x, y, z), any non-zero length):
    their first ``rows`` rows (F, rows, 3) (2: the orthographic cameras) and, if ``jacobian``,
    dA/dq (F, rows, 3, 4), else None. No validation (inner loops).

    A = H(q) / |q|^2 with every entry of H a quadratic form in q, so the map is invariant to the scale
    of q and the Jacobian satisfies J q = 0 (the camera LM penalises that direction).
    """
    F = q.shape[0]
    inv = 1.0 / np.einsum("fi,fi->f", q, q)  # 1 / |q|^2
    Eq = (q @ _H_FORM_ROWS[: 12 * rows].T).reshape(F, 3 * rows, 4)  # E q, rows (c, k)
    H = Eq @ q[:, :, None]  # (F, 3 rows, 1)
    A = (H[:, :, 0] * inv[:, None]).reshape(F, rows, 3)
    if not jacobian:
        return A, None
    # d(H / n) = dH / n - H dn / n^2 with dH = 2 E q, dn = 2 q: (2 / n) (E q - H q^T / n).
    J = (2 * inv[:, None, None]) * (Eq - H * (q * inv[:, None])[:, None, :])
    return A, J.reshape(F, rows, 3, 4)


def camera_to_quaternion(R) -> np.ndarray:
    """Unit quaternions (w, x, y, z), w >= 0, of orthographic cameras R (F, 2, 3), completed to
    rotations by :func:`complete_rotations` (projected to orthonormal rows first).

    ``quaternion_rotation(q, rows=2)[0]`` reproduces ``nearest_orthonormal_rows(R)``.
    """
    q = Rotation.from_matrix(complete_rotations(R)).as_quat()[:, [3, 0, 1, 2]]  # scipy: scalar last
    q[q[:, 0] < 0] *= -1
    return q


class CameraFrameVariables:
    """Each 3D point in its frame's camera coordinates, the unheld ones scaled: a preconditioner.

    With known orthographic cameras the data term holds a point's two image coordinates with
    curvature 2 and leaves its depth (and all three coordinates of an unobserved point) to the
    regularizer, whose curvature is smaller by orders of magnitude (tau = 1e-4): L-BFGS on S then
    needs thousands of iterations per penalty stage. In the variables Y, point j of frame f is
    ``s_fj = Q_f^T D_fj y_fj`` with ``Q_f = [R_f; r_f1 x r_f2]`` (a rotation for orthonormal
    cameras) and ``D_fj = diag(1, 1, depth_scale)`` if observed, ``depth_scale I`` if not: the
    unheld directions move ``depth_scale`` times further per unit step, which brings their
    curvature towards the data term's. The map is linear and invertible, so the minimisers are
    the same; only the path of the solver changes (docs/REPRODUCTION.md#table-3-solver). The
    methods take and return arrays of shape (F, 3P), shapes as rows (x_1..x_P, y_1..y_P, z_1..z_P).

    ``R`` (F, 2, 3): orthographic cameras (rows independent); ``mask`` (F, P): True where observed;
    ``depth_scale`` > 0: the scale of the unheld directions (1: only the rotation).
    """

    def __init__(self, R, mask, depth_scale: float):
        Q = complete_rotations(R, project=False)  # (F, 3, 3)
        mask = np.asarray(mask, dtype=bool)
        if mask.ndim != 2 or mask.shape[0] != Q.shape[0]:
            raise ValueError(f"mask must have shape (F, P) with F = {Q.shape[0]}; got {mask.shape}")
        if np.any(np.abs(np.linalg.det(Q)) < 1e-12):
            raise ValueError("R has a camera with two dependent rows; the change of variables needs a basis")
        scale = np.ones((R.shape[0], 3, mask.shape[1]))
        scale[:, 2, :] = check_positive(depth_scale, "depth_scale")
        scale[~np.broadcast_to(mask[:, None, :], scale.shape)] = depth_scale
        self._Q, self._Qinv_T, self._scale = Q, np.linalg.inv(Q).transpose(0, 2, 1), scale
        self._shape = scale.shape

    def to_samples(self, Y):
        """S = A(Y): ``s_fj = Q_f^T D_fj y_fj``."""
        Y = np.asarray(Y).reshape(self._shape)
        return np.einsum("fck,fcj->fkj", self._Q, self._scale * Y).reshape(self._shape[0], -1)

    def to_variables(self, S):
        """Y = A^-1(S)."""
        S = np.asarray(S).reshape(self._shape)
        return (np.einsum("fck,fkj->fcj", self._Qinv_T, S) / self._scale).reshape(self._shape[0], -1)

    def gradient_to_variables(self, G):
        """A^T(G): the gradient in Y of a function whose gradient in S is G."""
        G = np.asarray(G).reshape(self._shape)
        return (self._scale * np.einsum("fck,fkj->fcj", self._Q, G)).reshape(self._shape[0], -1)
