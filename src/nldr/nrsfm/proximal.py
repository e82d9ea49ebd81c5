"""Penalised TNH by accelerated proximal gradient: the fast shape step for camera refinement.

Problem (the paper's eq. 12 at fixed cameras), shapes X (F, 3P) as rows, cameras R (F, 2, 3),
visibility Z (F, P)::

    min_X  tau ||X||_*  +  sum_{f,j} Z_fj ||w_f(x_j) - R_f s_f(x_j)||^2

The cvxpy formulation (:class:`~nldr.nrsfm.tnh.TraceNormHeuristic`) solves it as a semidefinite
program; with estimated cameras it must be re-solved hundreds of times inside the camera/shape
alternation (Table 4), so this module solves the same convex problem with FISTA (Beck & Teboulle
2009): a gradient step on the data term followed by singular value soft-thresholding, the proximal
operator of tau ||X||_*.

Maintenance note (step size). The data term g(X) = sum_f ||Z_f o (W_f - R_f S_f)||^2 has gradient
-2 R_f^T (Z_f o (W_f - R_f S_f)) per frame. Its Lipschitz constant is 2 max_f ||R_f||_2^2 (the mask only
removes rows), i.e. 2 for cameras with orthonormal rows; the step is 1 / L. The iteration restarts its
momentum whenever the objective increases (O'Donoghue & Candes 2015), which keeps the objective
monotone. The residual M o (W - R Y) at the extrapolated point is the same extrapolation of the two
last residuals (it is affine in the shapes), so an iteration costs two batched (2x3)(3xP) products and
one singular value thresholding.

Maintenance note (thresholding). The thresholding is the cost of an iteration (one Table 4 alternation
on pickup at tau = 0.1 runs about 5 100 of them, 68 000 with the fixed shape tolerance it first had).
:func:`_soft_threshold_gram` takes the eigendecomposition of the small Gram matrix Y Y^T (F x F when
F <= 3P) instead of the SVD of Y: 135 instead of 255 microseconds at F = 36, 3P = 123 (pickup), 1.1
instead of 1.6 ms at F = 111 (drink), one thread. Eigenvalues of a Gram matrix carry an absolute
error of order eps s_max^2, i.e. a singular value near the threshold t would be off by
eps s_max^2 / t (2e-11 on pickup at tau = 0.1, as large as the objective decrease FISTA's stopping
test must resolve). So the singular values are not taken from the eigenvalues but recomputed as the
norms of the rows of U^T Y (Rayleigh-Ritz: the eigenvectors are accurate to O(eps) against the
dominant directions, which is what these norms need), accurate to eps ||Y|| like an SVD's. What stays
less accurate is the orthogonality of the right singular vectors of components near the threshold,
O(eps s_max^2 / t^2); the Gram path is used only while n eps s_max^2 <= 1e-4 t^2 and the SVD
otherwise (on pickup at tau = 0.1 the ratio is 2e-8).
:func:`_soft_threshold_singular_values` (full SVD) is kept as the reference the tests compare against.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .._validation import as_float_matrix, check_count, check_positive
from .reprojection import OrthographicReprojection, _masked_residual, _visibility_weights

__all__ = ["ProximalTNHResult", "tnh_proximal"]

_EPS = float(np.finfo(np.float64).eps)
# The Gram path needs n eps s_max^2 <= _GRAM_SAFETY t^2 (see the module's maintenance note).
_GRAM_SAFETY = 1e-4


@dataclass
class ProximalTNHResult:
    """Result of :func:`tnh_proximal`.

    Attributes
    ----------
    X : array, shape (F, 3P)
        Shapes as rows (unit of the tracks).
    objective : float
        tau ||X||_* + reprojection error at X.
    nuclear_norm, reprojection_error : float
        The two parts of the objective.
    n_iter : int
        Proximal-gradient iterations.
    converged : bool
        True when the relative objective decrease fell below ``tol``.
    message : str
    """

    X: np.ndarray
    objective: float
    nuclear_norm: float
    reprojection_error: float
    n_iter: int
    converged: bool
    message: str

    @property
    def success(self) -> bool:
        return self.converged


def _soft_threshold_singular_values(Y: np.ndarray, t: float) -> tuple[np.ndarray, float]:
    """Reference singular value soft-thresholding by a full thin SVD: (U (S - t)_+ V^T, sum (s - t)_+)."""
    U, s, Vt = np.linalg.svd(Y, full_matrices=False)
    s = np.maximum(s - t, 0.0)
    k = int(np.count_nonzero(s))
    return (U[:, :k] * s[:k]) @ Vt[:k], float(s[:k].sum())


def _soft_threshold_gram(Y: np.ndarray, t: float) -> tuple[np.ndarray, float]:
    """Singular value soft-thresholding of Y (m, n) at t > 0 through the Gram matrix of its short side.

    Returns the thresholded matrix (m, n) and its nuclear norm, sum (s_i - t)_+. With A the short-side
    orientation of Y (k x N, k <= N) and A A^T = U diag(lam) U^T, the singular values are taken as
    ||U^T A||'s row norms (accurate to eps ||Y||, see the module note) and the result is
    U_+ diag(1 - t / s_+) U_+^T A over the components with s > t. Falls back to
    :func:`_soft_threshold_singular_values` when the eigenvalue error eps s_max^2 is not negligible
    against t^2.
    """
    transpose = Y.shape[0] > Y.shape[1]
    A = Y.T if transpose else Y
    lam, U = np.linalg.eigh(A @ A.T)  # ascending
    noise = A.shape[0] * _EPS * max(float(lam[-1]), 0.0)
    if noise > _GRAM_SAFETY * t * t:
        return _soft_threshold_singular_values(Y, t)
    first = int(np.searchsorted(lam, 0.25 * t * t))  # candidates: s >= t / 2 by the (inaccurate) eigenvalues
    U = U[:, first:]
    B = U.T @ A
    s = np.sqrt(np.einsum("ij,ij->i", B, B))
    keep = s > t
    if not keep.any():
        return np.zeros_like(Y), 0.0
    s = s[keep]
    X = (U[:, keep] * (1.0 - t / s)) @ B[keep]
    return (X.T if transpose else X), float((s - t).sum())


def _lipschitz_step(R: np.ndarray) -> float:
    """1 / L with L = 2 max_f ||R_f||_2^2, from the 2x2 Gram matrices R_f R_f^T in closed form."""
    G = R @ R.transpose(0, 2, 1)
    a, b, c = G[:, 0, 0], G[:, 0, 1], G[:, 1, 1]
    top = 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + b * b)
    return 1.0 / (2.0 * max(float(top.max()), 1e-12))


@dataclass
class _FistaOutput:
    X: np.ndarray  # (F, 3, P)
    nuclear_norm: float
    reprojection_error: float
    n_iter: int
    converged: bool
    message: str
    momentum: tuple[np.ndarray, float, float]  # (previous iterate, next extrapolation weight, next t)


def _fista(
    W3: np.ndarray,
    m3: np.ndarray | None,
    R: np.ndarray,
    X: np.ndarray,
    x_nuclear: float,
    tau: float,
    max_iter: int,
    tol: float,
    svt: Callable[[np.ndarray, float], tuple[np.ndarray, float]] = _soft_threshold_gram,
    momentum: tuple[np.ndarray, float, float] | None = None,
) -> _FistaOutput:
    """FISTA with restarts on validated arrays (no checks): the loop of :func:`tnh_proximal`.

    Parameters
    ----------
    W3 : array, shape (F, 2, P)
        Tracks, zero where unobserved.
    m3 : array, shape (F, 1, P) or None
        Visibility as 0.0/1.0 (None: all observed).
    R : array, shape (F, 2, 3)
    X : array, shape (F, 3, P)
        Start (not modified).
    x_nuclear : float
        ||X||_* of the start.
    tau, max_iter, tol
        As in :func:`tnh_proximal`.
    svt : callable
        ``svt(Y (F, 3P), t) -> (X, nuclear norm)``, singular value soft-thresholding.
    momentum : (array (F, 3, P), float, float), optional
        ``(X_before, beta, t)``: continue an earlier run (the ``momentum`` of its output, whose last
        iterate is ``X``) from the extrapolated point X + beta (X - X_before) with its t, instead of
        from X with t = 1. The first step is then checked by the restart test like any other, so the
        objective still never increases. Used by the camera/shape alternation, where the cameras, hence
        the objective, change a little between runs.
    """
    F, _, P = X.shape
    Rt = R.transpose(0, 2, 1)
    step = _lipschitz_step(R)
    thresh = step * tau

    def residual(S):
        return _masked_residual(W3, m3, R, S)

    E_x = residual(X)
    f_prev = tau * x_nuclear + float(np.vdot(E_x, E_x))
    Y, E_y, t = X, E_x, 1.0
    carried = (X, 0.0, 1.0)
    if momentum is not None and momentum[1] > 0.0:
        X_before, beta, t = momentum
        Y = X + beta * (X - X_before)
        E_y = residual(Y)
        carried = momentum
    converged, message, it = False, f"reached max_iter={max_iter}", 0
    for it in range(1, max_iter + 1):
        # Y - step * grad g(Y), grad g(Y) = -2 R^T (M o (W - R Y))
        X_new, nuclear = svt((Y + (2.0 * step) * (Rt @ E_y)).reshape(F, 3 * P), thresh)
        X_new = X_new.reshape(F, 3, P)
        E_new = residual(X_new)
        f_new = tau * nuclear + float(np.vdot(E_new, E_new))
        if f_new > f_prev and t > 1.0:
            # momentum overshot: restart from the last iterate with a plain proximal step
            Y, E_y, t = X, E_x, 1.0
            carried = (X, 0.0, 1.0)
            continue
        t_new = (1.0 + np.sqrt(1.0 + 4.0 * t * t)) / 2.0
        beta = (t - 1.0) / t_new
        Y = X_new + beta * (X_new - X)
        E_y = E_new + beta * (E_new - E_x)  # the residual is affine in the shapes
        decrease = (f_prev - f_new) / max(abs(f_new), 1e-300)
        carried = (X, beta, t_new)
        X, E_x, x_nuclear, t, f_prev = X_new, E_new, nuclear, t_new, f_new
        if decrease < tol:  # a negative value here is rounding at the optimum (t = 1 steps are monotone)
            converged, message = (
                True,
                f"relative objective decrease {decrease:.2g} < tol after {it} iterations",
            )
            break
    return _FistaOutput(X, x_nuclear, float(np.vdot(E_x, E_x)), it, converged, message, carried)


def tnh_proximal(
    W2d,
    R,
    mask=None,
    *,
    tau: float,
    X0=None,
    max_iter: int = 5000,
    tol: float = 1e-10,
) -> ProximalTNHResult:
    """Minimise ``tau ||X||_* + sum Z ||w - R s||^2`` over the shapes X by FISTA with restarts.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Image tracks as rows (x coordinates of the P points, then y); unobserved entries ignored.
    R : array, shape (F, 2, 3)
        Orthographic cameras (orthonormal rows; the step size assumes ``||R_f||_2 <= 1``, and larger
        norms are accounted for).
    mask : bool array, shape (F, P), optional
        Visibility, True where observed; default all observed.
    tau : float > 0
        Trace-norm weight, in the unit of the tracks squared.
    X0 : array, shape (F, 3P), optional
        Warm start (e.g. the previous solution inside an alternation); default zeros.
    max_iter : int, default 5000
    tol : float > 0, default 1e-10
        Stop when the relative decrease of the objective in one iteration is below tol.

    Returns
    -------
    ProximalTNHResult
    """
    term = OrthographicReprojection(W2d, R, mask)  # validates the tracks, cameras and mask
    tau = check_positive(tau, "tau")
    tol = check_positive(tol, "tol")
    max_iter = check_count(max_iter, "max_iter")
    F, P = term.n_frames, term.n_points
    if X0 is None:
        X, x_nuclear = np.zeros((F, 3, P)), 0.0
    else:
        X = as_float_matrix(X0, "X0")
        if X.shape != term.shape:
            raise ValueError(f"X0 must have shape (F, 3P) = {term.shape}; got {X.shape}")
        x_nuclear = float(np.linalg.svd(X, compute_uv=False).sum())
        X = X.reshape(F, 3, P)
    m3 = _visibility_weights(term.mask)
    out = _fista(term.W.reshape(F, 2, P), m3, term.R, X, x_nuclear, tau, max_iter, tol)
    return ProximalTNHResult(
        X=out.X.reshape(F, 3 * P),
        objective=tau * out.nuclear_norm + out.reprojection_error,
        nuclear_norm=out.nuclear_norm,
        reprojection_error=out.reprojection_error,
        n_iter=out.n_iter,
        converged=out.converged,
        message=out.message,
    )
