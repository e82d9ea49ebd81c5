"""Trace-norm heuristic (TNH) for NRSfM with known cameras: the paper's linear baseline (eq. 12).

Penalised form, for tau > 0::

    min_X  tau ||X||_*  +  sum_{f,j} Z_fj ||w_f(x_j) - R_f s_f(x_j)||^2

Exact-fit form, the limit tau -> 0 (noise-free data; Dai, Li & He 2012)::

    min_X  ||X||_*   subject to   R_f s_f(x_j) = w_f(x_j)  for every observed (f, j)

X is the (F, 3P) shape matrix (shapes as rows; its nuclear norm equals that of the paper's (3P, F)
matrix). The paper runs TNH with ground-truth cameras and tau = 1e-7 in the data's original units; at
that strength the penalised problem is the exact-fit problem in practice, and the exact-fit form is the
numerically sound way to solve it. Measured on pickup (every 10th frame): the penalised form with
tau = 1e-7 has an optimal value ~1e-5, below what SCS resolves; SCS at eps 1e-5 stopped after 50
iterations at an exact fit of the wrong nuclear norm (e3D 0.55) and at eps 1e-7 had not finished after
14 minutes. With tau = 1e-4 ... 1e-3 the penalised form solves normally and gives the exact fit's e3D
(0.0475) to 4 digits.

Solver choice. cvxpy turns ||X||_* into a semidefinite cone of order F + 3P (159 for pickup sampled
every 10th frame, 234 for drink). The interior-point solver CLARABEL is accurate but its KKT systems
grow quickly with the cone order: it did not finish pickup's exact fit within 2 minutes (a trial
reported 9.5 minutes, e3D 0.0475). The first-order solver SCS, with the default tolerances below,
takes 2-10 s on pickup, yoga and stretch and ~3.5 minutes on drink's full-data exact fit (its
near-degenerate low-rank optimum slows the tail of convergence), and matches CLARABEL on small
problems (tests/test_nrsfm.py). SCS is therefore the default; CLARABEL is the reference for small
problems. Timings and e3D per sequence: benchmarks/bench_tnh.py.

For the exact-fit form ``solver="ADMM"`` bypasses cvxpy and runs :func:`nldr.nrsfm.admm.tnh_admm`, a
first-order splitting whose cost per iteration is linear in F: seconds on the subsampled sequences
and on full-length ones (drink, 1102 frames), which SCS cannot handle; benchmarks/bench_tnh_admm.py.
Constructing :class:`TraceNormHeuristic` only builds cvxpy's expression trees (~0.02 s for drink's
1102 frames); cvxpy compiles a problem on its first solve, so an ADMM-only use never pays for it.

The parameter tau is a ``cvxpy.Parameter``: sweeping tau re-solves without recompiling.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import cvxpy as cp
import numpy as np

from .._validation import check_positive
from .reprojection import OrthographicReprojection

__all__ = [
    "DEFAULT_SOLVER_OPTIONS",
    "TNHSolveError",
    "TNHResult",
    "TraceNormHeuristic",
    "trace_norm_heuristic",
]

#: Default options per solver. SCS: eps_abs = eps_rel = 1e-6 (cvxpy's default is 1e-5). On the paper's
#: four sequences (every 10th frame, exact fit) e3D at 1e-5, 1e-6 and 1e-7 agrees to 1e-5 or better
#: except drink at 1e-5 (0.0220 against 0.0221); 1e-6 costs 1.3-4x the iterations of 1e-5 and 1e-7
#: another 1.2-3x (drink full: 5400, 23875, 67525 iterations); see benchmarks/bench_tnh.py.
#: max_iters is raised from SCS's 1e5 so that the tolerance, not the cap, stops the solver.
DEFAULT_SOLVER_OPTIONS: dict[str, dict] = {
    "SCS": {"eps_abs": 1e-6, "eps_rel": 1e-6, "max_iters": 200_000},
    "CLARABEL": {},
}

_ACCEPTED = (cp.OPTIMAL, cp.OPTIMAL_INACCURATE)


class TNHSolveError(RuntimeError):
    """The conic solver failed or did not return an optimal solution; the message has the status."""


@dataclass
class TNHResult:
    """Result of a TNH solve (like ``scipy.optimize.OptimizeResult``).

    Attributes
    ----------
    X : array, shape (F, 3P)
        Estimated shapes as rows, in the unit of the image tracks.
    tau : float
        Regularisation strength; 0.0 for the exact-fit form.
    exact_fit : bool
        True when solved with equality constraints (the tau -> 0 limit).
    status : str
        cvxpy status, ``"optimal"`` or ``"optimal_inaccurate"`` (others raise :class:`TNHSolveError`).
    solver : str
        Name of the conic solver.
    solve_time : float
        Wall-clock seconds of ``problem.solve`` (includes cvxpy's compilation on the first solve).
    solver_time : float or None
        Seconds spent inside the solver, as it reports.
    n_iter : int or None
        Solver iterations, as it reports.
    objective : float
        Optimal value reported by the solver: ||X||_* (exact fit) or tau ||X||_* + reprojection error.
    nuclear_norm : float
        ||X||_* of the returned X, recomputed with an SVD.
    reprojection_error : float
        Sum over observed points of squared reprojection errors of the returned X (unit squared).
    max_abs_residual : float
        Largest absolute reprojection residual over observed coordinates (unit of the tracks).
    solver_options : dict
        Options passed to the solver.
    dual : array, shape (F, 3P), or None
        ADMM only: the multiplier Y of the splitting X = Z (dimensionless), an optimality certificate:
        Y is a subgradient of ||.||_* and lies (to the dual residual) in the row space of the
        constraints; see :mod:`nldr.nrsfm.admm`. None for the cvxpy solvers.
    duality_gap : float or None
        ADMM only: ||X||_* minus a certified lower bound on the optimum (unit of the tracks).
    """

    X: np.ndarray
    tau: float
    exact_fit: bool
    status: str
    solver: str
    solve_time: float
    solver_time: float | None
    n_iter: int | None
    objective: float
    nuclear_norm: float
    reprojection_error: float
    max_abs_residual: float
    solver_options: dict = field(default_factory=dict)
    dual: np.ndarray | None = None
    duality_gap: float | None = None

    @property
    def success(self) -> bool:
        """True when the solver reported ``optimal`` (not merely ``optimal_inaccurate``)."""
        return self.status == cp.OPTIMAL


class TraceNormHeuristic:
    """TNH for NRSfM with known cameras, compiled once and solved for any tau (or exactly).

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Image tracks as rows (row f = x of the P points, then y), length unit of the data.
    R : array, shape (F, 2, 3)
        Known orthographic cameras.
    mask : bool array, shape (F, P), optional
        True where point j is observed in frame f. Default: all observed.

    Attributes
    ----------
    data_term : OrthographicReprojection
        The reprojection term; its constant Jacobian is the linear operator of the constraints.
    tau : cvxpy.Parameter
        Non-negative parameter of the penalised problem.

    Examples
    --------
    >>> tnh = TraceNormHeuristic(W2d, R, mask)            # doctest: +SKIP
    >>> exact = tnh.solve()                                # tau -> 0: exact reprojection
    >>> sweep = [tnh.solve(tau) for tau in (1e-2, 1e-1)]  # compiled once, re-solved
    """

    def __init__(self, W2d, R, mask=None):
        self.data_term = OrthographicReprojection(W2d, R, mask)
        F, threeP = self.data_term.shape
        # r(X) = b - A vec(X): A = -J (constant), b = observed image coordinates.
        A = -self.data_term.jacobian()
        b = self.data_term.residuals(np.zeros(self.data_term.shape))
        self._x = cp.Variable(F * threeP, name="vecX")
        X = cp.reshape(self._x, (F, threeP), order="C")
        self.tau = cp.Parameter(nonneg=True, name="tau", value=1.0)
        nuclear = cp.normNuc(X)
        self._penalised = cp.Problem(cp.Minimize(self.tau * nuclear + cp.sum_squares(A @ self._x - b)))
        self._exact = cp.Problem(cp.Minimize(nuclear), [A @ self._x == b])
        self._admm_last: TNHResult | None = None  # last ADMM solution, the warm start of the next

    def _solve_admm(self, tau_value: float, solver_options, warm_start: bool, verbose: bool) -> TNHResult:
        """Exact-fit TNH by :func:`~nldr.nrsfm.admm.tnh_admm` (no cvxpy compilation)."""
        from .admm import ADMM_OPTIONS, tnh_admm  # admm imports TNHResult from this module

        if tau_value != 0.0:
            raise ValueError(
                f"solver 'ADMM' solves the exact-fit form only (tau None or 0); got tau={tau_value:g}. "
                f"Use a cvxpy solver (e.g. 'SCS') or nldr.nrsfm.proximal.tnh_proximal for tau > 0"
            )
        options = dict(solver_options or {})
        unknown = sorted(set(options) - set(ADMM_OPTIONS))
        if unknown:
            raise ValueError(
                f"unknown solver_options for ADMM: {unknown}; allowed: {sorted(ADMM_OPTIONS)} "
                f"(verbose is the argument of solve)"
            )
        last = self._admm_last
        if warm_start and last is not None and "X0" not in options and "Y0" not in options:
            options.update(X0=last.X, Y0=last.dual)
            options.setdefault("beta", last.solver_options["final_beta"])
        term = self.data_term
        result = tnh_admm(term.W, term.R, term.mask, verbose=verbose, **options)
        self._admm_last = result
        return result

    def solve(
        self,
        tau: float | None = None,
        *,
        solver: str = "SCS",
        solver_options: dict | None = None,
        warm_start: bool = False,
        verbose: bool = False,
    ) -> TNHResult:
        """Solve TNH, penalised (``tau > 0``) or exact-fit (``tau`` None or 0).

        Parameters
        ----------
        tau : float or None
            Weight of ||X||_* against the sum of squared reprojection errors (the data's squared unit
            per unit of nuclear norm). None or 0 solves the exact-fit form.
        solver : str, default "SCS"
            A cvxpy conic solver that handles semidefinite cones ("SCS", "CLARABEL", ...), or
            ``"ADMM"`` for :func:`~nldr.nrsfm.admm.tnh_admm` (exact-fit form only).
        solver_options : dict, optional
            Passed to the solver, replacing :data:`DEFAULT_SOLVER_OPTIONS` for that solver key by key.
            For ADMM: keyword arguments of :func:`~nldr.nrsfm.admm.tnh_admm` (``tol``, ``max_iter``,
            ``beta``, ``X0``, ``Y0``, ``relaxation``, ``adaptive``).
        warm_start : bool, default False
            Start from the previous solution (useful in tau sweeps with SCS; with ADMM the previous
            ADMM solution, its multiplier and final penalty become ``X0``, ``Y0`` and ``beta`` unless
            ``solver_options`` gives X0 or Y0).
        verbose : bool, default False

        Returns
        -------
        TNHResult

        Raises
        ------
        TNHSolveError
            If the solver fails or the status is neither optimal nor optimal_inaccurate (a warning is
            issued for optimal_inaccurate).
        ValueError
            For an unknown solver, a negative tau, ``solver="ADMM"`` with tau > 0, unknown ADMM options
            or an infeasible exact fit detected by ADMM (see :func:`~nldr.nrsfm.admm.tnh_admm`).
        """
        tau_value = 0.0 if tau is None else check_positive(tau, "tau", allow_zero=True)
        exact = tau_value == 0.0
        if isinstance(solver, str) and solver.upper() == "ADMM":
            return self._solve_admm(tau_value, solver_options, warm_start, verbose)
        if exact:
            problem = self._exact
        else:
            self.tau.value = tau_value
            problem = self._penalised
        if not isinstance(solver, str) or solver.upper() not in cp.installed_solvers():
            raise ValueError(
                f"solver must be 'ADMM' or one of the installed cvxpy solvers {cp.installed_solvers()}; "
                f"got {solver!r}"
            )
        solver = solver.upper()
        options = {**DEFAULT_SOLVER_OPTIONS.get(solver, {}), **(solver_options or {})}
        start = time.perf_counter()
        try:
            problem.solve(solver=solver, warm_start=warm_start, verbose=verbose, **options)
        except cp.error.SolverError as exc:
            raise TNHSolveError(
                f"TNH ({'exact fit' if exact else f'tau={tau_value:g}'}) with {solver} failed: {exc}"
            ) from exc
        wall = time.perf_counter() - start
        status = problem.status
        if status not in _ACCEPTED or self._x.value is None:
            raise TNHSolveError(
                f"TNH ({'exact fit' if exact else f'tau={tau_value:g}'}) with {solver} ended with status "
                f"{status!r}; try another solver or looser/tighter solver_options"
            )
        if status == cp.OPTIMAL_INACCURATE:
            warnings.warn(
                f"TNH with {solver}: status optimal_inaccurate (solver stopped before its tolerance); "
                f"raise max_iters or loosen eps",
                RuntimeWarning,
                stacklevel=2,
            )
        X = np.asarray(self._x.value, dtype=np.float64).reshape(self.data_term.shape)
        r = self.data_term.residuals(X)
        stats = problem.solver_stats
        return TNHResult(
            X=X,
            tau=tau_value,
            exact_fit=exact,
            status=status,
            solver=solver,
            solve_time=wall,
            solver_time=None if stats is None else stats.solve_time,
            n_iter=None if stats is None else stats.num_iters,
            objective=float(problem.value),
            nuclear_norm=float(np.linalg.svd(X, compute_uv=False).sum()),
            reprojection_error=float(r @ r),
            max_abs_residual=float(np.max(np.abs(r))) if r.size else 0.0,
            solver_options=options,
        )


def trace_norm_heuristic(
    W2d,
    R,
    mask=None,
    tau: float | None = None,
    *,
    solver: str = "SCS",
    solver_options: dict | None = None,
    verbose: bool = False,
) -> TNHResult:
    """One TNH solve; see :class:`TraceNormHeuristic` (use it directly for tau sweeps).

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Image tracks as rows.
    R : array, shape (F, 2, 3)
        Known orthographic cameras.
    mask : bool array, shape (F, P), optional
        Visibility; default all observed.
    tau : float or None
        None or 0: exact fit (min ||X||_* s.t. exact reprojection of the observed points).
    solver, solver_options, verbose
        See :meth:`TraceNormHeuristic.solve`.

    Returns
    -------
    TNHResult
    """
    return TraceNormHeuristic(W2d, R, mask).solve(
        tau, solver=solver, solver_options=solver_options, verbose=verbose
    )
