"""Evaluation of NRSfM reconstructions: the normalised mean 3D error of the CMU mocap benchmark.

e3D = 1 / (sigma F P) sum_fj ||s_fj - s_fj^gt|| (paper Section 4.3), pinned to the benchmark's
evaluation function ``compareStructs.m`` (Akhter et al. 2009, reused by Dai, Li & He 2012):
sigma is the population standard deviation of every (frame, coordinate) row of the ground truth over
the P points, averaged over the 3F rows; both shapes are centred per frame (translation is not
observable under orthography); with estimated cameras one global orthogonal alignment (rotation or
reflection, :func:`procrustes_rotation`) comes first. The derivation and the pooled alternative of
:func:`ground_truth_sigma` are in docs/REPRODUCTION.md#table-3-sigma. Cameras are compared up to the
same global gauge: :func:`camera_error` after :func:`global_camera_alignment`.
"""

from __future__ import annotations

import numpy as np

from .._validation import as_float_matrix, check_count
from ._reprojection import check_cameras
from ._rotations import complete_rotations

__all__ = [
    "e3d",
    "e3d_per_frame",
    "ground_truth_sigma",
    "center_per_frame",
    "procrustes_rotation",
    "global_camera_alignment",
    "camera_error",
]


def _as_shapes(X, name: str, P: int) -> np.ndarray:
    X = as_float_matrix(X, name)
    if X.shape[1] != 3 * P:
        raise ValueError(f"{name} must have shape (F, 3P) = (F, {3 * P}) for P={P}; got {X.shape}")
    return X


def center_per_frame(X, P: int) -> np.ndarray:
    """Subtract, in every frame, the centroid of its P points.

    X (F, 3P), shapes as rows in any length unit, -> the same with zero mean per frame and coordinate."""
    P = check_count(P, "P (number of points)")
    X = _as_shapes(X, "X", P)
    blocks = X.reshape(X.shape[0], 3, P)
    return (blocks - blocks.mean(axis=2, keepdims=True)).reshape(X.shape)


def ground_truth_sigma(X_gt, P: int, *, pooled: bool = False) -> float:
    """The normaliser sigma of e3D: the mean standard deviation of the ground-truth coordinates.

    Parameters
    ----------
    X_gt : array, shape (F, 3P)
        Ground-truth shapes (length unit of the data).
    P : int
    pooled : bool, default False
        False (the benchmark's ``compareStructs.m``): population std of each coordinate across the P
        points of each frame, averaged over the F frames and 3 coordinates. True: one population std
        per coordinate over all F*P centred points, averaged over the 3 coordinates.

    Returns
    -------
    sigma : float
        In the length unit of ``X_gt``.
    """
    P = check_count(P, "P (number of points)")
    blocks = center_per_frame(X_gt, P).reshape(-1, 3, P)
    if pooled:
        return float(np.mean(np.sqrt(np.mean(blocks**2, axis=(0, 2)))))
    return float(np.mean(np.sqrt(np.mean(blocks**2, axis=2))))


def procrustes_rotation(X_est, X_gt, P: int, *, allow_reflection: bool = True) -> np.ndarray:
    """The 3x3 orthogonal Q minimising sum_f ||S_gt,f - Q S_est,f||_F^2 (one Q for all frames).

    Parameters
    ----------
    X_est, X_gt : arrays, shape (F, 3P)
        Shapes as rows, same unit; centre them first if translation should not matter.
    P : int
    allow_reflection : bool, default True
        NRSfM with unknown cameras recovers shapes up to a global rotation and reflection, so the
        benchmark's alignment allows det(Q) = -1; False restricts Q to rotations.

    Returns
    -------
    Q : array, shape (3, 3)
    """
    P = check_count(P, "P (number of points)")
    A = _as_shapes(X_gt, "X_gt", P).reshape(-1, 3, P)
    B = _as_shapes(X_est, "X_est", P).reshape(-1, 3, P)
    if A.shape != B.shape:
        raise ValueError(f"X_est and X_gt must have the same shape; got {B.shape} and {A.shape}")
    return _nearest_orthogonal(np.einsum("fkp,flp->kl", A, B), allow_reflection)  # M = sum_f A_f B_f^T


def _nearest_orthogonal(M, allow_reflection: bool) -> np.ndarray:
    """The orthogonal Q maximising tr(Q^T M) (3, 3): U V^T from M = U D V^T (orthogonal Procrustes),
    the last column of U flipped if a reflection is not allowed and det(U V^T) < 0."""
    U, _, Vt = np.linalg.svd(M)
    if not allow_reflection and np.linalg.det(U @ Vt) < 0:
        U[:, -1] = -U[:, -1]
    return U @ Vt


