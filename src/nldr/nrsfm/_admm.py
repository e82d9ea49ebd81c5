"""TNH by ADMM with known cameras: the exact fit (:func:`solve_admm`, the default backend of
:func:`~nldr.nrsfm._reconstruct.trace_norm_heuristic`) and the robust TNH
(:func:`robust_trace_norm_heuristic`), one loop whose only difference is the residual block.

Problems (shapes as rows X (F, 3P), tracks W (F, 2P), cameras R (F, 2, 3), visibility (F, P); A X the
observed projections, b the observed tracks)::

    exact fit:   min_X ||X||_*                       subject to  A X = b
    robust:      min_X tau ||X||_* + ||b - A X||_1    (an l1 reprojection term, for gross errors)

The robust problem is written with a residual block e: ``min ||X||_* + ||e||_1 / tau  s.t.  A X + e =
b`` (its objective over tau). Without e it is the exact fit. Both are ``min i_C(x) + g(z)  s.t.  x =
z`` with x = X (exact) or x = (X, e) (robust, per point the 3 shape rows stacked over the 2 residual
rows), C the affine set of the constraints and g the nuclear norm (plus ||e||_1 / tau). ADMM in scaled
form with the multiplier Y = beta U, relaxation alpha and penalty beta::

    x <- P_C(z - U)                     projection onto C, one small solve per (frame, point)
    h <- alpha x + (1 - alpha) z        relaxed iterate
    z <- prox_{g / beta}(h + U)         singular value thresholding (and soft-thresholding of e)
    U <- U + h - z

P_C decouples per (frame, point): with B_f = R_f (exact) or [R_f, I_2] (robust), an observed block
moves to N_f v + B_f^+ w_f(x_j), N_f = I - B_f^+ B_f the projector onto the null space of B_f; an
unobserved block keeps its shape rows and has e = 0. A rank-deficient camera is handled through its
pseudo-inverse (singular values below 1e-10 of the largest count as zero); if an observed point is
then not reachable, the exact fit is infeasible and a ValueError names the frame.

The problem is solved in normalised units (tracks divided by their RMS over the observed entries; both
objectives are positively homogeneous in the tracks) with beta = 1 as start, adapted by residual
balancing (He, Yang & Wang 2000; Boyd et al. 2011, sec. 3.4.1): every 10 iterations beta doubles when
the relative primal residual exceeds twice the relative dual residual, and halves in the opposite
case (U rescaled so that Y is unchanged); at most 50 changes (docs/PERFORMANCE.md).

Optimality certificate and stopping rule
----------------------------------------
x is optimal iff it is in C and some Y lies both in dg(z = x) and in the row space of the constraints,
range(B^T). The iterates deliver the subgradient by the prox step, so what remains are the primal
residual ``r = ||x - z||_F`` and the dual residual ``s = ||P_null(Y)||_F`` (its distance from
range(B^T)). The solver stops when ``r <= tol max(||x||, ||z||)``, ``s <= tol ||Y||`` **and** the relative
duality gap is at most tol. The gap is rigorous: Y_r = P_range(Y) = B^T lambda, scaled into the dual's
feasible set, bounds the optimum from below by its dual value <b, lambda>. Exact fit: the dual is
``max <b, lambda>  s.t.  ||A^T lambda||_2 <= 1`` and the upper bound is ||X||_* of the feasible x.
Robust: the dual adds ``|lambda_i| <= 1 / tau`` and the upper bound is the objective at the low-rank z,
which is returned (the problem is unconstrained in X). At termination the returned objective exceeds
the optimum by at most a relative tol / (1 - tol). The gap needs two extra SVDs and is evaluated only
when the residual tests pass. The exact fit's tol = 1e-6 determines TNH's e3D to a few 1e-4
(docs/REPRODUCTION.md#table-3-tnh; pass tol=1e-7 when that matters).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np

from .._validation import as_float_matrix, check_count, check_positive
from ..result import CONVERGED, MAX_ITER
from ._reprojection import OrthographicReprojection, check_shapes
from ._tnh import TNHResult, fit_summary, soft_threshold_singular_values_gram

__all__ = ["solve_admm", "robust_trace_norm_heuristic"]

_RCOND = 1e-10  # relative cut-off of camera singular values in the pseudo-inverse
_ADAPT_EVERY = 10  # iterations between residual-balancing checks
_ADAPT_MU = 2.0  # balance when one relative residual exceeds mu times the other
_ADAPT_FACTOR = 2.0
_ADAPT_MAX_CHANGES = 50
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

    The backend of ``trace_norm_heuristic(W2d, visible, R, method="admm", **options)``, which validates
    the tracks, cameras (rows need not be orthonormal) and mask into ``term``. See the module docstring
    for the algorithm, the certificate and the stopping rule.

    Parameters
    ----------
    term : OrthographicReprojection
        Tracks, cameras and visibility.
    tol : float in (0, 1), default 1e-6
        Relative tolerance of the primal residual, the dual residual and the duality gap.
    max_iter : int, default 50000
        Iteration cap; reaching it gives ``status == MAX_ITER`` and a RuntimeWarning.
    beta : float > 0, optional
        Initial penalty in normalised units (tracks divided by their RMS); default 1.0.
    X0, Y0 : arrays (F, 3P), optional
        Warm starts for Z (unit of the tracks; default the least-norm exact fit) and the multiplier Y
        (dimensionless; default zeros): from a result ``res``, ``X0=res.x, Y0=res.dual,
        beta=res.options["final_beta"]``.
    relaxation : float in (0, 2), default 1.6
        Relaxation parameter alpha (1 = plain ADMM).
    adaptive, verbose : bool, default True, False
        Adapt beta by residual balancing; print the residuals every 100 iterations and at the end.

    Returns
    -------
    TNHResult
        ``x`` (F, 3P) feasible to rounding, ``method="admm"``, ``tau=0.0``, ``fun = nuclear_norm``,
        ``dual`` the multiplier Y (F, 3P), ``duality_gap``, ``options`` with ``final_beta``.

    Raises
    ------
    ValueError
        For options out of range, X0 or Y0 of the wrong shape or not finite, and when no exact fit exists.
    """
    start = time.perf_counter()
    options = _check_options(tol, max_iter, beta, relaxation, adaptive)
    problem = _Splitting(term, tau=None)
    Z, U = problem.start(X0, Y0, options["beta"])
    run = problem.iterate(Z, U, options, verbose)
    X = run.X * problem.scale
    fit = fit_summary(term, X)
    message = _finish(run, "TNH with ADMM", verbose, f"||X||_* {fit['nuclear_norm']:.6g}")
    return TNHResult(
        x=X, fun=fit["nuclear_norm"], status=run.status, message=message, nit=run.nit,
        wall_time=time.perf_counter() - start, method="admm", solver="ADMM", tau=0.0, exact_fit=True, **fit,
        options={**options, "final_beta": run.beta}, dual=run.beta * run.U,
        duality_gap=float(run.gap * problem.scale),
    )  # fmt: skip


