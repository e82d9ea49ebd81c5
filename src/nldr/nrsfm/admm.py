"""Exact-fit trace-norm heuristic (TNH) by ADMM: the default backend of
:func:`~nldr.nrsfm.tnh.trace_norm_heuristic` (``method="admm"``), for sequences of any length.

Problem (the paper's eq. 12 in its tau -> 0 limit, known cameras; see :mod:`nldr.nrsfm.tnh`)::

    min_X ||X||_*   subject to   R_f s_f(x_j) = w_f(x_j)   for every observed (f, j)

with shapes as rows X (F, 3P), image tracks W (F, 2P), cameras R (F, 2, 3) and a visibility mask
(F, P). Write C for the affine set of shape matrices that reproject exactly onto the observed tracks.

Why this module exists
----------------------
cvxpy hands ||X||_* to a conic solver as a semidefinite cone of order F + 3P. SCS is slow on drink
sampled every 10th frame (F = 111) and cannot handle the full sequence (F = 1102): the cone and its
eigendecompositions grow with F. Two facts make a dedicated solver cheap: the constraints act
on each (frame, point) block s_f(x_j) in R^3 separately, so projecting onto C is a 3x3 operation per
block, and the proximal operator of the nuclear norm is singular value thresholding of an F x 3P
matrix whose thin SVD costs O(F (3P)^2) -- linear in F.

Algorithm
---------
ADMM on the splitting ``min  i_C(X) + ||Z||_*  s.t.  X = Z`` (i_C the indicator of C), in scaled
form with the multiplier Y = beta U of X = Z, relaxation parameter alpha (over-relaxation for
alpha > 1; Eckstein & Bertsekas 1992) and penalty beta > 0::

    X <- P_C(Z - U)                        projection onto the constraints
    H <- alpha X + (1 - alpha) Z           relaxed iterate
    Z <- SVT_{1/beta}(H + U)               prox of ||.||_* / beta: soft-threshold singular values
    U <- U + H - Z

P_C decouples per (frame, point): an observed block moves to the nearest exact reprojection,
s <- s - R_f^+ (R_f s - w_f(x_j)) = N_f s + R_f^+ w_f(x_j) with the pseudo-inverse R_f^+ and the
projector N_f = I - R_f^+ R_f onto the null space of R_f (the viewing direction); an unobserved block
is unconstrained and left alone. N_f and R_f^+ w are precomputed, so an X-update is one einsum. A
rank-deficient camera is handled through its pseudo-inverse (singular values below 1e-10 of the
largest are treated as zero); if some observed point is then not reachable (no exact fit exists)
the problem is infeasible and a ValueError says which frame.

The problem is solved in normalised units (tracks divided by their RMS over the observed entries),
in which beta = 1 is a sensible start; beta is then adapted by residual balancing (He, Yang & Wang
2000; Boyd et al. 2011, sec. 3.4.1): every 10 iterations, if the relative primal residual exceeds
twice the relative dual residual beta doubles, in the opposite case it halves (U is rescaled so that
Y is unchanged; residuals defined below). The threshold 2 instead of the customary 10 needs fewer
iterations on the slowest full-length sequences (yoga, pickup; benchmarks/bench_tnh_admm.py).
Adaptation stops after 50 changes, after which the fixed-penalty convergence theory applies.

Optimality certificate and stopping rule
----------------------------------------
X is optimal iff it is feasible and some Y satisfies both Y in d||X||_* (the subdifferential) and
Y in range(A^T), the row space of the constraint operator A (i.e. Y vanishes on unobserved blocks and
is orthogonal to the viewing direction of every observed block). The iterates deliver these up to
two residuals: X is feasible by construction, Y = beta U is a subgradient of ||.||_* at Z (the prox
step guarantees it; :func:`~nldr.nrsfm.svt.soft_threshold_singular_values_gram`, whose right singular
vectors near the threshold are orthogonal only to O(eps s_max^2 / t^2), at most GRAM_SAFETY = 1e-4, as
it falls back to the full SVD beyond; on Table 3's eight problems it gave the full SVD's iterations,
nuclear norms to 10 digits and X to 6e-12 relative, 1.4-1.6x less CPU), so what remains is

- primal residual ``r = ||X - Z||_F``  (how far the feasible X is from the point Y certifies),
- dual residual   ``s = ||P_null(Y)||_F``, the distance of Y from range(A^T) (P_null applies N_f to
  observed blocks and keeps unobserved blocks).

The solver stops when ``r <= tol max(||X||_F, ||Z||_F)``, ``s <= tol ||Y||_F`` (||Y||_F >= 1 for any
subgradient at a non-zero Z) **and** the relative duality gap is at most tol. The gap is rigorous:
Y_r = P_range(Y) lies in range(A^T), so Y_r / max(1, ||Y_r||_2) = A^T lambda is feasible for the dual
``max <b, lambda> s.t. ||A^T lambda||_2 <= 1`` and its value <b, lambda> = <X, A^T lambda> (X is
feasible) bounds the optimum from below, while ||X||_* bounds it from above. Hence at termination

    ||X||_* - OPT  <=  gap  <=  tol ||X||_*,

i.e. the nuclear norm of the returned X is within a relative tol / (1 - tol) of the optimum. The gap
needs two extra SVDs (singular values only) and is evaluated only when the residual tests pass.

Default tol = 1e-6 (benchmarks/bench_tnh_admm.py, results/benchmarks/tnh_admm.csv). On the paper's
four sequences sampled every 10th frame (full data and 50% missing) e3D agrees with SCS at eps 1e-6
(the cvxpy backend's default) to 2e-6, except drink with full data (7e-5). Caveat, measured: on some problems
the optimum is so flat that the nuclear norm hardly pins X down. On drink every 10th frame, full data,
two long ADMM runs ended at nuclear norms equal to 3e-10 (relative) with X 0.2% apart and e3D 0.0225
against 0.0233; runs stopped at tol 1e-6 with different penalty settings gave e3D 0.0221 ... 0.0234
(SCS: 0.0221). On full-length pickup (full data) and drink (50% missing) the residual-balancing
threshold alone moved e3D by 5e-4 at tol 1e-6, while tol 1e-7 reproduced the better run. So the e3D
of exact-fit TNH is determined to a few 1e-4 at tol 1e-6; pass tol=1e-7 (more iterations) when that
matters.

The returned X is the X-iterate, feasible to rounding whatever the number of iterations.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from .._validation import as_float_matrix, check_count, check_positive
from ..result import CONVERGED, MAX_ITER
from .reprojection import OrthographicReprojection
from .svt import soft_threshold_singular_values_gram
from .tnh_result import TNHResult, fit_summary

__all__ = [
    "solve_admm",
    "check_admm_options",
    "balancing_factor",
    "track_scale",
    "options_record",
    "ADAPT_MAX_CHANGES",
]

_RCOND = 1e-10  # relative cut-off of camera singular values in the pseudo-inverse
_ADAPT_EVERY = 10  # iterations between residual-balancing checks
_ADAPT_MU = 2.0  # balance when one relative residual exceeds mu times the other
_ADAPT_FACTOR = 2.0
ADAPT_MAX_CHANGES = 50
_FEASIBILITY_RTOL = 1e-9  # exact-fit residual tolerance (relative to the track scale) of a singular camera


def solve_admm(
    term: OrthographicReprojection,
    *,
    tol: float = 1e-6,
    max_iter: int = 50_000,
    beta: float | None = None,
    X0=None,
    Y0=None,
    relaxation: float = 1.6,
    adaptive: bool = True,
    verbose: bool = False,
) -> TNHResult:
    """Exact-fit TNH ``min ||X||_* s.t. exact reprojection of the observed points`` by ADMM.

    The backend of ``trace_norm_heuristic(W2d, R, mask, method="admm", **options)``, which validates
    the tracks (unobserved entries may be NaN), cameras (rows need not be orthonormal; a rank-deficient
    camera is handled by its pseudo-inverse) and mask into ``term``. See the module docstring for the
    algorithm, the optimality certificate and the stopping rule.

    Parameters
    ----------
    term : OrthographicReprojection
        Tracks, cameras and visibility.
    tol : float in (0, 1), default 1e-6
        Relative tolerance of the primal residual, the dual residual and the duality gap; at
        ``status == CONVERGED`` the returned ||X||_* exceeds the optimum by at most a relative
        ``tol / (1 - tol)``.
    max_iter : int, default 50000
        Iteration cap; reaching it gives ``status == MAX_ITER`` and a RuntimeWarning.
    beta : float > 0, optional
        Initial ADMM penalty in normalised units (tracks divided by their RMS); default 1.0.
    X0 : array, shape (F, 3P), optional
        Warm start for Z (e.g. a previous solution, unit of the tracks); default the least-norm
        exact fit (unobserved blocks zero).
    Y0 : array, shape (F, 3P), optional
        Warm start for the multiplier Y (dimensionless; e.g. ``result.dual`` of a previous solve);
        default zeros. A warm start from a previous solution needs both X0 and Y0 (and ideally
        ``beta=result.options["final_beta"]``): with X0 alone the multiplier is rebuilt from
        scratch and hardly any iterations are saved.
    relaxation : float in (0, 2), default 1.6
        Relaxation parameter alpha (1 = plain ADMM).
    adaptive : bool, default True
        Adapt beta by residual balancing (at most 50 changes).
    verbose : bool, default False
        Print the residuals every 100 iterations and at the end.

    Returns
    -------
    TNHResult
        ``x`` (F, 3P) in the unit of the tracks, feasible to rounding; ``method="admm"``,
        ``solver="ADMM"``, ``tau=0.0``, ``exact_fit=True``, ``fun = nuclear_norm`` (||X||_*, unit of
        the tracks), ``reprojection_error`` (unit squared), ``max_abs_residual`` (unit), ``dual`` (the
        multiplier Y (F, 3P), dimensionless, ||Y||_2 <= 1), ``duality_gap`` (||X||_* minus a certified
        lower bound on the optimum, unit of the tracks) and ``options`` (the options used, plus
        ``final_beta``, the adapted penalty).

    Raises
    ------
    ValueError
        For tol outside (0, 1), max_iter not a positive integer, beta <= 0, relaxation outside (0, 2),
        X0 or Y0 of the wrong shape or not finite, and when no exact fit exists (an observed point
        outside the range of a rank-deficient camera).

    Warns
    -----
    RuntimeWarning
        When ``max_iter`` is reached before the tolerance is met (status MAX_ITER).
    """
    start = time.perf_counter()
    tol, max_iter, beta0, alpha = check_admm_options(tol, max_iter, beta, relaxation)
    feasible = _ExactFitSet(term)
    Z, U = _initial_iterates(term, feasible.scale, feasible.offset, X0, Y0, beta0)
    run = _iterate(feasible, Z, U, beta0, alpha, tol, max_iter, adaptive, verbose)

    scale = feasible.scale
    X = run.X * scale
    Y = run.beta * run.U
    fit = fit_summary(term, X)
    nuclear = fit["nuclear_norm"]
    wall = time.perf_counter() - start
    converged = run.status == CONVERGED
    if verbose:
        print(
            f"ADMM {'optimal' if converged else 'stopped'} after {run.n_iter} iterations: primal "
            f"{run.r_rel:.2e} dual {run.s_rel:.2e} gap {run.gap * scale:.3g} ||X||_* {nuclear:.6g} "
            f"({wall:.2f} s)"
        )
    if converged:
        message = (
            f"optimal: primal and dual residuals and duality gap within tol={tol:g} after {run.n_iter} "
            f"iterations"
        )
    else:
        message = (
            f"tolerance {tol:g} not met after max_iter={run.n_iter} iterations (relative primal residual "
            f"{run.r_rel:.2e}, dual residual {run.s_rel:.2e})"
        )
        warnings.warn(f"TNH with ADMM: {message}. Raise max_iter or loosen tol", RuntimeWarning, stacklevel=3)
    return TNHResult(
        x=X,
        fun=nuclear,
        status=run.status,
        message=message,
        nit=run.n_iter,
        wall_time=wall,
        method="admm",
        solver="ADMM",
        tau=0.0,
        exact_fit=True,
        **fit,
        options=options_record(tol, max_iter, beta0, alpha, adaptive, run.beta),
        dual=Y,
        duality_gap=float(run.gap * scale),
    )


def options_record(tol, max_iter, beta0, alpha, adaptive, final_beta) -> dict:
    """The ``options`` of an ADMM TNH result: those it ran with, and ``final_beta``, the adapted penalty."""
    keys = ("tol", "max_iter", "beta", "relaxation", "adaptive", "final_beta")
    return dict(zip(keys, (tol, max_iter, beta0, alpha, bool(adaptive), final_beta), strict=True))


def track_scale(term: OrthographicReprojection) -> float:
    """RMS of the observed tracks (1 if they are all zero): the unit of the ADMM solvers' normalised
    problems, whose objectives are positively homogeneous in the tracks."""
    scale = float(np.sqrt(np.sum(term.W**2) / (2 * max(int(term.mask.sum()), 1))))
    return scale if scale > 0 else 1.0


def check_admm_options(tol, max_iter, beta, relaxation) -> tuple[float, int, float, float]:
    """(tol, max_iter, initial beta, relaxation alpha) of the ADMM TNH solvers, validated."""
    tol = check_positive(tol, "tol")
    if tol >= 1.0:
        raise ValueError(f"tol must be in (0, 1); got {tol!r}")
    max_iter = check_count(max_iter, "max_iter")
    beta0 = 1.0 if beta is None else check_positive(beta, "beta")
    alpha = check_positive(relaxation, "relaxation")
    if alpha >= 2.0:
        raise ValueError(f"relaxation must be in (0, 2); got {relaxation!r}")
    return tol, max_iter, beta0, alpha


def _pinv_cameras(R: np.ndarray) -> np.ndarray:
    """Pseudo-inverses (F, 3, 2) of cameras (F, 2, 3), singular values < _RCOND * largest set to 0."""
    U, s, Vt = np.linalg.svd(R, full_matrices=False)  # U (F,2,2), s (F,2), Vt (F,2,3)
    cutoff = _RCOND * s[:, :1]
    inv = np.divide(1.0, s, out=np.zeros_like(s), where=(s > cutoff) & (s > 0))
    return np.einsum("fkc,fc,fdc->fkd", Vt.transpose(0, 2, 1), inv, U)


class _ExactFitSet:
    """The affine set C of shapes (F, 3P) that reproject exactly onto the observed tracks, in normalised
    units (tracks divided by ``scale``, their RMS over the observed entries), and its projections.

    Raises a ValueError when C is empty (an observed point outside the range of a singular camera).
    """

    def __init__(self, term: OrthographicReprojection):
        F, P = term.n_frames, term.n_points
        self.shape3 = (F, 3, P)
        self.shape = (F, 3 * P)
        self.observed = term.mask[:, None, :]  # (F, 1, P), broadcasts over the 3 coordinates

        # Normalised units: the problem is positively homogeneous in the tracks, so solve with b / scale.
        self.scale = scale = track_scale(term)
        W3 = (term.W / scale).reshape(F, 2, P)

        pinv = _pinv_cameras(term.R)  # (F, 3, 2)
        self.null_proj = np.eye(3) - np.einsum("fkc,fcl->fkl", pinv, term.R)  # (F, 3, 3), I - R^+ R
        # least-norm fit, (F, 3, P)
        self.offset = np.where(self.observed, np.einsum("fkc,fcp->fkp", pinv, W3), 0.0)
        fit = np.einsum("fck,fkp->fcp", term.R, self.offset) - W3  # residual of the least-norm fit, (F, 2, P)
        bad = term.mask & (np.abs(fit).max(axis=1) > _FEASIBILITY_RTOL * max(1.0, float(np.abs(W3).max())))
        if bad.any():
            f, j = np.argwhere(bad)[0]
            raise ValueError(
                f"no exact fit exists: point {j} observed in frame {f} is outside the range of the camera "
                f"R[{f}] (rank {np.linalg.matrix_rank(term.R[f])}); {int(bad.sum())} observed point(s) "
                f"are unreachable. Fix the cameras, hide those points in the mask or use a penalised solver"
            )

    def project(self, V: np.ndarray) -> np.ndarray:
        """P_C(V): observed blocks to the nearest exact reprojection, unobserved blocks unchanged."""
        V3 = V.reshape(self.shape3)
        return np.where(
            self.observed, np.einsum("fkl,flp->fkp", self.null_proj, V3) + self.offset, V3
        ).reshape(self.shape)

    def project_null(self, V: np.ndarray) -> np.ndarray:
        """Projection onto the null space of the constraints (N_f on observed blocks, identity else)."""
        V3 = V.reshape(self.shape3)
        return np.where(self.observed, np.einsum("fkl,flp->fkp", self.null_proj, V3), V3).reshape(self.shape)


def _initial_iterates(term, scale, offset, X0, Y0, beta) -> tuple[np.ndarray, np.ndarray]:
    """(Z, U) in normalised units: Z from X0 (default the least-norm fit), U = Y0 / beta (default 0)."""
    if X0 is None:
        Z = offset.reshape(term.shape).copy()
    else:
        Z = as_float_matrix(X0, "X0")
        if Z.shape != term.shape:
            raise ValueError(f"X0 must have shape (F, 3P) = {term.shape}; got {Z.shape}")
        Z = Z / scale
    if Y0 is None:
        U = np.zeros_like(Z)
    else:
        U = as_float_matrix(Y0, "Y0")
        if U.shape != term.shape:
            raise ValueError(f"Y0 must have shape (F, 3P) = {term.shape}; got {U.shape}")
        U = U / beta
    return Z, U


class _Run:
    """State of the ADMM loop when it stopped (normalised units)."""

    def __init__(self, X, U, beta, status, n_iter, gap, r_rel, s_rel):
        self.X, self.U, self.beta, self.status, self.n_iter = X, U, beta, status, n_iter
        self.gap, self.r_rel, self.s_rel = gap, r_rel, s_rel


def _iterate(feasible: _ExactFitSet, Z, U, beta, alpha, tol, max_iter, adaptive, verbose) -> _Run:
    """The ADMM iterations of the module docstring, with the stopping test every _ADAPT_EVERY
    iterations and residual balancing of beta."""
    status, n_iter, gap, changes = MAX_ITER, 0, np.nan, 0
    r_rel = s_rel = np.inf
    for it in range(1, max_iter + 1):
        n_iter = it
        X = feasible.project(Z - U)
        H = alpha * X + (1.0 - alpha) * Z
        V = H + U
        Z, z_nuclear = soft_threshold_singular_values_gram(V, 1.0 / beta)
        U = V - Z

        check = it % _ADAPT_EVERY == 0 or it == max_iter
        if not check:
            continue
        Y = beta * U
        r_rel, s_rel = _relative_residuals(X, Z, Y, feasible)
        if verbose and it % 100 == 0:
            print(
                f"ADMM {it:6d}  primal {r_rel:.2e}  dual {s_rel:.2e}  beta {beta:.3g}  "
                f"||Z||_* {z_nuclear:.6g}"
            )
        if r_rel <= tol and s_rel <= tol:
            gap, nuclear = _duality_gap(X, Y, feasible)
            if gap <= tol * nuclear:
                status = CONVERGED
                break
        if adaptive and changes < ADAPT_MAX_CHANGES:
            factor = balancing_factor(r_rel, s_rel)
            if factor is None:
                continue
            beta *= factor
            U /= factor
            changes += 1

    if status != CONVERGED:  # the gap at the last iterate (any earlier evaluation is stale)
        gap, _ = _duality_gap(X, beta * U, feasible)
    return _Run(X, U, beta, status, n_iter, gap, r_rel, s_rel)


def _relative_residuals(X, Z, Y, feasible: _ExactFitSet) -> tuple[float, float]:
    """Relative primal residual ||X - Z|| / max(||X||, ||Z||) and dual residual ||P_null(Y)|| / ||Y||."""
    norm_x, norm_z, norm_y = (float(np.linalg.norm(M)) for M in (X, Z, Y))
    r_rel = float(np.linalg.norm(X - Z)) / max(norm_x, norm_z, 1e-300)
    s_rel = float(np.linalg.norm(feasible.project_null(Y))) / max(norm_y, 1e-300)
    return r_rel, s_rel


def balancing_factor(r_rel: float, s_rel: float) -> float | None:
    """Residual balancing: the factor beta is multiplied by, or None to leave it."""
    if r_rel > _ADAPT_MU * s_rel:
        return _ADAPT_FACTOR
    if s_rel > _ADAPT_MU * r_rel:
        return 1.0 / _ADAPT_FACTOR
    return None


def _duality_gap(X: np.ndarray, Y: np.ndarray, feasible: _ExactFitSet) -> tuple[float, float]:
    """(||X||_* - dual bound, ||X||_*) for a feasible X and a multiplier estimate Y (normalised units)."""
    Yr = Y - feasible.project_null(Y)  # component in range(A^T)
    spectral = float(np.linalg.norm(Yr, 2)) if Yr.size else 0.0
    lower = float(np.vdot(X, Yr)) / max(1.0, spectral)
    nuclear = float(np.linalg.svd(X, compute_uv=False).sum())
    return nuclear - lower, nuclear
