"""Rotations of orthographic cameras: unit quaternions and the nearest matrix with orthonormal rows.

An orthographic camera R_f (2, 3) is the first two rows of a rotation. The camera LM
(:mod:`nldr.nrsfm.camera_refinement`) parameterises each camera by a quaternion q = (w, x, y, z),
scalar first, as the paper does ("parameterising each R_i with quaternions"); any non-zero q is valid
(the rotation is that of q / |q|).
"""

from __future__ import annotations

import numpy as np

from .reprojection import check_cameras

__all__ = [
    "nearest_orthonormal_rows",
    "quaternion_to_camera",
    "quaternion_to_camera_batch",
    "camera_to_quaternion",
]


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


# Rows 0 and 1 of H(q), the homogeneous rotation matrix of q = (w, x, y, z) (R = H / |q|^2), and their
# derivatives: each entry is a quadratic form q^T E q, dH/dq = 2 E q. Built from
#   H = [[w2+x2-y2-z2, 2(xy-wz), 2(xz+wy)], [2(xy+wz), w2-x2+y2-z2, 2(yz-wx)], ...].
_H_FORMS = np.zeros((2, 3, 4, 4))
for (_c, _k), _terms in {
    (0, 0): [(0, 0, 1), (1, 1, 1), (2, 2, -1), (3, 3, -1)],
    (0, 1): [(1, 2, 1), (2, 1, 1), (0, 3, -1), (3, 0, -1)],
    (0, 2): [(1, 3, 1), (3, 1, 1), (0, 2, 1), (2, 0, 1)],
    (1, 0): [(1, 2, 1), (2, 1, 1), (0, 3, 1), (3, 0, 1)],
    (1, 1): [(0, 0, 1), (1, 1, -1), (2, 2, 1), (3, 3, -1)],
    (1, 2): [(2, 3, 1), (3, 2, 1), (0, 1, -1), (1, 0, -1)],
}.items():
    for _i, _j, _v in _terms:
        _H_FORMS[_c, _k, _i, _j] = _v


def _check_quaternions(q) -> tuple[np.ndarray, bool]:
    q = np.asarray(q, dtype=np.float64) if not isinstance(q, np.ndarray) else q.astype(np.float64)
    single = q.ndim == 1
    q2 = q[None] if single else q
    if q2.ndim != 2 or q2.shape[1] != 4 or q2.shape[0] == 0:
        raise ValueError(f"q must have shape (4,) or (F, 4) (scalar first: w, x, y, z); got {q.shape}")
    if not np.all(np.isfinite(q2)):
        raise ValueError("q contains NaN or infinite values")
    if np.any(np.einsum("fi,fi->f", q2, q2) < 1e-300):
        raise ValueError("q must be non-zero (a rotation is defined by q / |q|)")
    return q2, single


def quaternion_to_camera(q, *, jacobian: bool = False):
    """Orthographic camera (first two rows of the rotation matrix) of quaternions q = (w, x, y, z).

    The rotation is that of q / |q| (R = H(q) / |q|^2 with H quadratic), so any non-zero q is valid and
    the map is invariant to the scale of q: the Jacobian satisfies J q = 0. Levenberg-Marquardt on q
    (:func:`refine_cameras`) handles this gauge direction and renormalises q after each step.

    Parameters
    ----------
    q : array, shape (4,) or (F, 4)
        Quaternions, scalar first; need not be unit.
    jacobian : bool, default False
        Also return d R / d q.

    Returns
    -------
    R : array, shape (2, 3) or (F, 2, 3)
        Orthonormal rows.
    J : array, shape (2, 3, 4) or (F, 2, 3, 4)
        Only with ``jacobian=True``: J[..., c, k, i] = d R[c, k] / d q_i.
    """
    q, single = _check_quaternions(q)
    R, J = quaternion_to_camera_batch(q, jacobian)
    if single:
        R = R[0]
        J = None if J is None else J[0]
    return (R, J) if jacobian else R