def robust_trace_norm_heuristic(
    W2d,
    visible,
    R,
    *,
    tau: float,
    tol: float = 1e-6,
    max_iter: int = 20_000,
    beta: float | None = None,
    relaxation: float = 1.6,
    X0=None,
    adaptive: bool = True,
    verbose: bool = False,
) -> TNHResult:
    """Robust TNH with known cameras: ``min tau ||X||_* + l1 reprojection error`` by ADMM.

    The l1 term leaves a coordinate unexplained at a cost proportional to its error, so a few displaced
    points are rejected instead of bending every shape towards them; on well-tracked motion it keeps the
    inliers' residuals exactly zero, needs no threshold, and keeps tau dimensionless (both terms are
    lengths). It is the Huber loss's delta -> 0 limit, per image coordinate like
    :class:`nldr.data_terms.Huber`. For small tau the exact fit is a solution; at large tau X = 0.

    Parameters
    ----------
    W2d, visible, R
        Tracks (F, 2P), visibility (F, P) or None (all observed) and known cameras (F, 2, 3), as in
        :func:`~nldr.nrsfm._reconstruct.trace_norm_heuristic`.
    tau : float > 0
        Weight of ||X||_* against the l1 reprojection error (dimensionless).
    tol, max_iter, beta, relaxation, adaptive, verbose
        As in :func:`solve_admm` (here max_iter defaults to 20000).
    X0 : array, shape (F, 3P), optional
        Start for Z (unit of the tracks), e.g. the exact-fit TNH; default the least-norm point of C.

    Returns
    -------
    TNHResult
        ``x`` (F, 3P) the shapes in the unit of the tracks; ``fun`` the objective tau ||X||_* + the l1
        reprojection error at ``x`` (unit of the tracks); ``method="admm_l1"``, ``solver="ADMM"``,
        ``exact_fit=False``; ``dual`` the dual-feasible multiplier mu of the residuals, shape (F, 2P)
        with zeros at unobserved entries (dimensionless, |mu| <= 1, ||A^T mu||_2 <= tau);
        ``duality_gap`` ``fun`` minus the certified lower bound <mu, b> (unit of the tracks).

    Raises
    ------
    ValueError
        For malformed tracks, visibility or cameras, tau <= 0, and the option errors of :func:`solve_admm`.
    """
    start = time.perf_counter()
    term = OrthographicReprojection(W2d, visible, R)  # validates tracks, cameras and visibility
    tau = check_positive(tau, "tau")
    options = _check_options(tol, max_iter, beta, relaxation, adaptive)
    problem = _Splitting(term, tau=tau)
    Z, U = problem.start(X0, None, options["beta"])
    run = problem.iterate(Z, U, options, verbose)
    X = problem.shapes(run.Z) * problem.scale
    fit = fit_summary(term, X)
    l1 = float(np.abs(term.residuals(X)).sum())
    fun = tau * fit["nuclear_norm"] + l1
    mu = tau * problem.best_dual  # (F, 2, P), zero where unobserved
    lower = float(np.vdot(mu, term.W.reshape(mu.shape)))
    message = _finish(run, "robust TNH", verbose, f"objective {fun:.6g}, lower bound {lower:.6g}")
    return TNHResult(
        x=X, fun=fun, status=run.status, message=message, nit=run.nit, wall_time=time.perf_counter() - start,
        method="admm_l1", solver="ADMM", tau=tau, exact_fit=False, **fit,
        options={**options, "final_beta": run.beta}, dual=mu.reshape(term.n_frames, -1),
        duality_gap=float(fun - lower),
    )  # fmt: skip


