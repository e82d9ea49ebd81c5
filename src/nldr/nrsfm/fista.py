"""Penalised TNH by accelerated proximal gradient (FISTA): a backend of
:func:`~nldr.nrsfm.tnh.trace_norm_heuristic` and the shape step of the camera alternation.

Problem (the paper's eq. 12 at fixed cameras), shapes X (F, 3P) as rows, cameras R (F, 2, 3),
visibility Z (F, P)::

    min_X  tau ||X||_*  +  sum_{f,j} Z_fj ||w_f(x_j) - R_f s_f(x_j)||^2

cvxpy solves it as a semidefinite program (:mod:`nldr.nrsfm.cvxpy_tnh`); with estimated cameras it must
be re-solved in every outer iteration of the camera/shape alternation (Table 4), so this module solves
the same convex problem with FISTA (Beck & Teboulle 2009): a gradient step on the data term followed by
singular value soft-thresholding, the proximal operator of tau ||X||_* (:mod:`nldr.nrsfm.svt`).

- :func:`solve_fista`: the backend of ``trace_norm_heuristic(..., method="fista")``.
- :func:`fista_tnh`: the loop itself on validated batched arrays, warm-startable with the previous
  run's momentum; :func:`~nldr.nrsfm.unknown_cameras.tnh_with_camera_refinement` calls it once per
  outer iteration.

Maintenance note (step size). The data term g(X) = sum_f ||Z_f o (W_f - R_f S_f)||^2 has gradient
-2 R_f^T (Z_f o (W_f - R_f S_f)) per frame. Its Lipschitz constant is 2 max_f ||R_f||_2^2 (the mask only
removes rows), i.e. 2 for cameras with orthonormal rows; the step is 1 / L. The iteration restarts its
momentum whenever the objective increases (O'Donoghue & Candes 2015), which keeps the objective
monotone. The residual M o (W - R Y) at the extrapolated point is the same extrapolation of the two
last residuals (it is affine in the shapes), so an iteration costs two batched (2x3)(3xP) products and
one singular value thresholding, the dominant cost.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .._validation import as_float_matrix, check_count, check_positive
from ..result import SolverResult, status_from
from .reprojection import OrthographicReprojection, masked_residual, visibility_weights
from .svt import soft_threshold_singular_values_gram
from .tnh_result import TNHResult

__all__ = ["FistaResult", "fista_tnh", "solve_fista"]


def _lipschitz_step(R: np.ndarray) -> float:
    """1 / L with L = 2 max_f ||R_f||_2^2, from the 2x2 Gram matrices R_f R_f^T in closed form."""
    G = R @ R.transpose(0, 2, 1)
    a, b, c = G[:, 0, 0], G[:, 0, 1], G[:, 1, 1]
    top = 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + b * b)
    return 1.0 / (2.0 * max(float(top.max()), 1e-12))


@dataclass(kw_only=True, repr=False)
class FistaResult(SolverResult):
    """Result of :func:`fista_tnh` (a :class:`~nldr.result.SolverResult`).

    Attributes
    ----------
    x : array, shape (F, 3, P)
        The last iterate, in the batched layout of the input (``x.reshape(F, 3 * P)``: shapes as rows).
    fun : float
        tau ||x||_* + reprojection error.
    status, message, nit, wall_time
        As in :class:`~nldr.result.SolverResult`; CONVERGED when the relative objective decrease of an
        iteration fell below ``tol``, MAX_ITER otherwise.
    nuclear_norm, reprojection_error : float
        The two parts of the objective.
    momentum : (array (F, 3, P), float, float)
        ``(X_before, beta, t)``: the state to continue from (pass it back as ``momentum`` with
        ``X=x``).
    """

    nuclear_norm: float
    reprojection_error: float
    momentum: tuple[np.ndarray, float, float]


def fista_tnh(
    W3: np.ndarray,
    m3: np.ndarray | None,
    R: np.ndarray,
    X: np.ndarray,
    x_nuclear: float,
    tau: float,
    max_iter: int,
    tol: float,
    svt: Callable[[np.ndarray, float], tuple[np.ndarray, float]] = soft_threshold_singular_values_gram,
    momentum: tuple[np.ndarray, float, float] | None = None,
) -> FistaResult:
    """FISTA with restarts for penalised TNH on validated batched arrays (no checks), warm-startable.

    Minimises ``tau ||X||_* + sum_f ||m_f o (W_f - R_f X_f)||^2`` from ``X``; stops when the relative
    decrease of the objective in one iteration is below ``tol``, or after ``max_iter`` iterations.

    Parameters
    ----------
    W3 : array, shape (F, 2, P)
        Tracks, zero where unobserved.
    m3 : array, shape (F, 1, P) or None
        :func:`~nldr.nrsfm.reprojection.visibility_weights` of the mask (None: all observed).
    R : array, shape (F, 2, 3)
        Cameras.
    X : array, shape (F, 3, P)
        Start (not modified).
    x_nuclear : float
        ||X||_* of the start.
    tau : float > 0
        Trace-norm weight, in the unit of the tracks squared.
    max_iter : int >= 1
    tol : float > 0
        Relative objective decrease that stops the loop.
    svt : callable, default :func:`~nldr.nrsfm.svt.soft_threshold_singular_values_gram`
        ``svt(Y (F, 3P), t) -> (X, nuclear norm)``, singular value soft-thresholding.
    momentum : (array (F, 3, P), float, float), optional
        ``(X_before, beta, t)``: continue an earlier run (the ``momentum`` of its result, whose last
        iterate is ``X``) from the extrapolated point X + beta (X - X_before) with its t, instead of
        from X with t = 1. The first step is then checked by the restart test like any other, so the
        objective still never increases. Used by the camera/shape alternation, where the cameras, hence
        the objective, change a little between runs.

    Returns
    -------
    FistaResult
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
            converged, message = (
                True,
                f"relative objective decrease {decrease:.2g} < tol after {it} iterations",
            )
            break
    reprojection_error = float(np.vdot(E_x, E_x))
    return FistaResult(
        x=X,
        fun=tau * x_nuclear + reprojection_error,
        status=status_from(converged),
        message=message,
        nit=it,
        wall_time=time.perf_counter() - start,
        nuclear_norm=x_nuclear,
        reprojection_error=reprojection_error,
        momentum=carried,
    )