_H_FORMS_ROWS = _H_FORMS.reshape(24, 4)  # rows (c, k, i): E q is one (F, 4) x (4, 24) product


def quaternion_to_camera_batch(q: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """:func:`quaternion_to_camera` of validated quaternions (F, 4), without checks: (R (F, 2, 3), J
    (F, 2, 3, 4) or None). The camera LM's inner loop calls it."""
    F = q.shape[0]
    inv = 1.0 / np.einsum("fi,fi->f", q, q)  # 1 / |q|^2
    Eq = (q @ _H_FORMS_ROWS.T).reshape(F, 6, 4)  # E q, rows (c, k)
    H = Eq @ q[:, :, None]  # (F, 6, 1)
    R = (H[:, :, 0] * inv[:, None]).reshape(F, 2, 3)
    if not jacobian:
        return R, None
    # d(H / n) = dH / n - H dn / n^2 with dH = 2 E q, dn = 2 q: (2 / n) (E q - H q^T / n).
    J = (2 * inv[:, None, None]) * (Eq - H * (q * inv[:, None])[:, None, :])
    return R, J.reshape(F, 2, 3, 4)


def camera_to_quaternion(R) -> np.ndarray:
    """Unit quaternions (w, x, y, z), w >= 0, of orthographic cameras (completed to rotations).

    Each 2x3 camera is first replaced by the nearest matrix with orthonormal rows, then completed by
    the cross product of its rows into a rotation (det +1); the quaternion follows by Shepperd's method
    (the numerically safest of the four closed forms is picked per frame).

    Parameters
    ----------
    R : array, shape (2, 3) or (F, 2, 3)

    Returns
    -------
    q : array, shape (4,) or (F, 4)
        ``quaternion_to_camera(q)`` reproduces ``nearest_orthonormal_rows(R)``.
    """
    R = np.asarray(R, dtype=np.float64)
    if R.shape[-2:] != (2, 3) or R.ndim not in (2, 3):
        raise ValueError(f"R must have shape (2, 3) or (F, 2, 3); got {R.shape}")
    single = R.ndim == 2
    R = nearest_orthonormal_rows(R[None] if single else R)
    rot = np.concatenate([R, np.cross(R[:, 0], R[:, 1])[:, None]], axis=1)  # (F, 3, 3)
    r = rot
    tr = r[:, 0, 0] + r[:, 1, 1] + r[:, 2, 2]
    cand = np.stack([tr, r[:, 0, 0], r[:, 1, 1], r[:, 2, 2]], axis=1)
    case = np.argmax(cand, axis=1)
    q = np.empty((R.shape[0], 4))
    d21, d02, d10 = r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]
    s01, s02, s12 = r[:, 0, 1] + r[:, 1, 0], r[:, 0, 2] + r[:, 2, 0], r[:, 1, 2] + r[:, 2, 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        t0 = np.sqrt(np.maximum(1 + tr, 0)) * 2
        t1 = np.sqrt(np.maximum(1 + r[:, 0, 0] - r[:, 1, 1] - r[:, 2, 2], 0)) * 2
        t2 = np.sqrt(np.maximum(1 - r[:, 0, 0] + r[:, 1, 1] - r[:, 2, 2], 0)) * 2
        t3 = np.sqrt(np.maximum(1 - r[:, 0, 0] - r[:, 1, 1] + r[:, 2, 2], 0)) * 2
        options = [
            np.stack([t0 / 4, d21 / t0, d02 / t0, d10 / t0], axis=1),
            np.stack([d21 / t1, t1 / 4, s01 / t1, s02 / t1], axis=1),
            np.stack([d02 / t2, s01 / t2, t2 / 4, s12 / t2], axis=1),
            np.stack([d10 / t3, s02 / t3, s12 / t3, t3 / 4], axis=1),
        ]
    for i, opt in enumerate(options):
        q[case == i] = opt[case == i]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q[q[:, 0] < 0] *= -1
    return q[0] if single else q