def _check_options(tol, max_iter, beta, relaxation, adaptive) -> dict:
    tol = check_positive(tol, "tol")
    if tol >= 1.0:
        raise ValueError(f"tol must be in (0, 1); got {tol!r}")
    alpha = check_positive(relaxation, "relaxation")
    if alpha >= 2.0:
        raise ValueError(f"relaxation must be in (0, 2); got {relaxation!r}")
    beta = 1.0 if beta is None else check_positive(beta, "beta")
    return {"tol": tol, "max_iter": check_count(max_iter, "max_iter"), "beta": beta, "relaxation": alpha,
            "adaptive": bool(adaptive)}  # fmt: skip


def _finish(run, name: str, verbose: bool, summary: str) -> str:
    """The result message (and the warning or the verbose line) of a finished run."""
    if run.status == CONVERGED:
        message = f"optimal: residuals and duality gap within tol={run.tol:g} after {run.nit} iterations"
    else:
        message = (
            f"tolerance {run.tol:g} not met after max_iter={run.nit} iterations (relative primal residual "
            f"{run.r_rel:.2e}, dual residual {run.s_rel:.2e})"
        )
        warnings.warn(f"{name}: {message}. Raise max_iter or loosen tol", RuntimeWarning, stacklevel=3)
    if verbose:
        print(f"{name}: {message}; {summary}")
    return message


def _pinv_blocks(B: np.ndarray) -> np.ndarray:
    """Pseudo-inverses (F, n, 2) of (F, 2, n), singular values < _RCOND * largest set to 0."""
    U, s, Vt = np.linalg.svd(B, full_matrices=False)  # U (F,2,2), s (F,2), Vt (F,2,n)
    cutoff = _RCOND * s[:, :1]
    inv = np.divide(1.0, s, out=np.zeros_like(s), where=(s > cutoff) & (s > 0))
    return np.einsum("fkc,fc,fdc->fkd", Vt.transpose(0, 2, 1), inv, U)


