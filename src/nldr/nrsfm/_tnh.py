"""The trace-norm heuristic's shared pieces: its result type, singular value thresholding, and the
penalised TNH by accelerated proximal gradient (FISTA).

TNH (the paper's eq. 12, known cameras; layouts as in :mod:`nldr.nrsfm._layout`), penalised (tau > 0) or
in its exact-fit limit (tau -> 0)::

    min_X  tau ||X||_*  +  sum_{f,j} Z_fj ||w_f(x_j) - R_f s_f(x_j)||^2
    min_X  ||X||_*   subject to   R_f s_f(x_j) = w_f(x_j)  for every observed (f, j)

The entry point is :func:`~nldr.nrsfm._reconstruct.trace_norm_heuristic` (backends :mod:`nldr.nrsfm._admm` and
:mod:`nldr.nrsfm._cvxpy_tnh`); :func:`fista_tnh` is the shape step of Table 4's camera/shape alternation
(:mod:`nldr.nrsfm._camera_refinement`).

Singular value thresholding ``prox_{t ||.||_*}(Y) = U (S - t)_+ V^T`` comes by a thin SVD
(:func:`soft_threshold_singular_values`) or, the default of every solver here, through the
eigendecomposition of the Gram matrix of Y's short side (:func:`soft_threshold_singular_values_gram`).
A Gram eigenvalue carries an absolute error of order eps s_max^2, so the singular values are recomputed
as the row norms of U^T Y (accurate to eps ||Y||); the right singular vectors of components near the
threshold lose orthogonality as O(eps s_max^2 / t^2), so the Gram path is taken only while
n eps s_max^2 <= :data:`GRAM_SAFETY` t^2 (docs/PERFORMANCE.md#scale).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .._spectral import shrink_singular_values
from ..result import SolverResult, status_from
from ._reprojection import OrthographicReprojection, masked_residual

__all__ = [
    "GRAM_SAFETY",
    "TNHResult",
    "TNHSolveError",
    "fit_summary",
    "soft_threshold_singular_values",
    "soft_threshold_singular_values_gram",
    "fista_tnh",
]

_EPS = float(np.finfo(np.float64).eps)
#: The Gram path needs n eps s_max^2 <= GRAM_SAFETY t^2 (see the module's maintenance note).
GRAM_SAFETY = 1e-4


class TNHSolveError(RuntimeError):
    """The conic solver failed or did not return an optimal solution; the message has the status."""


@dataclass(kw_only=True, repr=False)
class TNHResult(SolverResult):
    """Result of a TNH solve (:func:`~nldr.nrsfm._reconstruct.trace_norm_heuristic`, :func:`fista_tnh`), a
    :class:`~nldr.result.SolverResult`.

    Attributes
    ----------
    x : array, shape (F, 3P)
        Shapes as rows, in the unit of the image tracks.
    fun : float
        ||X||_* for the exact fit, else tau ||X||_* + reprojection error (cvxpy: the solver's optimum).
    status, message, nit, wall_time
        CONVERGED (cvxpy: ``optimal``), MAX_ITER (ADMM, FISTA) or INACCURATE (cvxpy's
        ``optimal_inaccurate``); cvxpy's ``nit`` is the conic solver's (0 if unreported) and its
        ``wall_time`` includes compiling on a first solve.
    method, solver : str
        ``"admm"``, ``"admm_l1"`` (robust TNH), ``"cvxpy"`` or ``"fista"``; ``"ADMM"``, ``"FISTA"`` or the
        conic solver (``"SCS"``, ``"CLARABEL"``, ...).
    tau : float
        Regularisation strength; 0.0 for the exact fit (``exact_fit`` True: equality constraints).
    nuclear_norm, reprojection_error, max_abs_residual : float
        ||X||_* (FISTA: from its last thresholding), the sum of squared reprojection errors over the
        observed points (unit squared) and the largest absolute residual (unit of the tracks).
    options : dict
        The solver's options, defaults filled in (ADMM adds ``final_beta``, its adapted penalty).
    dual, duality_gap : array or None, float or None
        ADMM only: the exact fit's multiplier Y (F, 3P) of the splitting X = Z, or the robust TNH's
        dual-feasible multiplier of the residuals (F, 2P) (:mod:`nldr.nrsfm._admm`); ``fun`` minus a
        certified lower bound on the optimum (unit of the tracks).
    solver_time : float or None
        cvxpy only: seconds inside the conic solver.
    momentum : (array (F, 3, P), float, float) or None
        :func:`fista_tnh` only: ``(X_before, beta, t)``, the state to continue from.
    """

    method: str
    solver: str
    tau: float
    exact_fit: bool
    nuclear_norm: float
    reprojection_error: float
    max_abs_residual: float
    options: dict = field(default_factory=dict)
    dual: np.ndarray | None = None
    duality_gap: float | None = None
    solver_time: float | None = None
    momentum: tuple | None = None


def fit_summary(term: OrthographicReprojection, X: np.ndarray) -> dict[str, float]:
    """``nuclear_norm`` (by an SVD), ``reprojection_error`` and ``max_abs_residual`` of shapes X
    (F, 3P) under the reprojection term: the fit fields of a :class:`TNHResult`."""
    r = term.residuals(X)
    return {
        "nuclear_norm": float(np.linalg.svd(X, compute_uv=False).sum()),
        "reprojection_error": float(r @ r),
        "max_abs_residual": float(np.max(np.abs(r))) if r.size else 0.0,
    }


def soft_threshold_singular_values(Y: np.ndarray, t: float) -> tuple[np.ndarray, float]:
    """Singular value soft-thresholding of Y (m, n) at t >= 0 by a thin SVD: ``U (S - t)_+ V^T``
    (m, n) and its nuclear norm ``sum (s_i - t)_+``."""
    X, kept = shrink_singular_values(Y, t)
    return X, float(kept.sum())


def soft_threshold_singular_values_gram(Y: np.ndarray, t: float) -> tuple[np.ndarray, float]:
    """Singular value soft-thresholding of Y (m, n) at t > 0 through the Gram matrix of its short side.

    Returns the thresholded matrix (m, n) and its nuclear norm, like
    :func:`soft_threshold_singular_values`. With A the short-side orientation of Y (k x N, k <= N) and
    A A^T = U diag(lam) U^T, the singular values are ||U^T A||'s row norms (see the module note) and the
    result is U_+ diag(1 - t / s_+) U_+^T A over the components with s > t. Falls back to the SVD when
    the eigenvalue error eps s_max^2 is not negligible against t^2.
    """
    transpose = Y.shape[0] > Y.shape[1]
    A = Y.T if transpose else Y
    lam, U = np.linalg.eigh(A @ A.T)  # ascending
    noise = A.shape[0] * _EPS * max(float(lam[-1]), 0.0)
    if noise > GRAM_SAFETY * t * t:
        return soft_threshold_singular_values(Y, t)
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


def fista_tnh(
    W3, m3, R, X, x_nuclear: float, tau: float, max_iter: int, tol: float,
    svt: Callable = soft_threshold_singular_values_gram, momentum: tuple | None = None,
) -> TNHResult:  # fmt: skip
    """FISTA with restarts for penalised TNH on validated batched arrays (no checks), warm-startable.

    Minimises ``tau ||X||_* + sum_f ||m_f o (W_f - R_f X_f)||^2`` from ``X`` with the step 1 / L,
    L = 2 max_f ||R_f||_2^2 (the data term's Lipschitz constant); the momentum restarts whenever the
    objective increases (O'Donoghue & Candes 2015), so the objective never increases. Stops when the
    relative decrease of the objective in one iteration is below ``tol``, or after ``max_iter``.

    Parameters
    ----------
    W3 : array (F, 2, P)
        Tracks, zero where unobserved.
    m3 : array (F, 1, P) or None
        :func:`~nldr.nrsfm._reprojection.visibility_weights` of the mask (None: all observed).
    R : array (F, 2, 3)
    X : array (F, 3, P)
        Start (not modified), with ``x_nuclear`` its ||X||_*.
    x_nuclear, tau, max_iter, tol : float, float > 0, int >= 1, float > 0
        tau in the unit of the tracks squared.
    svt : callable, default :func:`soft_threshold_singular_values_gram`
        ``svt(Y (F, 3P), t) -> (X, nuclear norm)``.
    momentum : (array (F, 3, P), float, float), optional
        The ``momentum`` ``(X_before, beta, t)`` of an earlier run whose last iterate is ``X``: start
        from the extrapolated X + beta (X - X_before) with its t (the camera/shape alternation, whose
        objective changes a little between runs); the first step passes the restart test like any other.

    Returns
    -------
    TNHResult
        ``x`` the last iterate (F, 3P), ``method="fista"``, ``momentum`` the state to continue from.
    """
    start = time.perf_counter()
    F, _, P = X.shape
    Rt = R.transpose(0, 2, 1)
    step = _lipschitz_step(R)
    thresh = step * tau

    def residual(S):
        return masked_residual(W3, m3, R, S)

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
            converged, message = True, f"relative decrease {decrease:.2g} < tol after {it} iterations"
            break
    reprojection_error = float(np.vdot(E_x, E_x))
    return TNHResult(
        x=X.reshape(F, 3 * P), fun=tau * x_nuclear + reprojection_error, status=status_from(converged),
        message=message, nit=it, wall_time=time.perf_counter() - start, method="fista", solver="FISTA",
        tau=tau, exact_fit=False, nuclear_norm=x_nuclear, reprojection_error=reprojection_error,
        max_abs_residual=float(np.max(np.abs(E_x))) if E_x.size else 0.0,
        options={"max_iter": max_iter, "tol": tol}, momentum=carried,
    )  # fmt: skip
