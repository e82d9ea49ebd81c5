"""The result type of the trace-norm heuristic, shared by its solvers (:mod:`nldr.nrsfm.tnh` is the
entry point; :mod:`~nldr.nrsfm.admm`, :mod:`~nldr.nrsfm.fista` and :mod:`~nldr.nrsfm.cvxpy_tnh` are
its backends, each returning a :class:`TNHResult`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..result import SolverResult
from .reprojection import OrthographicReprojection

__all__ = ["TNHResult", "TNHSolveError", "fit_summary"]


class TNHSolveError(RuntimeError):
    """The conic solver failed or did not return an optimal solution; the message has the status."""


@dataclass(kw_only=True, repr=False)
class TNHResult(SolverResult):
    """Result of a TNH solve (:func:`~nldr.nrsfm.tnh.trace_norm_heuristic`), a
    :class:`~nldr.result.SolverResult`.

    Attributes
    ----------
    x : array, shape (F, 3P)
        Estimated shapes as rows, in the unit of the image tracks.
    fun : float
        The objective at ``x``: ||X||_* for the exact fit, tau ||X||_* + reprojection error otherwise.
        ADMM and FISTA evaluate it at ``x``; cvxpy reports the conic solver's optimal value.
    status : int
        CONVERGED: the solver met its tolerance (cvxpy: status ``optimal``); MAX_ITER: it reached its
        iteration cap (ADMM, FISTA); INACCURATE: cvxpy's ``optimal_inaccurate``.
    message : str
        Why the solver stopped.
    nit : int
        Iterations of the solver (cvxpy: as the conic solver reports them, 0 if it does not).
    wall_time : float
        Seconds of wall-clock time (cvxpy: of ``problem.solve``, compilation on a first solve included).
    method : str
        ``"admm"``, ``"fista"`` or ``"cvxpy"``.
    solver : str
        ``"ADMM"``, ``"FISTA"`` or the name of the conic solver (``"SCS"``, ``"CLARABEL"``, ...).
    tau : float
        Regularisation strength; 0.0 for the exact-fit form.
    exact_fit : bool
        True when solved with equality constraints (the tau -> 0 limit).
    nuclear_norm : float
        ||X||_* of the returned X (ADMM, cvxpy: recomputed with an SVD; FISTA: from its last
        thresholding).
    reprojection_error : float
        Sum over observed points of squared reprojection errors of the returned X (unit squared).
    max_abs_residual : float
        Largest absolute reprojection residual over observed coordinates (unit of the tracks).
    options : dict
        The options the solver ran with (defaults filled in). ADMM adds ``final_beta``, its adapted
        penalty; cvxpy: the conic solver's options.
    dual : array, shape (F, 3P), or None
        ADMM only: the multiplier Y of the splitting X = Z (dimensionless), an optimality certificate:
        Y is a subgradient of ||.||_* and lies (to the dual residual) in the row space of the
        constraints; see :mod:`nldr.nrsfm.admm`.
    duality_gap : float or None
        ADMM only: ||X||_* minus a certified lower bound on the optimum (unit of the tracks).
    solver_time : float or None
        cvxpy only: seconds inside the conic solver, as it reports them.
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


def fit_summary(term: OrthographicReprojection, X: np.ndarray) -> dict[str, float]:
    """``nuclear_norm`` (by an SVD), ``reprojection_error`` and ``max_abs_residual`` of shapes X
    (F, 3P) under the reprojection term: the fit fields of a :class:`TNHResult`."""
    r = term.residuals(X)
    return {
        "nuclear_norm": float(np.linalg.svd(X, compute_uv=False).sum()),
        "reprojection_error": float(r @ r),
        "max_abs_residual": float(np.max(np.abs(r))) if r.size else 0.0,
    }
