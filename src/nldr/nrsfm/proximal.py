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
removes rows), i.e. 2 for cameras with orthonormal rows; the step is 1 / L. Each iteration costs one
thin SVD of the F x 3P matrix. The iteration restarts its momentum whenever the objective increases
(O'Donoghue & Candes 2015), which keeps the objective monotone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validation import as_float_matrix, check_positive
from .reprojection import OrthographicReprojection

__all__ = ["ProximalTNHResult", "tnh_proximal"]


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
    U, s, Vt = np.linalg.svd(Y, full_matrices=False)
    s = np.maximum(s - t, 0.0)
    k = int(np.count_nonzero(s))
    return (U[:, :k] * s[:k]) @ Vt[:k], float(s[:k].sum())


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
        Trace-norm weight.
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
    if isinstance(max_iter, bool) or not isinstance(max_iter, int | np.integer) or max_iter < 1:
        raise ValueError(f"max_iter must be a positive integer; got {max_iter!r}")
    if X0 is None:
        X = np.zeros(term.shape)
    else:
        X = as_float_matrix(X0, "X0").copy()
        if X.shape != term.shape:
            raise ValueError(f"X0 must have shape (F, 3P) = {term.shape}; got {X.shape}")

    lipschitz = 2.0 * max(float(np.max(np.linalg.norm(term.R, ord=2, axis=(1, 2)))) ** 2, 1e-12)
    step = 1.0 / lipschitz

    def objective(Xm, nuclear):
        return tau * nuclear + term.value(Xm)

    x_nuclear = float(np.linalg.svd(X, compute_uv=False).sum())
    f_prev = objective(X, x_nuclear)
    Y, t = X.copy(), 1.0
    converged, message, it = False, f"reached max_iter={max_iter}", 0
    for it in range(1, max_iter + 1):
        X_new, nuclear = _soft_threshold_singular_values(Y - step * term.gradient(Y), step * tau)
        f_new = objective(X_new, nuclear)
        if f_new > f_prev and t > 1.0:
            # momentum overshot: restart from the last iterate with a plain proximal step
            Y, t = X.copy(), 1.0
            continue
        t_new = (1.0 + np.sqrt(1.0 + 4.0 * t * t)) / 2.0
        Y = X_new + ((t - 1.0) / t_new) * (X_new - X)
        decrease = (f_prev - f_new) / max(abs(f_new), 1e-300)
        X, x_nuclear, t, f_prev = X_new, nuclear, t_new, f_new
        if decrease < tol:  # a negative value here is rounding at the optimum (t = 1 steps are monotone)
            converged, message = (
                True,
                f"relative objective decrease {decrease:.2g} < tol after {it} iterations",
            )
            break
    reproj = term.value(X)
    return ProximalTNHResult(
        X=X,
        objective=tau * x_nuclear + reproj,
        nuclear_norm=x_nuclear,
        reprojection_error=reproj,
        n_iter=it,
        converged=converged,
        message=message,
    )
