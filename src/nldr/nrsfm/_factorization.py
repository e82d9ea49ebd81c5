"""Camera initialisation for NRSfM with unknown cameras: rigid factorisation and metric upgrade.

The paper initialises the orthographic cameras "with rigid factorization" (Section 4.3, Table 4):

1. :func:`rigid_factorization`: rank-3 factorisation W ~ M S of the stacked tracks (2F, P); with
   missing data by variable projection (Wiberg) on the observed entries only.
2. :func:`metric_upgrade`: the corrective matrix G with (M_f G)(M_f G)^T ~ I_2 for every frame.
3. :func:`initialize_cameras`: 1 + 2, then the nearest 2x3 matrix with orthonormal rows per frame
   (:func:`~nldr.nrsfm._rotations.nearest_orthonormal_rows`).

Layouts as in :mod:`nldr.nrsfm._layout`: image tracks W2d (F, 2P), cameras (F, 2, 3), visibility masks
(F, P). The image tracks are assumed centred like the benchmark's (orthographic model w = R s without
translation, as in :class:`~nldr.nrsfm._reprojection.OrthographicReprojection`). The cameras are
determined up to one global orthogonal transform (see :mod:`nldr.nrsfm._camera_refinement` on the gauge).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from .._validation import check_count, check_positive
from ..result import CONVERGED, SolverResult, status_from
from ._reprojection import check_cameras, check_tracks
from ._rotations import nearest_orthonormal_rows

__all__ = ["RigidFactorization", "rigid_factorization", "metric_upgrade", "initialize_cameras"]


@dataclass(kw_only=True, repr=False)
class RigidFactorization(SolverResult):
    """Affine rank-3 factorisation of image tracks, W_f ~ M_f S for every frame f (a
    :class:`~nldr.result.SolverResult`).

    Attributes
    ----------
    x : array, shape (3, P)
        The affine rigid shape S, the variable of variable projection (M is eliminated in closed form).
    fun : float
        Sum of squared residuals over the observed image coordinates (unit of the tracks, squared).
    status, message, wall_time
        As in :class:`~nldr.result.SolverResult`; ``status`` is CONVERGED when the trust-region solver
        met ``ftol``, ``xtol`` or ``gtol`` (always, for full data), MAX_ITER when it ran out of
        evaluations.
    nit : int
        Residual evaluations of the variable-projection solver (0 when solved by one SVD).
    M : array, shape (F, 2, 3)
        Affine cameras (defined up to an invertible 3x3 G: M G, G^-1 S fit equally well).
    rms : float
        Root mean square residual over the observed image coordinates (unit of the tracks).
    """

    M: np.ndarray
    rms: float


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


# Nonlinear least squares of the camera initialisation (variable projection, metric polish): "trf",
# which repeats bit for bit, not MINPACK's "lm", which did not (docs/PERFORMANCE.md, determinism).
_LSQ_METHOD = "trf"


def rigid_factorization(W2d, mask=None, *, max_iter: int = 500, tol: float = 1e-12) -> RigidFactorization:
    """Rank-3 factorisation of the tracks, W_f ~ M_f S, in least squares over the observed entries.

    Full data: the truncated SVD of the stacked (2F, P) matrix (the global optimum, Tomasi-Kanade).
    Missing data: variable projection (Wiberg) on the observed entries: M is eliminated frame by frame
    in closed form and the 3P entries of S are optimised by a trust-region Gauss-Newton method
    (``least_squares(method="trf")``) with Kaufman's Jacobian, from the SVD of the zero-filled matrix.
    It reaches the global optimum of low-rank completion from simple starts far more often than
    alternating least squares (Hong & Fitzgibbon 2015); on noise-free rigid tracks it is exact.

    Parameters
    ----------
    W2d, mask : arrays (F, 2P) and (F, P), optional
        Centred tracks (no translation is estimated) and visibility (:mod:`nldr.nrsfm._layout`; default
        all observed); every frame needs >= 3 points.
    max_iter : int, default 500
        Missing data only: residual evaluations of the trust-region solver (``max_nfev``).
    tol : float > 0, default 1e-12
        Missing data only: ``ftol``, ``xtol`` and ``gtol`` of the trust-region solver.

    Returns
    -------
    RigidFactorization
        Affine cameras ``M`` (F, 2, 3) and shape ``x`` (3, P); see :func:`metric_upgrade`.

    """
    start = time.perf_counter()
    W, mask = check_tracks(W2d, mask)
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
    if mask.all():  # the truncated SVD is the global optimum
        M = (U[:, :3] * root).reshape(F, 2, 3)
        r = (Wf3 - np.einsum("fck,kp->fcp", M, S)).ravel()
        status, message, nit = CONVERGED, "truncated SVD (full data)", 0
    else:
        if n_obs < 3 * P:
            raise ValueError(
                f"mask leaves {n_obs} observed coordinates, fewer than the 3P = {3 * P} unknowns"
            )

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
        status, nit = status_from(sol.status > 0), int(sol.nfev)
        message = f"variable projection: {sol.message}"
    return RigidFactorization(
        x=S, fun=float(r @ r), status=status, message=message, nit=nit, wall_time=time.perf_counter() - start,
        M=M, rms=float(np.sqrt(r @ r / n_obs)),
    )  # fmt: skip


def _metric_rows(a, b):
    """Coefficients of a^T Q b in the 6 unknowns (Q00, Q01, Q02, Q11, Q12, Q22) of a symmetric Q."""
    pairs = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
    columns = [a[:, i] * b[:, i] if i == j else a[:, i] * b[:, j] + a[:, j] * b[:, i] for i, j in pairs]
    return np.stack(columns, axis=1)


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


def initialize_cameras(W2d, mask=None, *, refine_metric: bool = True, max_iter: int = 500) -> np.ndarray:
    """Orthographic cameras from rigid factorisation: :func:`rigid_factorization`, :func:`metric_upgrade`,
    then :func:`nearest_orthonormal_rows` of each M_f G.

    Parameters
    ----------
    W2d, mask, max_iter
        As in :func:`rigid_factorization`.
    refine_metric : bool, default True
        Polish the corrective matrix by nonlinear least squares (see :func:`metric_upgrade`).

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