@dataclass
class _Run:
    """State of the ADMM loop when it stopped (normalised units)."""

    X: np.ndarray
    Z: np.ndarray
    U: np.ndarray
    beta: float
    status: int
    nit: int
    gap: float
    r_rel: float
    s_rel: float
    tol: float


class _Splitting:
    """The splitting of the module docstring in normalised units: the affine set C of x (blocks (F, k, P),
    k = 3 shape rows, plus 2 residual rows for the robust TNH), its projections, the prox of g and the
    duality gap. ``tau=None``: the exact fit."""

    def __init__(self, term: OrthographicReprojection, tau: float | None):
        F, P = term.n_frames, term.n_points
        self.tau, self.R = tau, term.R
        k = 3 if tau is None else 5
        self.shape3, self.shape = (F, k, P), (F, k * P)
        self.observed = term.mask[:, None, :]  # (F, 1, P), broadcasts over the block's rows
        self.scale = scale = float(np.sqrt(np.sum(term.W**2) / (2 * max(int(term.mask.sum()), 1)))) or 1.0
        self.b = (term.W / scale).reshape(F, 2, P)
        B = term.R if tau is None else np.concatenate([term.R, np.broadcast_to(np.eye(2), (F, 2, 2))], axis=2)
        pinv = _pinv_blocks(B)  # (F, k, 2)
        self.null_proj = np.eye(k) - np.einsum("fkc,fcl->fkl", pinv, B)  # (F, k, k), I - B^+ B
        self.offset = np.where(
            self.observed, np.einsum("fkc,fcp->fkp", pinv, self.b), 0.0
        )  # least-norm point
        # unobserved blocks: the shape rows are free, a residual row is 0
        self.free = None if tau is None else np.array([1.0, 1.0, 1.0, 0.0, 0.0])[None, :, None]
        self.best_lower, self.best_dual = -np.inf, np.zeros((F, 2, P))
        if tau is not None:
            return
        fit = np.einsum("fck,fkp->fcp", term.R, self.offset) - self.b  # residual of the least-norm fit
        bad = term.mask & (
            np.abs(fit).max(axis=1) > _FEASIBILITY_RTOL * max(1.0, float(np.abs(self.b).max()))
        )
        if bad.any():
            f, j = np.argwhere(bad)[0]
            raise ValueError(
                f"no exact fit exists: point {j} observed in frame {f} is outside the range of the camera "
                f"R[{f}] (rank {np.linalg.matrix_rank(term.R[f])}); {int(bad.sum())} observed point(s) "
                f"are unreachable. Fix the cameras, hide those points in the mask or use a penalised solver"
            )

    def start(self, X0, Y0, beta) -> tuple[np.ndarray, np.ndarray]:
        """(Z, U): Z from X0 (default the least-norm point of C), U = Y0 / beta (default 0)."""
        F, k, P = self.shape3
        if X0 is None:
            Z = self.offset.reshape(self.shape).copy()
        else:
            X0 = check_shapes(X0, F, P, name="X0")
            Z = np.zeros(self.shape3)
            Z[:, :3] = X0.reshape(F, 3, P) / self.scale
            Z = Z.reshape(self.shape)
        if Y0 is None:
            return Z, np.zeros_like(Z)
        U = as_float_matrix(Y0, "Y0")
        if U.shape != self.shape:
            raise ValueError(f"Y0 must have shape (F, 3P) = {self.shape}; got {U.shape}")
        return Z, U / beta

    def project(self, V: np.ndarray, offset: bool = True) -> np.ndarray:
        """P_C(V) (``offset=False``: the projection onto the null space of the constraints)."""
        V3 = V.reshape(self.shape3)
        NV = np.einsum("fkl,flp->fkp", self.null_proj, V3)
        return np.where(
            self.observed, NV + self.offset if offset else NV, V3 if self.free is None else V3 * self.free
        ).reshape(self.shape)

    def shapes(self, V: np.ndarray) -> np.ndarray:
        """The shape rows (F, 3P) of x- or z-shaped V."""
        return V.reshape(self.shape3)[:, :3].reshape(self.shape3[0], -1)

    def prox(self, V: np.ndarray, t: float) -> tuple[np.ndarray, float]:
        """prox_{t g}(V) and ||.||_* of its shapes."""
        if self.tau is None:
            return soft_threshold_singular_values_gram(V, t)
        V3 = V.reshape(self.shape3)
        S, nuclear = soft_threshold_singular_values_gram(self.shapes(V), t)
        e = V3[:, 3:]
        e = np.sign(e) * np.maximum(np.abs(e) - t / self.tau, 0.0)
        return np.concatenate([S.reshape(self.shape3[0], 3, -1), e], axis=1).reshape(self.shape), nuclear

    def duality_gap(self, X: np.ndarray, Z: np.ndarray, Y: np.ndarray) -> tuple[float, float]:
        """(upper bound - dual bound, upper bound) for the iterates and a multiplier estimate Y."""
        Yr = Y - self.project(Y, offset=False)  # component in range(B^T)
        if self.tau is None:
            spectral = float(np.linalg.norm(Yr, 2)) if Yr.size else 0.0
            nuclear = float(np.linalg.svd(X, compute_uv=False).sum())
            return nuclear - float(np.vdot(X, Yr)) / max(1.0, spectral), nuclear
        lam = np.where(self.observed, Yr.reshape(self.shape3)[:, 3:], 0.0)  # Yr = (R^T lam, lam)
        spectral = float(np.linalg.norm(self.shapes(Yr), 2))
        lam = lam / max(1.0, spectral, self.tau * float(np.abs(lam).max()))
        lower = float(np.vdot(lam, self.b))
        if lower > self.best_lower:  # every evaluated bound is valid: keep the best
            self.best_lower, self.best_dual = lower, lam
        S = self.shapes(Z).reshape(self.shape3[0], 3, -1)
        l1 = float(np.abs(np.where(self.observed, self.b - self.R @ S, 0.0)).sum())
        upper = float(np.linalg.svd(self.shapes(Z), compute_uv=False).sum()) + l1 / self.tau
        return upper - self.best_lower, upper

    def iterate(self, Z, U, options, verbose) -> _Run:
        """The ADMM iterations, the stopping test every _ADAPT_EVERY iterations, residual balancing."""
        tol, max_iter, beta, alpha = (options[k] for k in ("tol", "max_iter", "beta", "relaxation"))
        status, nit, gap, changes = MAX_ITER, 0, np.nan, 0
        r_rel = s_rel = np.inf
        for it in range(1, max_iter + 1):
            nit = it
            X = self.project(Z - U)
            H = alpha * X + (1.0 - alpha) * Z
            V = H + U
            Z, z_nuclear = self.prox(V, 1.0 / beta)
            U = V - Z
            if not (it % _ADAPT_EVERY == 0 or it == max_iter):
                continue
            Y = beta * U
            norm_x, norm_z, norm_y = (float(np.linalg.norm(M)) for M in (X, Z, Y))
            r_rel = float(np.linalg.norm(X - Z)) / max(norm_x, norm_z, 1e-300)
            s_rel = float(np.linalg.norm(self.project(Y, offset=False))) / max(norm_y, 1e-300)
            if verbose and it % 100 == 0:
                print(f"ADMM {it:6d}  primal {r_rel:.2e}  dual {s_rel:.2e}  beta {beta:.3g}  {z_nuclear:.6g}")
            if r_rel <= tol and s_rel <= tol:
                gap, upper = self.duality_gap(X, Z, Y)
                if gap <= tol * upper:
                    status = CONVERGED
                    break
            if options["adaptive"] and changes < _ADAPT_MAX_CHANGES:
                up, down = r_rel > _ADAPT_MU * s_rel, s_rel > _ADAPT_MU * r_rel
                if not (up or down):
                    continue
                factor = _ADAPT_FACTOR if up else 1 / _ADAPT_FACTOR
                beta *= factor
                U /= factor
                changes += 1
        if status != CONVERGED:  # the gap at the last iterate (any earlier evaluation is stale)
            gap, _ = self.duality_gap(X, Z, beta * U)
        return _Run(X, Z, U, beta, status, nit, gap, r_rel, s_rel, tol)