def e3d_per_frame(X_est, X_gt, P: int, *, align: bool = False) -> np.ndarray:
    """Per-frame normalised mean 3D error: (1 / (sigma P)) sum_j ||s_fj - s_fj^gt||.

    See :func:`e3d` for the definition and the parameters; returns an array of shape (F,)
    (dimensionless), whose mean is :func:`e3d`.
    """
    P = check_count(P, "P (number of points)")
    X_est = _as_shapes(X_est, "X_est", P)
    X_gt = _as_shapes(X_gt, "X_gt", P)
    if X_est.shape != X_gt.shape:
        raise ValueError(f"X_est and X_gt must have the same shape; got {X_est.shape} and {X_gt.shape}")
    sigma = ground_truth_sigma(X_gt, P)
    if sigma <= 0:
        raise ValueError("X_gt has zero spread (every frame is a single point); e3D is undefined")
    A = center_per_frame(X_gt, P).reshape(-1, 3, P)
    B = center_per_frame(X_est, P).reshape(-1, 3, P)
    if align:
        Q = procrustes_rotation(B.reshape(X_est.shape), A.reshape(X_gt.shape), P)
        B = np.einsum("kl,flp->fkp", Q, B)
    distances = np.sqrt(np.sum((A - B) ** 2, axis=1))  # (F, P)
    return distances.mean(axis=1) / sigma


def e3d(X_est, X_gt, P: int, *, align: bool = False) -> float:
    """Normalised mean 3D error e3D = (1 / (sigma F P)) sum_{f,j} ||s_fj - s_fj^gt|| (module docstring).

    Parameters
    ----------
    X_est, X_gt : arrays, shape (F, 3P)
        Estimated and true shapes as rows, in one length unit (the value is unit-free).
    P : int
        Number of points.
    align : bool, default False
        One global orthogonal Procrustes alignment of the estimate first (the protocol with estimated
        cameras; with ground-truth cameras the reconstruction is already in the world frame).

    Returns
    -------
    float
        Dimensionless (in units of sigma): the mean of :func:`e3d_per_frame`.
    """
    return float(np.mean(e3d_per_frame(X_est, X_gt, P, align=align)))


def global_camera_alignment(R_est, R_gt, *, allow_reflection: bool = True) -> np.ndarray:
    """The orthogonal Q minimising sum_f ||R_gt,f - R_est,f Q^T||_F^2 (cameras transform as R Q^T
    when shapes transform as Q S).

    R_est, R_gt (F, 2, 3) -> Q (3, 3); ``allow_reflection`` as in :func:`procrustes_rotation`."""
    R_est = check_cameras(R_est, name="R_est")
    R_gt = check_cameras(R_gt, R_est.shape[0], name="R_gt")
    # ||A - B Q^T||^2 = const - 2 tr(Q^T A^T B), M = sum_f A_f^T B_f
    return _nearest_orthogonal(np.einsum("fck,fcl->kl", R_gt, R_est), allow_reflection)


def camera_error(R_est, R_gt, *, Q=None, degrees: bool = True) -> float:
    """Mean angle between estimated and true camera rotations after one global alignment.

    The estimate is aligned by R_est,f Q^T, with Q from :func:`global_camera_alignment` unless given
    (e.g. the Q of the shapes' alignment, :func:`~nldr.nrsfm._metrics.procrustes_rotation`). Both 2x3
    cameras are projected to orthonormal rows and completed to rotations by the cross product of
    their rows; the angle of R_gt,f^T R_est,f is arccos((trace - 1) / 2).

    Parameters
    ----------
    R_est, R_gt : arrays, shape (F, 2, 3)
    Q : array, shape (3, 3), optional
        Orthogonal global alignment (det +-1).
    degrees : bool, default True
        Degrees (True) or radians.

    Returns
    -------
    float
        Mean angle over the F frames.
    """
    R_est = check_cameras(R_est, name="R_est")
    R_gt = check_cameras(R_gt, R_est.shape[0], name="R_gt")
    if Q is None:
        Q = global_camera_alignment(R_est, R_gt)
    else:
        Q = as_float_matrix(Q, "Q")
        if Q.shape != (3, 3) or not np.allclose(Q @ Q.T, np.eye(3), atol=1e-8):
            raise ValueError(f"Q must be a 3x3 orthogonal matrix; got shape {Q.shape}")
    A3, B3 = complete_rotations(R_est @ Q.T), complete_rotations(R_gt)
    cos = (np.einsum("fij,fij->f", A3, B3) - 1) / 2
    # arccos is ill-conditioned near 0: use the chordal distance ||A3 - B3||_F = 2 sqrt(2) sin(theta / 2).
    chord = np.linalg.norm(A3 - B3, axis=(1, 2))
    angle = np.where(
        cos > 0.5, 2 * np.arcsin(np.clip(chord / (2 * np.sqrt(2)), 0, 1)), np.arccos(np.clip(cos, -1, 1))
    )
    mean = float(angle.mean())
    return float(np.degrees(mean)) if degrees else mean
