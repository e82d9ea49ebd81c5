"""Camera estimation for NRSfM with unknown cameras (paper Section 4.3, Table 4).

The paper initialises the orthographic cameras "with rigid factorization" and then alternates between
the 3D shapes and the cameras, "parameterising each R_i with quaternions ... using LM". This module
provides each piece, as library functions on the layouts of :mod:`nldr.nrsfm.layout` (image tracks
W2d (F, 2P), shapes X (F, 3P), cameras R (F, 2, 3), visibility masks (F, P)):

1. :func:`rigid_factorization`: rank-3 factorisation W ~ M S of the stacked tracks (2F, P); with
   missing data by variable projection (Wiberg) on the observed entries only.
2. :func:`metric_upgrade`: the corrective matrix G with (M_f G)(M_f G)^T ~ I_2 for every frame.
3. :func:`initialize_cameras`: 1 + 2, then the nearest 2x3 matrix with orthonormal rows per frame.
4. :func:`quaternion_to_camera` (with its analytic Jacobian) and :func:`camera_to_quaternion`.
5. :func:`refine_cameras`: Levenberg-Marquardt on the per-frame quaternions with the shapes fixed,
   vectorised over frames (given the shapes, the frames are independent 4-parameter problems).
6. :func:`refine_cameras_and_shapes`: alternation of a shape step (any callable R -> X, e.g. TNH)
   with the camera LM; :func:`rigid_shape_step` is the rigid shape step (a rigid bundle adjustment).
7. :func:`align_global` and :func:`camera_error`: evaluation up to the global rotation/reflection.

The image tracks are assumed centred like the benchmark's (orthographic model w = R s without
translation, as in :class:`~nldr.nrsfm.reprojection.OrthographicReprojection`).

Gauge. With unknown cameras, (R_f Q, Q^T S_f) reproduces the tracks for any orthogonal Q, det -1
included (the reflected cameras R_f Q still have orthonormal rows, and the images are unchanged).
Estimated cameras and shapes are therefore compared with the ground truth after ONE global
orthogonal alignment per sequence; the benchmark's ``compareStructs.m`` does the same (see
:mod:`nldr.nrsfm.metrics`), and a per-frame alignment would hide camera errors.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from .._validation import as_float_matrix, check_count, check_positive
from .metrics import center_per_frame, procrustes_rotation
from .reprojection import _masked_residual, _visibility_weights, check_cameras, check_visibility_mask

__all__ = [
    "RigidFactorization",
    "CameraRefinementResult",
    "CameraShapeResult",
    "rigid_factorization",
    "metric_upgrade",
    "nearest_orthonormal_rows",
    "initialize_cameras",
    "quaternion_to_camera",
    "camera_to_quaternion",
    "reprojection_error",
    "refine_cameras",
    "rigid_shape_step",
    "refine_cameras_and_shapes",
    "align_global",
    "global_camera_alignment",
    "camera_error",
]


# --------------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------------


def _check_tracks(W2d, mask, *, min_points: int = 3):
    """Validated (W (F, 2P) with zeros where unobserved, mask (F, P)); every frame needs min_points."""
    W2d = as_float_matrix(W2d, "W2d", allow_nan=True)
    if W2d.shape[1] % 2:
        raise ValueError(f"W2d must have shape (F, 2P) (image tracks as rows); got {W2d.shape}")
    F, P = W2d.shape[0], W2d.shape[1] // 2
    mask = check_visibility_mask(mask, (F, P))
    mask2 = np.concatenate([mask, mask], axis=1)
    if not np.all(np.isfinite(W2d[mask2])):
        raise ValueError("W2d has NaN or infinite values at observed entries (where mask is True)")
    counts = mask.sum(axis=1)
    if np.any(counts < min_points):
        bad = np.flatnonzero(counts < min_points)
        raise ValueError(
            f"mask must leave at least {min_points} observed points in every frame (an orthographic camera "
            f"has 5 degrees of freedom); frames {bad[:10].tolist()} have fewer"
        )
    return np.where(mask2, W2d, 0.0), mask


def _check_shapes(X, F: int, P: int, name: str = "X") -> np.ndarray:
    X = as_float_matrix(X, name)
    if X.shape != (F, 3 * P):
        raise ValueError(f"{name} must have shape (F, 3P) = {(F, 3 * P)}; got {X.shape}")
    return X


# --------------------------------------------------------------------------------------------------
# Rigid factorisation and metric upgrade
# --------------------------------------------------------------------------------------------------


@dataclass
class RigidFactorization:
    """Affine rank-3 factorisation of image tracks, W_f ~ M_f S for every frame f.

    Attributes
    ----------
    M : array, shape (F, 2, 3)
        Affine cameras (defined up to an invertible 3x3 G: M G, G^-1 S fit equally well).
    S : array, shape (3, P)
        Affine rigid shape.
    rms : float
        Root mean square residual over the observed image coordinates (unit of the tracks).
    n_iter : int
        Residual evaluations of the variable-projection solver (0 when solved by one SVD).
    converged : bool
    message : str
    """

    M: np.ndarray
    S: np.ndarray
    rms: float
    n_iter: int
    converged: bool
    message: str


def _fit_affine_cameras(Wf3, S, mask):
    """Least-squares M_f (F, 2, 3) given S (3, P), over the observed points of each frame."""
    F = Wf3.shape[0]
    M = np.empty((F, 2, 3))
    for f in range(F):
        A = S[:, mask[f]]  # (3, n_f)
        M[f] = np.linalg.lstsq(A.T, Wf3[f][:, mask[f]].T, rcond=None)[0].T
    return M


def _varpro_residuals_jacobian(s, Wf3, mask, P, want_jacobian):
    """Residuals of W_f - M_f*(S) S (M eliminated by least squares) and Kaufman's Jacobian in vec(S).

    Maintenance note. For one image row w (observed on the set O), with A = S[:, O]^T (n x 3), the
    eliminated residual is r = (I - A A^+) w and m = A^+ w. Kaufman's approximation of its derivative,
    the one Wiberg's algorithm and most variable-projection codes use (Hong & Fitzgibbon 2015), keeps
    the projector's dominant term: dr = -(I - A A^+) dA m, i.e. d r / d S[:, O_j'] = -(I - A A^+)[:, j'] m^T.
    Both image rows of a frame share O, hence the projector.
    """
    S = s.reshape(3, P)
    res, blocks = [], []
    for f in range(Wf3.shape[0]):
        O = np.flatnonzero(mask[f])
        A = S[:, O].T  # (n, 3)
        U, sv, _ = np.linalg.svd(A, full_matrices=False)
        keep = sv > sv[0] * 1e-12 if sv[0] > 0 else np.zeros(3, dtype=bool)
        U = U[:, keep]
        Wo = Wf3[f][:, O]  # (2, n)
        Rf = Wo - (Wo @ U) @ U.T  # (2, n), rows (I - A A^+) w
        res.append(Rf.ravel())
        if want_jacobian:
            m = np.linalg.lstsq(A, Wo.T, rcond=None)[0].T  # (2, 3)
            Pperp = np.eye(O.size) - U @ U.T
            # rows (c, j), columns (k, j'): -Pperp[j, j'] m[c, k]
            block = -np.einsum("jl,ck->cjkl", Pperp, m).reshape(2 * O.size, 3, O.size)
            J = np.zeros((2 * O.size, 3, P))
            J[:, :, O] = block
            blocks.append(J.reshape(2 * O.size, 3 * P))
    r = np.concatenate(res)
    return r, (np.vstack(blocks) if want_jacobian else None)


# Nonlinear least squares of the camera initialisation (variable projection, metric polish). Not
# "lm": scipy's MINPACK (1.17, C translation) returned different bits for identical inputs on
# repeated calls in one process (three distinct answers in 100 calls of the metric polish on
# pickup, also through scipy.optimize.leastsq), which made Table 4 differ between two clean runs
# now and then. "trf" is numpy code (dense SVD per step), reaches the same optimum (rms equal to
# 1e-13 on the four Table 4 sequences with half the points missing) in as many evaluations, and
# repeats bit for bit (tests/test_cameras.py).
_LSQ_METHOD = "trf"


def rigid_factorization(W2d, mask=None, *, max_iter: int = 500, tol: float = 1e-12) -> RigidFactorization:
    """Rank-3 factorisation of the tracks, W_f ~ M_f S, in least squares over the observed entries.

    Full data: the truncated SVD of the stacked (2F, P) matrix (the global optimum, Tomasi-Kanade).
    Missing data: variable projection (Wiberg) on the observed entries: M is eliminated frame by frame
    in closed form and the 3P entries of S are optimised by a trust-region Gauss-Newton method
    (``least_squares(method="trf")``, see :data:`_LSQ_METHOD`) with Kaufman's Jacobian, from the SVD of
    the zero-filled matrix. Variable projection reaches the
    global optimum of low-rank completion from simple starts far more often than alternating least
    squares (Hong & Fitzgibbon 2015); on noise-free rigid tracks it recovers an exact factorisation.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Image tracks as rows, centred (no translation is estimated); unobserved entries are ignored.
    mask : bool array, shape (F, P), optional
        True where point j is observed in frame f. Default: all observed. Every frame needs >= 3 points.
    max_iter : int, default 500
        Missing data only: residual evaluations of the trust-region solver (``max_nfev``).
    tol : float > 0, default 1e-12
        Missing data only: ``ftol``, ``xtol`` and ``gtol`` of the trust-region solver.

    Returns
    -------
    RigidFactorization
        Affine cameras ``M`` (F, 2, 3) and shape ``S`` (3, P); see :func:`metric_upgrade`.

    Raises
    ------
    ValueError
        If ``W2d`` or ``mask`` is malformed or a frame has fewer than 3 observed points.
    """
    W, mask = _check_tracks(W2d, mask)
    max_iter = check_count(max_iter, "max_iter")
    tol = check_positive(tol, "tol")
    F, P = mask.shape
    Wf3 = W.reshape(F, 2, P)
    stacked = W.reshape(2 * F, P)
    n_obs = 2 * int(mask.sum())
    # The zero-filled matrix, rescaled by the observed fraction, is an unbiased estimate of W.
    U, sv, Vt = np.linalg.svd(stacked * (mask.size / mask.sum()), full_matrices=False)
    root = np.sqrt(sv[:3])
    S = root[:, None] * Vt[:3]
    if mask.all():
        M = (U[:, :3] * root).reshape(F, 2, 3)
        r = (Wf3 - np.einsum("fck,kp->fcp", M, S)).ravel()
        return RigidFactorization(M, S, float(np.sqrt(r @ r / n_obs)), 0, True, "truncated SVD (full data)")
    if n_obs < 3 * P:
        raise ValueError(f"mask leaves {n_obs} observed coordinates, fewer than the 3P = {3 * P} unknowns")

    def fun(s):
        return _varpro_residuals_jacobian(s, Wf3, mask, P, False)[0]

    def jac(s):
        return _varpro_residuals_jacobian(s, Wf3, mask, P, True)[1]

    sol = least_squares(
        fun, S.ravel(), jac=jac, method=_LSQ_METHOD, ftol=tol, xtol=tol, gtol=tol, max_nfev=max_iter
    )
    S = sol.x.reshape(3, P)
    M = _fit_affine_cameras(Wf3, S, mask)
    r = fun(sol.x)
    return RigidFactorization(
        M,
        S,
        float(np.sqrt(r @ r / n_obs)),
        int(sol.nfev),
        bool(sol.status > 0),
        f"variable projection: {sol.message}",
    )


def _metric_rows(a, b):
    """Coefficients of a^T Q b in the 6 unknowns (Q00, Q01, Q02, Q11, Q12, Q22) of a symmetric Q."""
    return np.stack(
        [
            a[:, 0] * b[:, 0],
            a[:, 0] * b[:, 1] + a[:, 1] * b[:, 0],
            a[:, 0] * b[:, 2] + a[:, 2] * b[:, 0],
            a[:, 1] * b[:, 1],
            a[:, 1] * b[:, 2] + a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 2],
        ],
        axis=1,
    )


def metric_upgrade(M, *, refine: bool = True) -> np.ndarray:
    """Corrective matrix G making the affine cameras M_f G orthographic (orthonormal rows).

    With m_a, m_b the rows of M_f, the orthonormality constraints m_a^T Q m_a = m_b^T Q m_b = 1 and
    m_a^T Q m_b = 0 are linear in the symmetric Q = G G^T: solved by linear least squares over all
    frames; a Q that is not positive definite (non-rigid or noisy tracks) is replaced by the nearest
    positive definite matrix (eigenvalues clipped at 1e-6 of the largest). G = V Lambda^(1/2) from
    Q = V Lambda V^T. With ``refine``, G is then polished by trust-region Gauss-Newton on the same
    residuals (:data:`_LSQ_METHOD`),
    ||M_f G G^T M_f^T - I_2||_F^2 summed over frames, which is the quantity that matters once Q had to
    be clipped, and weighs the constraints consistently.

    Parameters
    ----------
    M : array, shape (F, 2, 3)
        Affine cameras from :func:`rigid_factorization`. F >= 3: the 3F constraints must fix the 6
        unknowns of Q, and two views leave a one-parameter family.
    refine : bool, default True
        Polish G by nonlinear least squares after the linear solution.

    Returns
    -------
    G : array, shape (3, 3)
        Invertible; defined up to a right orthogonal factor (the global gauge).
    """
    M = check_cameras(M, name="M")
    if M.shape[0] < 3:
        raise ValueError(f"M must hold at least 3 cameras for a unique metric upgrade; got {M.shape[0]}")
    a, b = M[:, 0], M[:, 1]
    F = M.shape[0]
    A = np.vstack([_metric_rows(a, a), _metric_rows(b, b), _metric_rows(a, b)])
    rhs = np.concatenate([np.ones(F), np.ones(F), np.zeros(F)])
    q = np.linalg.lstsq(A, rhs, rcond=None)[0]
    Q = np.array([[q[0], q[1], q[2]], [q[1], q[3], q[4]], [q[2], q[4], q[5]]])
    lam, V = np.linalg.eigh(Q)
    if lam[-1] <= 0:
        # Degenerate (e.g. the sign of the whole factorisation flipped the quadratic form): use |Q|.
        lam = np.abs(lam)
    lam = np.maximum(lam, 1e-6 * lam.max())
    G = V * np.sqrt(lam)
    if refine:
        G = _refine_metric(M, G)
    return G


def _refine_metric(M, G0):
    weights = np.array([1.0, 1.0, np.sqrt(2.0)])  # ||.||_F^2 of the symmetric 2x2 residual

    def fun(g):
        B = M @ g.reshape(3, 3)  # (F, 2, 3)
        E = np.einsum("fck,fdk->fcd", B, B) - np.eye(2)
        return (np.stack([E[:, 0, 0], E[:, 1, 1], E[:, 0, 1]], axis=1) * weights).ravel()

    def jac(g):
        # d (m_a^T G G^T m_b) / dG = m_a (G^T m_b)^T + m_b (G^T m_a)^T
        B = M @ g.reshape(3, 3)
        a, b = M[:, 0], M[:, 1]
        Ba, Bb = B[:, 0], B[:, 1]
        d_aa = 2 * np.einsum("fk,fl->fkl", a, Ba)
        d_bb = 2 * np.einsum("fk,fl->fkl", b, Bb)
        d_ab = np.einsum("fk,fl->fkl", a, Bb) + np.einsum("fk,fl->fkl", b, Ba)
        J = np.stack([d_aa, d_bb, d_ab], axis=1) * weights[None, :, None, None]
        return J.reshape(-1, 9)

    sol = least_squares(fun, G0.ravel(), jac=jac, method=_LSQ_METHOD, xtol=1e-14, ftol=1e-14, gtol=1e-14)
    G = sol.x.reshape(3, 3)
    if not np.all(np.isfinite(G)) or np.linalg.cond(G) > 1e12:
        return G0
    return G


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


def initialize_cameras(W2d, mask=None, *, refine_metric: bool = True, max_iter: int = 500) -> np.ndarray:
    """Orthographic cameras from rigid factorisation: :func:`rigid_factorization`, :func:`metric_upgrade`,
    then :func:`nearest_orthonormal_rows` of each M_f G.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Centred image tracks as rows; unobserved entries are ignored.
    mask : bool array, shape (F, P), optional
        Visibility; default all observed. Every frame needs >= 3 observed points.
    refine_metric : bool, default True
        Polish the corrective matrix by nonlinear least squares (see :func:`metric_upgrade`).
    max_iter : int, default 500
        Passed to :func:`rigid_factorization` (missing data only).

    Returns
    -------
    R : array, shape (F, 2, 3)
        Cameras with orthonormal rows, up to one global orthogonal transform (det +-1).
    """
    n_frames = np.shape(W2d)[0] if np.ndim(W2d) == 2 else 0
    if n_frames < 3:
        raise ValueError(
            f"W2d must hold at least 3 frames (rows) to determine metric cameras; got shape {np.shape(W2d)}"
        )
    fac = rigid_factorization(W2d, mask, max_iter=max_iter)
    G = metric_upgrade(fac.M, refine=refine_metric)
    return nearest_orthonormal_rows(fac.M @ G)


# --------------------------------------------------------------------------------------------------
# Quaternions
# --------------------------------------------------------------------------------------------------

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
    R, J = _quaternion_to_camera(q, jacobian)
    if single:
        R = R[0]
        J = None if J is None else J[0]
    return (R, J) if jacobian else R


_H_FORMS_ROWS = _H_FORMS.reshape(24, 4)  # rows (c, k, i): E q is one (F, 4) x (4, 24) product


def _quaternion_to_camera(q, jacobian):
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


# --------------------------------------------------------------------------------------------------
# Camera refinement (Levenberg-Marquardt on quaternions, shapes fixed)
# --------------------------------------------------------------------------------------------------


def _frame_costs(Wf3, mask, R, Sf):
    E = Wf3 - R @ Sf
    E *= mask[:, None, :]
    return np.einsum("fcp,fcp->f", E, E), E


def reprojection_error(W2d, mask, R, X) -> float:
    """Sum over observed points of ||w_f(x_j) - R_f s_f(x_j)||^2 (unit of the tracks, squared).

    Parameters
    ----------
    W2d : array, shape (F, 2P)
    mask : bool array, shape (F, P) or None (all observed)
    R : array, shape (F, 2, 3)
    X : array, shape (F, 3P)

    Returns
    -------
    float
    """
    W, mask = _check_tracks(W2d, mask, min_points=0)
    F, P = mask.shape
    R = check_cameras(R, F)
    X = _check_shapes(X, F, P)
    return float(_frame_costs(W.reshape(F, 2, P), mask, R, X.reshape(F, 3, P))[0].sum())


@dataclass
class CameraRefinementResult:
    """Result of :func:`refine_cameras` (like ``scipy.optimize.OptimizeResult``).

    Attributes
    ----------
    R : array, shape (F, 2, 3)
        Refined cameras (orthonormal rows).
    q : array, shape (F, 4)
        Their unit quaternions (w >= 0).
    cost_history : array, shape (n_iter + 1,)
        Sum of squared reprojection errors over all frames, initially and after every LM iteration.
    frame_cost : array, shape (F,)
        Final per-frame sum of squared reprojection errors.
    n_iter : int
        LM iterations (each: one batched 4x4 solve per active frame and one cost evaluation).
    converged : bool
        True when every frame met a tolerance before ``max_iter``.
    message : str
    """

    R: np.ndarray
    q: np.ndarray
    cost_history: np.ndarray
    frame_cost: np.ndarray
    n_iter: int
    converged: bool
    message: str

    @property
    def cost(self) -> float:
        return float(self.cost_history[-1])


def _lm_normal_equations(J, C2, SE):
    """J^T J (n, 4, 4) and -J^T r (n, 4) of the per-frame camera LM from 3x3 and 3x2 summaries.

    With the residual r = mask o (W - R S) of a frame and D_i = dR/dq_i S (2 x P), the normal equations
    need J^T J = sum D_i . D_j and J^T r = -sum D_i . E over the observed entries (E the masked residual).
    With J_c (3 x 4) the camera Jacobian of image row c, C = S diag(mask) S^T (3 x 3, fixed while the
    shapes are) and S E^T (3 x 2): J^T J = sum_c J_c^T C J_c and -J^T r = sum_c J_c^T (S E^T)[:, c], which
    avoids the (2, P, 4) array D per frame. Stacking J_0 over J_1 (6 x 4), both are matrix products.

    Parameters
    ----------
    J : array, shape (n, 2, 3, 4)
        d R / d q.
    C2 : array, shape (n, 6, 6)
        Block diagonal diag(C, C).
    SE : array, shape (n, 3, 2)
        S E^T.
    """
    n = J.shape[0]
    Js = J.reshape(n, 6, 4)
    JtJ = Js.transpose(0, 2, 1) @ (C2 @ Js)
    g = (SE.transpose(0, 2, 1).reshape(n, 1, 6) @ Js)[:, 0]
    return JtJ, g


def _refine_cameras(Wf3, mask, q, Sf, max_iter, ftol, xtol):
    """Batched LM over frames; Wf3 (F, 2, P) zero where unobserved, Sf (F, 3, P). Returns q, history, ..."""
    F = q.shape[0]
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    R, J = _quaternion_to_camera(q, True)
    m3 = _visibility_weights(mask)
    C = (Sf if m3 is None else Sf * m3) @ Sf.transpose(0, 2, 1)  # S diag(mask) S^T, (F, 3, 3)
    C2 = np.zeros((F, 6, 6))
    C2[:, :3, :3] = C2[:, 3:, 3:] = C
    cost, E = _frame_costs(Wf3, mask, R, Sf)
    SE = Sf @ E.transpose(0, 2, 1)  # S E^T, (F, 3, 2)
    scale = np.einsum("fcp,fcp->f", Wf3, Wf3) + 1e-300
    lam = np.full(F, 1e-3)
    active = np.ones(F, dtype=bool)
    history = [float(cost.sum())]
    n_iter = 0
    for n_iter in range(1, max_iter + 1):  # noqa: B007 (n_iter is reported)
        idx = np.flatnonzero(active)
        rows = slice(None) if idx.size == F else idx  # views while every frame is active
        qi, cost_i, lam_i, S_i = q[rows], cost[idx], lam[idx], Sf[rows]
        JtJ, g = _lm_normal_equations(J[rows], C2[rows], SE[rows])  # g = -J^T r
        diag = JtJ.diagonal(axis1=1, axis2=2)
        # J q = 0 (scale invariance): penalising the radial component keeps the system regular and the
        # step tangent to the unit sphere. Marquardt damping lam (diag(J^T J) + 1e-12).
        A = JtJ + (qi[:, :, None] * qi[:, None, :]) * (diag.max(axis=1) + 1e-300)[:, None, None]
        A.reshape(-1, 16)[:, ::5] += lam_i[:, None] * (diag + 1e-12)
        step = np.linalg.solve(A, g[..., None])
        # decrease of the Gauss-Newton model ||r + J step||^2, relative
        predicted = (2 * g - (JtJ @ step)[..., 0]) * step[..., 0]
        predicted = predicted.sum(axis=1) / np.maximum(cost_i, 1e-300)
        step = step[..., 0]
        step_norm = np.sqrt(np.einsum("fi,fi->f", step, step))
        q_new = qi + step
        q_new /= np.sqrt(np.einsum("fi,fi->f", q_new, q_new))[:, None]
        R_new, J_new = _quaternion_to_camera(q_new, True)
        E_new = _masked_residual(Wf3[rows], None if m3 is None else m3[rows], R_new, S_i)
        cost_new = np.einsum("fcp,fcp->f", E_new, E_new)
        better = cost_new < cost_i
        decrease = (cost_i - cost_new) / np.maximum(cost_i, 1e-300)
        acc = idx[better]
        q[acc], R[acc], J[acc], cost[acc] = q_new[better], R_new[better], J_new[better], cost_new[better]
        SE[acc] = S_i[better] @ E_new[better].transpose(0, 2, 1)
        lam[idx] = np.where(better, np.maximum(lam_i / 3, 1e-12), lam_i * 4)
        # converged: an accepted step gained <= ftol, or a rejected one lost <= ftol where the model
        # promised <= ftol (the change is rounding; MINPACK's test), or the step or the cost vanished
        done = np.where(better, decrease <= ftol, (-decrease <= ftol) & (predicted <= ftol))
        done |= (step_norm <= xtol) | (cost[idx] <= 1e-30 * scale[idx]) | (lam[idx] > 1e16)
        active[idx[done]] = False
        history.append(float(cost.sum()))
        if not active.any():
            break
    if active.any():
        msg = f"LM reached max_iter={max_iter} with {int(active.sum())} of {F} frames still improving"
    else:
        msg = "every frame met ftol or xtol"
    return q, R, np.asarray(history), cost, n_iter, not active.any(), msg


def refine_cameras(
    W2d, mask, R0, X, *, max_iter: int = 100, ftol: float = 1e-12, xtol: float = 1e-12
) -> CameraRefinementResult:
    """Levenberg-Marquardt on the per-frame quaternions, shapes fixed, analytic Jacobian.

    Minimises sum_f sum_j mask_fj ||w_f(x_j) - R(q_f) s_f(x_j)||^2 over q_1..q_F. Given the shapes
    the frames decouple, so LM runs on all frames at once with a damping factor per frame (one
    batched 4x4 solve per iteration; a frame stops when its step is accepted with a relative cost
    decrease <= ftol, when a step is rejected with a relative cost increase <= ftol although the
    Gauss-Newton model predicted a relative decrease <= ftol (the cost no longer changes beyond
    rounding, MINPACK's ftol test), or when its step is <= xtol). Steps are taken in q and renormalised;
    the radial direction, along which the cost is constant, is penalised in the normal equations.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Centred image tracks as rows.
    mask : bool array, shape (F, P) or None
        Visibility (None: all observed).
    R0 : array, shape (F, 2, 3)
        Initial cameras (projected to orthonormal rows first).
    X : array, shape (F, 3P)
        Shapes as rows, held fixed.
    max_iter : int, default 100
    ftol, xtol : float > 0, default 1e-12
        Relative cost decrease and step-length (in unit quaternion) tolerances.

    Returns
    -------
    CameraRefinementResult
    """
    W, mask = _check_tracks(W2d, mask, min_points=0)
    F, P = mask.shape
    R0 = check_cameras(R0, F, name="R0")
    X = _check_shapes(X, F, P)
    max_iter = check_count(max_iter, "max_iter")
    ftol, xtol = check_positive(ftol, "ftol"), check_positive(xtol, "xtol")
    q0 = camera_to_quaternion(R0)
    q, R, history, cost, n_iter, ok, msg = _refine_cameras(
        W.reshape(F, 2, P), mask, q0, X.reshape(F, 3, P), max_iter, ftol, xtol
    )
    return CameraRefinementResult(R, q, history, cost, n_iter, ok, msg)


# --------------------------------------------------------------------------------------------------
# Alternation of shapes and cameras
# --------------------------------------------------------------------------------------------------


def rigid_shape_step(W2d, mask=None) -> Callable[[np.ndarray], np.ndarray]:
    """Shape step of a rigid model: given cameras, the one shape S (3, P) minimising the reprojection
    error, repeated for every frame.

    Per point j, s_j solves the 3x3 normal equations sum_f mask_fj R_f^T R_f s_j = sum_f mask_fj R_f^T
    w_f(x_j). Alternated with :func:`refine_cameras` by :func:`refine_cameras_and_shapes`, this is a
    rigid bundle adjustment with orthonormal cameras (a refinement of :func:`initialize_cameras`).

    Parameters
    ----------
    W2d : array, shape (F, 2P)
    mask : bool array, shape (F, P), optional

    Returns
    -------
    step : callable, R (F, 2, 3) -> X (F, 3P)
    """
    W, mask = _check_tracks(W2d, mask)
    F, P = mask.shape
    Wf3 = W.reshape(F, 2, P)

    def step(R):
        R = check_cameras(R, F)
        A = np.einsum("fp,fck,fcl->pkl", mask.astype(float), R, R)
        b = np.einsum("fck,fcp->pk", R, Wf3)
        A = A + 1e-12 * np.trace(A, axis1=1, axis2=2)[:, None, None] * np.eye(3)
        S = np.linalg.solve(A, b[..., None])[..., 0].T  # (3, P)
        return np.broadcast_to(S.ravel(), (F, 3 * P)).copy()

    return step


@dataclass
class CameraShapeResult:
    """Result of :func:`refine_cameras_and_shapes`.

    Attributes
    ----------
    R : array, shape (F, 2, 3)
        Cameras after the last camera step.
    X : array, shape (F, 3P)
        Shapes of the last shape step (the pair (R, X) has reprojection error ``history[-1]``).
    history : array, shape (n_outer,)
        Reprojection error (sum of squares over observed points) after each outer iteration's camera step.
    shape_history : array, shape (n_outer,)
        Reprojection error after each shape step (with the previous cameras).
    energy_history : array, shape (n_outer,) or None
        ``penalty(X) + history``, the joint energy after each outer iteration, when ``penalty`` was given.
    converged : bool
        True when the relative decrease of the monitored quantity (the joint energy if ``penalty`` was
        given, else the reprojection error) fell below ``tol``.
    message : str
    n_outer : int
    shape_time, camera_time : float
        Seconds spent in the shape steps and in the camera LM.
    wall_time : float
    """

    R: np.ndarray
    X: np.ndarray
    history: np.ndarray
    shape_history: np.ndarray
    energy_history: np.ndarray | None
    converged: bool
    message: str
    n_outer: int
    shape_time: float
    camera_time: float
    wall_time: float

    @property
    def success(self) -> bool:
        return self.converged


def refine_cameras_and_shapes(
    W2d,
    mask,
    R0,
    shape_step: Callable[[np.ndarray], np.ndarray],
    *,
    max_outer: int = 20,
    tol: float = 1e-4,
    camera_max_iter: int = 100,
    camera_ftol: float = 1e-12,
    penalty: Callable[[np.ndarray], float] | None = None,
    callback: Callable[[int, np.ndarray, np.ndarray], None] | None = None,
    window: int = 1,
) -> CameraShapeResult:
    """Alternate a shape step X = shape_step(R) with the camera LM (:func:`refine_cameras`).

    Outer iteration k: X_k = shape_step(R_{k-1}), then R_k = LM from R_{k-1} with X_k fixed. If the
    shape step minimises an energy ``penalty(X) + reprojection(R, X)`` (TNH with tau > 0, the kernel
    regulariser), every step decreases that joint energy. Stops when the relative decrease
    (E_{k-1} - E_k) / E_{k-1} of the monitored quantity after the camera step is below ``tol``
    (increases included), or after ``max_outer`` iterations. The monitored quantity is the joint
    energy ``penalty(X_k) + e_k`` when ``penalty`` is given, else the reprojection error e_k. Pass the
    penalty for a regularised shape step: its reprojection error alone need not decrease (on pickup
    with TNH, tau = 10, it rose by 5% in the second iteration while the joint energy fell), so the
    reprojection-only test can stop a descending alternation at once. Note that an exact-fit shape
    step (TNH with tau -> 0) reprojects any cameras exactly, so it cannot drive the cameras.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Centred image tracks as rows.
    mask : bool array, shape (F, P) or None
    R0 : array, shape (F, 2, 3)
        Initial cameras (e.g. :func:`initialize_cameras`).
    shape_step : callable
        ``shape_step(R) -> X`` with R (F, 2, 3) and X (F, 3P), e.g.
        ``lambda R: TraceNormHeuristic(W2d, R, mask).solve(tau).X``; use a closure to warm-start.
    max_outer : int, default 20
    tol : float > 0, default 1e-4
    camera_max_iter : int, default 100
    camera_ftol : float > 0, default 1e-12
        Passed to :func:`refine_cameras`.
    penalty : callable, optional
        ``penalty(X) -> float``, the regulariser the shape step minimises with the reprojection error
        (for TNH with tau: ``lambda X: tau * nuclear norm of X``). Monitored with the reprojection error.
    callback : callable, optional
        ``callback(k, R_k, X_k)`` after every outer iteration (k from 1).
    window : int, default 1
        Measure the decrease over this many outer iterations: stop when (E_{k-window} - E_k) / E_k
        < tol. Block-coordinate alternations crawl; a window of about 10 keeps a slow but steady
        descent going where a one-step test would stop it (Table 4 needs hundreds of iterations).

    Returns
    -------
    CameraShapeResult
    """
    start = time.perf_counter()
    W, mask = _check_tracks(W2d, mask)
    F, P = mask.shape
    R = nearest_orthonormal_rows(check_cameras(R0, F, name="R0"))
    if not callable(shape_step):
        raise ValueError(
            f"shape_step must be a callable R (F, 2, 3) -> X (F, 3P); got {type(shape_step).__name__}"
        )
    max_outer = check_count(max_outer, "max_outer")
    tol = check_positive(tol, "tol")
    camera_max_iter = check_count(camera_max_iter, "camera_max_iter")
    camera_ftol = check_positive(camera_ftol, "camera_ftol")
    window = check_count(window, "window")
    Wf3 = W.reshape(F, 2, P)
    q = camera_to_quaternion(R)
    history, shape_history, energy = [], [], []
    if penalty is not None and not callable(penalty):
        raise ValueError(
            f"penalty must be a callable X (F, 3P) -> float or None; got {type(penalty).__name__}"
        )
    shape_time = camera_time = 0.0
    converged, message = False, f"reached max_outer={max_outer} outer iterations"
    X = None
    for k in range(1, max_outer + 1):
        t0 = time.perf_counter()
        X = _check_shapes(shape_step(R.copy()), F, P, name="shape_step(R)")
        t1 = time.perf_counter()
        Sf = X.reshape(F, 3, P)
        shape_history.append(float(_frame_costs(Wf3, mask, R, Sf)[0].sum()))
        q, R, _, frame_cost, _, _, _ = _refine_cameras(Wf3, mask, q, Sf, camera_max_iter, camera_ftol, 1e-12)
        camera_time += time.perf_counter() - t1
        shape_time += t1 - t0
        history.append(float(frame_cost.sum()))
        monitored = history
        if penalty is not None:
            energy.append(float(penalty(X)) + history[-1])
            monitored = energy
        if callback is not None:
            callback(k, R.copy(), X.copy())
        if k > window:
            previous = monitored[-1 - window]
            decrease = (previous - monitored[-1]) / previous if previous > 0 else 0.0
            if decrease < tol:
                converged = True
                what = "joint energy" if penalty is not None else "reprojection error"
                message = (
                    f"relative decrease of the {what} over {window} iteration(s) {decrease:.3g} < tol "
                    f"after {k} iterations"
                )
                break
    return CameraShapeResult(
        R=R,
        X=X,
        history=np.asarray(history),
        shape_history=np.asarray(shape_history),
        energy_history=np.asarray(energy) if penalty is not None else None,
        converged=converged,
        message=message,
        n_outer=len(history),
        shape_time=shape_time,
        camera_time=camera_time,
        wall_time=time.perf_counter() - start,
    )


# --------------------------------------------------------------------------------------------------
# Evaluation up to the global gauge
# --------------------------------------------------------------------------------------------------


def align_global(X_est, X_gt, P: int, *, allow_reflection: bool = True) -> np.ndarray:
    """Centre every frame, then apply ONE orthogonal Q (over all frames) aligning X_est to X_gt.

    Q minimises sum_f ||S_gt,f - Q S_est,f||_F^2 (orthogonal Procrustes on the per-frame centred
    shapes; :func:`~nldr.nrsfm.metrics.procrustes_rotation`). ``e3d(align_global(X, G, P), G, P)``
    equals ``e3d(X, G, P, align=True)``.

    Parameters
    ----------
    X_est, X_gt : arrays, shape (F, 3P)
        Shapes as rows, same unit.
    P : int
        Number of points.
    allow_reflection : bool, default True
        With unknown cameras the reconstruction is defined up to a rotation and a reflection.

    Returns
    -------
    X_aligned : array, shape (F, 3P)
        The centred estimate rotated (reflected) into the ground truth's frame.
    """
    B = center_per_frame(X_est, P)
    A = center_per_frame(X_gt, P)
    if A.shape != B.shape:
        raise ValueError(f"X_est and X_gt must have the same shape; got {B.shape} and {A.shape}")
    Q = procrustes_rotation(B, A, P, allow_reflection=allow_reflection)
    F = B.shape[0]
    return np.einsum("kl,flp->fkp", Q, B.reshape(F, 3, P)).reshape(B.shape)


def global_camera_alignment(R_est, R_gt, *, allow_reflection: bool = True) -> np.ndarray:
    """The orthogonal Q minimising sum_f ||R_gt,f - R_est,f Q^T||_F^2 (cameras transform as R Q^T
    when shapes transform as Q S).

    Parameters
    ----------
    R_est, R_gt : arrays, shape (F, 2, 3)
    allow_reflection : bool, default True

    Returns
    -------
    Q : array, shape (3, 3)
    """
    R_est = check_cameras(R_est, name="R_est")
    R_gt = check_cameras(R_gt, R_est.shape[0], name="R_gt")
    # ||A - B Q^T||^2 = const - 2 tr(Q^T A^T B): maximised by Q = U V^T from sum_f A_f^T B_f = U D V^T.
    U, _, Vt = np.linalg.svd(np.einsum("fck,fcl->kl", R_gt, R_est))
    if not allow_reflection and np.linalg.det(U @ Vt) < 0:
        U[:, -1] = -U[:, -1]
    return U @ Vt


def camera_error(R_est, R_gt, *, Q=None, degrees: bool = True) -> float:
    """Mean angle between estimated and true camera rotations after one global alignment.

    The estimate is aligned by R_est,f Q^T, with Q from :func:`global_camera_alignment` unless given
    (e.g. the Q of the shapes' alignment, :func:`~nldr.nrsfm.metrics.procrustes_rotation`). Both 2x3
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
    A = nearest_orthonormal_rows(R_est @ Q.T)
    B = nearest_orthonormal_rows(R_gt)
    A3 = np.concatenate([A, np.cross(A[:, 0], A[:, 1])[:, None]], axis=1)
    B3 = np.concatenate([B, np.cross(B[:, 0], B[:, 1])[:, None]], axis=1)
    cos = (np.einsum("fij,fij->f", A3, B3) - 1) / 2
    # arccos is ill-conditioned near 0: use the chordal distance ||A3 - B3||_F = 2 sqrt(2) sin(theta / 2).
    chord = np.linalg.norm(A3 - B3, axis=(1, 2))
    angle = np.where(
        cos > 0.5, 2 * np.arcsin(np.clip(chord / (2 * np.sqrt(2)), 0, 1)), np.arccos(np.clip(cos, -1, 1))
    )
    mean = float(angle.mean())
    return float(np.degrees(mean)) if degrees else mean
