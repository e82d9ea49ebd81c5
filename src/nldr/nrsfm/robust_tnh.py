"""Robust trace-norm heuristic: TNH with an l1 reprojection term, for tracks with gross errors.

Problem (known cameras; shapes as rows X (F, 3P), tracks W (F, 2P), cameras R (F, 2, 3), visibility
(F, P))::

    min_X  tau ||X||_*  +  sum_{observed (f, j), c = x, y} |w_fcj - (R_f s_f(x_j))_c|

The exact-fit TNH of :mod:`nldr.nrsfm.admm` reproduces every observed coordinate, gross errors
included. Here a coordinate may be left unexplained at a cost proportional to its error, so a few
displaced points are rejected instead of bending every shape towards them. Both terms are lengths,
so tau is dimensionless: the same tau serves tracks in any unit. For tau below a threshold (``tau
max |lambda_i| <= 1`` for the exact fit's constraint multipliers lambda) the exact fit is a solution;
as tau grows, more coordinates are left to the residual, and at large tau X = 0.

Why l1 and not Huber
--------------------
Tracks of synthetic or well-tracked motion are nearly noise-free apart from the gross errors, so
the residuals of the inliers should be zero: l1 keeps them exactly zero (sparse residuals) where a
Huber term would trade a small residual on every point against the nuclear norm. l1 also needs no
threshold delta, which would have to come from a scale of residuals that do not exist before a
robust fit (the exact fit's residuals are zero), and it keeps tau free of units (a Huber term is a
squared length inside delta, so its tau would carry the unit of the tracks). Its tau -> 0 limit is
the exact-fit TNH, and for small delta a Huber term over 2 delta is l1 to within delta / 2 per
residual. The l1 is per image coordinate, as :class:`nldr.data_terms.Huber` is, so the Huber kernel
method started here sees the same residuals in its linear zone.

Algorithm
---------
ADMM on the splitting ``min tau ||Z||_* + ||e||_1  s.t.  X = Z,  A X + e = b`` (A X the observed
projections, b the observed tracks), with X one block and (Z, e) the other, scaled multipliers U
and V, penalty beta and relaxation alpha (both constraints are relaxed)::

    X <- argmin ||X - Z + U||^2 + ||A X + e - b + V||^2       per (frame, point): a 3x3 solve
    H <- alpha X + (1 - alpha) Z,   G <- alpha A X + (1 - alpha)(b - e)
    Z <- SVT_{tau / beta}(H + U)                               singular value thresholding
    e <- soft_{1 / beta}(b - G - V)                            soft-thresholding of the residuals
    U <- U + H - Z,   V <- V + G + e - b

The X-step is closed form: an observed point solves ``(I + R_f^T R_f) s = (Z - U)_fj + R_f^T (b - e -
V)_fj`` (one 3x3 inverse per frame, precomputed), an unobserved point takes ``(Z - U)_fj``. The problem
is solved in normalised units (tracks divided by their RMS over the observed entries; the objective
is positively homogeneous of degree 1 in the tracks) with beta adapted by residual balancing, as in
:mod:`nldr.nrsfm.admm`.

Optimality certificate and stopping rule
----------------------------------------
The dual of the problem is ``max <mu, b>  s.t.  |mu_i| <= 1,  ||A^T mu||_2 <= tau`` (spectral norm).
The e-step makes ``mu = -beta V`` satisfy |mu_i| <= 1 at every iteration; scaled by
``min(1, tau / ||A^T mu||_2)`` it is dual feasible, and its value bounds the optimum from below. The
primal objective is finite at any X (the problem is unconstrained), so the solver returns the
low-rank iterate Z and stops when the gap ``P(Z) - <mu', b>`` is at most ``tol P(Z)``: then P(Z)
exceeds the optimum by at most a relative ``tol``. The gap is evaluated every 10 iterations.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np

from .._validation import as_float_matrix, check_positive
from ..result import CONVERGED, MAX_ITER
from .admm import ADAPT_MAX_CHANGES, balancing_factor, check_admm_options, options_record, track_scale
from .reprojection import OrthographicReprojection
from .svt import soft_threshold_singular_values_gram
from .tnh_result import TNHResult, fit_summary

__all__ = ["RobustTNHResult", "robust_trace_norm_heuristic", "robust_tnh_objective"]

_CHECK_EVERY = 10  # iterations between gap evaluations and residual-balancing checks


@dataclass(kw_only=True, repr=False)
class RobustTNHResult(TNHResult):
    """Result of :func:`robust_trace_norm_heuristic`, a :class:`~nldr.nrsfm.TNHResult` (and so a
    :class:`~nldr.result.SolverResult`).

    ``x`` (F, 3P) the shapes in the unit of the tracks; ``fun`` the objective tau ||X||_* + the l1
    reprojection error at ``x`` (unit of the tracks); ``method="admm_l1"``, ``solver="ADMM"``,
    ``exact_fit=False``; ``nuclear_norm``, ``reprojection_error`` (sum of squares) and
    ``max_abs_residual`` as for TNH; ``dual`` the dual-feasible multiplier mu' of the residuals,
    shape (F, 2P) with zeros at unobserved entries (dimensionless, |mu'| <= 1);
    ``duality_gap`` ``fun`` minus the certified lower bound (unit of the tracks).

    Attributes
    ----------
    l1_error : float
        Sum of absolute reprojection residuals over the observed coordinates (unit of the tracks).
    lower_bound : float
        Certified lower bound on the optimal objective (unit of the tracks).
    """

    l1_error: float
    lower_bound: float


def robust_tnh_objective(term: OrthographicReprojection, X, tau: float) -> float:
    """tau ||X||_* + sum of absolute reprojection residuals of X (F, 3P) under ``term`` (unit of the
    tracks): the objective :func:`robust_trace_norm_heuristic` minimises."""
    X = np.asarray(X, dtype=np.float64)
    if X.shape != term.shape:
        raise ValueError(f"X must have shape (F, 3P) = {term.shape}; got {X.shape}")
    tau = check_positive(tau, "tau")
    return tau * float(np.linalg.svd(X, compute_uv=False).sum()) + float(np.abs(term.residuals(X)).sum())


def robust_trace_norm_heuristic(
    W2d,
    R,
    mask=None,
    *,
    tau: float,
    tol: float = 1e-6,
    max_iter: int = 20_000,
    beta: float | None = None,
    relaxation: float = 1.6,
    X0=None,
    adaptive: bool = True,
    verbose: bool = False,
) -> RobustTNHResult:
    """Robust TNH with known cameras: ``min tau ||X||_* + l1 reprojection error`` by ADMM.

    See the module docstring for the problem, the choice of l1, the algorithm and its certificate.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Image tracks as rows (row f = x of the P points, then y), length unit of the data; entries of
        unobserved points are ignored (they may be NaN).
    R : array, shape (F, 2, 3)
        Known orthographic cameras.
    mask : bool array, shape (F, P), optional
        True where point j is observed in frame f (both coordinates). Default: all observed.
    tau : float > 0
        Weight of ||X||_* against the l1 reprojection error (dimensionless).
    tol : float in (0, 1), default 1e-6
        Relative duality gap at which to stop: at ``status == CONVERGED``, ``fun`` exceeds the optimum
        by at most ``tol * fun``.
    max_iter : int, default 20000
        Iteration cap; reaching it gives ``status == MAX_ITER`` and a RuntimeWarning.
    beta : float > 0, optional
        Initial ADMM penalty in normalised units (tracks divided by their RMS); default 1.0.
    relaxation : float in (0, 2), default 1.6
        Relaxation parameter alpha (1 = plain ADMM).
    X0 : array, shape (F, 3P), optional
        Start for Z (unit of the tracks), e.g. the exact-fit TNH; default the least-norm exact fit.
    adaptive : bool, default True
        Adapt beta by residual balancing (at most 50 changes).
    verbose : bool, default False
        Print the gap every 100 iterations and at the end.

    Returns
    -------
    RobustTNHResult

    Raises
    ------
    ValueError
        For malformed tracks, cameras or mask, tau <= 0, tol outside (0, 1), max_iter not a positive
        integer, beta <= 0, relaxation outside (0, 2), or X0 of the wrong shape or not finite.

    Warns
    -----
    RuntimeWarning
        When ``max_iter`` is reached before the gap test is met (status MAX_ITER).
    """
    start = time.perf_counter()
    term = OrthographicReprojection(W2d, R, mask)  # validates tracks, cameras and mask
    tau = check_positive(tau, "tau")
    tol, max_iter, beta0, alpha = check_admm_options(tol, max_iter, beta, relaxation)
    problem = _L1Problem(term, tau)
    if X0 is None:
        Z = problem.least_norm_fit()
    else:
        Z = as_float_matrix(X0, "X0")
        if Z.shape != term.shape:
            raise ValueError(f"X0 must have shape (F, 3P) = {term.shape}; got {Z.shape}")
        Z = Z.reshape(problem.shape3) / problem.scale
    run = problem.iterate(Z, beta0, alpha, tol, max_iter, adaptive, verbose)

    X = run["Z"].reshape(term.shape) * problem.scale
    fit = fit_summary(term, X)
    l1 = float(np.abs(term.residuals(X)).sum())
    fun = tau * fit["nuclear_norm"] + l1
    lower = run["lower"] * problem.scale
    converged = run["status"] == CONVERGED
    if converged:
        message = f"optimal: relative duality gap within tol={tol:g} after {run['nit']} iterations"
    else:
        message = (
            f"tolerance {tol:g} not met after max_iter={run['nit']} iterations (relative duality gap "
            f"{(fun - lower) / max(fun, 1e-300):.2e})"
        )
        warnings.warn(f"robust TNH: {message}. Raise max_iter or loosen tol", RuntimeWarning, stacklevel=2)
    if verbose:
        print(f"robust TNH: {message}; objective {fun:.6g}, lower bound {lower:.6g}")
    dual = run["mu"].reshape(term.n_frames, 2 * term.n_points)  # zero at unobserved entries
    return RobustTNHResult(
        x=X,
        fun=fun,
        status=run["status"],
        message=message,
        nit=run["nit"],
        wall_time=time.perf_counter() - start,
        method="admm_l1",
        solver="ADMM",
        tau=tau,
        exact_fit=False,
        **fit,
        options=options_record(tol, max_iter, beta0, alpha, adaptive, run["beta"]),
        dual=dual,
        duality_gap=float(fun - lower),
        l1_error=l1,
        lower_bound=float(lower),
    )


class _L1Problem:
    """The robust TNH problem in normalised units, with the pieces of the ADMM iteration.

    Blocks: shapes (F, 3, P), residuals and tracks (F, 2, P) with zeros at unobserved points.
    """

    def __init__(self, term: OrthographicReprojection, tau: float):
        F, P = term.n_frames, term.n_points
        self.shape3 = (F, 3, P)
        self.tau = tau
        self.R = term.R
        self.observed = term.mask[:, None, :]  # (F, 1, P)
        self.scale = track_scale(term)
        self.b = term.W.reshape(F, 2, P) / self.scale  # zero where unobserved
        self.Rt = term.R.transpose(0, 2, 1)  # (F, 3, 2)
        self.inverse = np.linalg.inv(np.eye(3) + self.Rt @ term.R)  # (F, 3, 3), (I + R^T R)^-1
        self.b_norm = float(np.linalg.norm(self.b))

    def project(self, S: np.ndarray) -> np.ndarray:
        """A S: projections of the shapes (F, 3, P), zero at unobserved points, shape (F, 2, P)."""
        return np.where(self.observed, self.R @ S, 0.0)

    def back(self, E: np.ndarray) -> np.ndarray:
        """A^T E: residual-shaped (F, 2, P) (zero where unobserved) to shapes (F, 3, P)."""
        return self.Rt @ E

    def least_norm_fit(self) -> np.ndarray:
        """R_f^+ w per observed point (zero elsewhere): the default start."""
        pinv = np.linalg.pinv(self.R)  # (F, 3, 2)
        return np.where(self.observed, pinv @ self.b, 0.0)

    def objective(self, Z: np.ndarray, nuclear: float) -> float:
        return self.tau * nuclear + float(np.abs(self.b - self.project(Z)).sum())

    def dual_bound(self, mu: np.ndarray) -> tuple[float, np.ndarray]:
        """(<mu', b>, mu') with mu' = mu min(1, tau / ||A^T mu||_2), dual feasible when |mu| <= 1."""
        F = mu.shape[0]
        spectral = float(np.linalg.norm(self.back(mu).reshape(F, -1), 2))
        if spectral > self.tau:
            mu = mu * (self.tau / spectral)
        return float(np.vdot(mu, self.b)), mu

    def iterate(self, Z, beta, alpha, tol, max_iter, adaptive, verbose) -> dict:
        F = Z.shape[0]
        b, obs = self.b, self.observed
        e = np.zeros_like(b)
        U = np.zeros_like(Z)
        V = np.zeros_like(b)
        status, changes, nit = MAX_ITER, 0, 0
        lower, mu = -np.inf, np.zeros_like(b)
        for it in range(1, max_iter + 1):
            nit = it
            rhs = (Z - U) + self.back(np.where(obs, b - e - V, 0.0))
            X = np.where(obs, self.inverse @ rhs, Z - U)
            AX = self.project(X)
            H = alpha * X + (1.0 - alpha) * Z
            G = alpha * AX + (1.0 - alpha) * (b - e)
            check = it % _CHECK_EVERY == 0 or it == max_iter
            if check:
                Z_old, e_old = Z, e
            Zm, nuclear = soft_threshold_singular_values_gram((H + U).reshape(F, -1), self.tau / beta)
            Z = Zm.reshape(self.shape3)
            T = np.where(obs, b - G - V, 0.0)
            e = np.sign(T) * np.maximum(np.abs(T) - 1.0 / beta, 0.0)
            U = U + H - Z
            V = V + np.where(obs, G + e - b, 0.0)
            if not check:
                continue
            primal = self.objective(Z, nuclear)
            value, mu = self.dual_bound(-beta * V)
            lower = max(lower, value)  # every evaluated bound is valid: keep the best
            gap = primal - lower
            if verbose and it % 100 == 0:
                print(f"robust TNH {it:6d}  objective {primal:.8g}  gap {gap:.3e}  beta {beta:.3g}")
            if gap <= tol * primal:
                status = CONVERGED
                break
            if adaptive and changes < ADAPT_MAX_CHANGES:
                r = np.sqrt(np.sum((X - Z) ** 2) + np.sum((AX + e - b) ** 2 * obs))
                r_rel = r / max(np.linalg.norm(X), np.linalg.norm(Z), self.b_norm, 1e-300)
                s = beta * np.linalg.norm(self.back(e - e_old) - (Z - Z_old))
                s_rel = s / max(beta * np.linalg.norm(U), beta * np.linalg.norm(self.back(V)), 1e-300)
                factor = balancing_factor(r_rel, s_rel)
                if factor is not None:
                    beta *= factor
                    U /= factor
                    V /= factor
                    changes += 1
        return {"Z": Z, "status": status, "nit": nit, "beta": beta, "lower": lower, "mu": mu}