def solve_fista(
    term: OrthographicReprojection, *, tau: float, X0=None, max_iter: int = 5000, tol: float = 1e-10
) -> TNHResult:
    """Penalised TNH ``min tau ||X||_* + sum Z ||w - R s||^2`` over the shapes X by FISTA with restarts.

    The backend of ``trace_norm_heuristic(W2d, R, mask, tau=tau, method="fista", X0=..., max_iter=...,
    tol=...)``, which validates the tracks, cameras and mask into ``term``.

    Parameters
    ----------
    term : OrthographicReprojection
        Tracks, cameras (orthonormal rows; the step size assumes ``||R_f||_2 <= 1``, and larger norms
        are accounted for) and visibility.
    tau : float > 0
        Trace-norm weight, in the unit of the tracks squared.
    X0 : array, shape (F, 3P), optional
        Warm start (e.g. the previous solution inside an alternation); default zeros.
    max_iter : int, default 5000
    tol : float > 0, default 1e-10
        Stop when the relative decrease of the objective in one iteration is below tol.

    Returns
    -------
    TNHResult
        ``method="fista"``, ``solver="FISTA"``; ``fun = tau * nuclear_norm + reprojection_error``;
        ``nuclear_norm`` from the last thresholding.
    """
    start = time.perf_counter()
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
    m3 = visibility_weights(term.mask)
    out = fista_tnh(term.W.reshape(F, 2, P), m3, term.R, X, x_nuclear, tau, max_iter, tol)
    X = out.x.reshape(F, 3 * P)
    r = term.residuals(X)
    return TNHResult(
        x=X,
        fun=tau * out.nuclear_norm + out.reprojection_error,
        status=out.status,
        message=out.message,
        nit=out.nit,
        wall_time=time.perf_counter() - start,
        method="fista",
        solver="FISTA",
        tau=tau,
        exact_fit=False,
        nuclear_norm=out.nuclear_norm,
        reprojection_error=out.reprojection_error,
        max_abs_residual=float(np.max(np.abs(r))) if r.size else 0.0,
        options={"max_iter": max_iter, "tol": tol},
    )
