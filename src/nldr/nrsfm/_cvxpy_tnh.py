"""TNH as a conic program through cvxpy: the reference backend of
:func:`~nldr.nrsfm._reconstruct.trace_norm_heuristic` (``method="cvxpy"``), and :class:`CvxpyTNH` for tau
sweeps.

cvxpy is an optional dependency (``pip install nldr[cvxpy]``); importing this module without it raises
an ImportError that says so. cvxpy turns ||X||_* into a semidefinite cone of order F + 3P: the
interior-point CLARABEL is accurate and practical for small problems (the tests' reference), the
first-order SCS (the default) handles the subsampled sequences; neither takes full-length sequences,
which the ADMM backend does (benchmarks/bench_tnh.py). tau is a ``cvxpy.Parameter``, compiled on the
first solve, so a tau sweep on one :class:`CvxpyTNH` re-solves without recompiling.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

try:
    import cvxpy as cp
except ImportError as exc:  # pragma: no cover - exercised by tests with cvxpy hidden
    raise ImportError(
        "TNH with method='cvxpy' needs cvxpy, an optional dependency of nldr: pip install nldr[cvxpy] "
        "(or use method='admm' for the exact fit)"
    ) from exc

from .._validation import check_positive
from ..result import CONVERGED, INACCURATE
from ._reprojection import OrthographicReprojection
from ._tnh import TNHResult, TNHSolveError, fit_summary

__all__ = ["DEFAULT_SOLVER_OPTIONS", "CvxpyTNH"]

#: Default options per conic solver. SCS: eps_abs = eps_rel = 1e-6 (cvxpy's default 1e-5; the choice is
#: measured by benchmarks/bench_tnh.py), max_iters raised so that the tolerance, not the cap, stops it.
DEFAULT_SOLVER_OPTIONS: dict[str, dict] = {
    "SCS": {"eps_abs": 1e-6, "eps_rel": 1e-6, "max_iters": 200_000},
    "CLARABEL": {},
}

_ACCEPTED = (cp.OPTIMAL, cp.OPTIMAL_INACCURATE)


class CvxpyTNH:
    """TNH for NRSfM with known cameras as a cvxpy problem, compiled once and solved for any tau.

    Parameters
    ----------
    W2d, visible, R
        Tracks (F, 2P), visibility (F, P) or None (all observed) and known cameras (F, 2, 3), as in
        :func:`~nldr.nrsfm._reconstruct.trace_norm_heuristic`.

    Attributes
    ----------
    data_term : OrthographicReprojection
        The reprojection term; its constant Jacobian is the linear operator of the constraints.
    tau : cvxpy.Parameter
        Non-negative parameter of the penalised problem.

    Examples
    --------
    >>> tnh = CvxpyTNH(W2d, visible, R)                   # doctest: +SKIP
    >>> exact = tnh.solve()                                # tau -> 0: exact reprojection
    >>> sweep = [tnh.solve(tau) for tau in (1e-2, 1e-1)]  # compiled once, re-solved
    """

    def __init__(self, W2d, visible, R):
        self.data_term = OrthographicReprojection(W2d, visible, R)
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
            Weight of ||X||_* (unit of the tracks squared); None or 0 solves the exact-fit form.
        solver : str, default "SCS"
            A cvxpy conic solver that handles semidefinite cones ("SCS", "CLARABEL", ...).
        solver_options : dict, optional
            Passed to the solver, replacing :data:`DEFAULT_SOLVER_OPTIONS` for that solver key by key.
        warm_start : bool, default False
            Start from the previous solution (useful in tau sweeps with SCS).
        verbose : bool, default False

        Returns
        -------
        TNHResult
            ``method="cvxpy"``, ``solver`` the conic solver; ``fun`` the solver's optimal value;
            ``nit`` and ``solver_time`` as the solver reports them; status INACCURATE for cvxpy's
            ``optimal_inaccurate`` (with a RuntimeWarning).

        Raises
        ------
        TNHSolveError
            If the solver fails or the status is neither optimal nor optimal_inaccurate.
        ValueError
            For an unknown solver or a negative tau.
        """
        tau_value = 0.0 if tau is None else check_positive(tau, "tau", allow_zero=True)
        exact = tau_value == 0.0
        if exact:
            problem = self._exact
        else:
            self.tau.value = tau_value
            problem = self._penalised
        if not isinstance(solver, str) or solver.upper() not in cp.installed_solvers():
            raise ValueError(
                f"solver must be one of the installed cvxpy solvers {cp.installed_solvers()}; got {solver!r}"
            )
        solver = solver.upper()
        options = {**DEFAULT_SOLVER_OPTIONS.get(solver, {}), **(solver_options or {})}
        form = "exact fit" if exact else f"tau={tau_value:g}"
        start = time.perf_counter()
        try:
            problem.solve(solver=solver, warm_start=warm_start, verbose=verbose, **options)
        except cp.error.SolverError as exc:
            raise TNHSolveError(f"TNH ({form}) with {solver} failed: {exc}") from exc
        wall = time.perf_counter() - start
        status = problem.status
        if status not in _ACCEPTED or self._x.value is None:
            raise TNHSolveError(
                f"TNH ({form}) with {solver} ended with status {status!r}; try another solver or "
                f"looser/tighter solver_options"
            )
        if status == cp.OPTIMAL_INACCURATE:
            warnings.warn(
                f"TNH with {solver}: status optimal_inaccurate (solver stopped before its tolerance); "
                f"raise max_iters or loosen eps",
                RuntimeWarning,
                stacklevel=2,
            )
        X = np.asarray(self._x.value, dtype=np.float64).reshape(self.data_term.shape)
        stats = problem.solver_stats
        n_iter = None if stats is None else stats.num_iters
        return TNHResult(
            x=X, fun=float(problem.value), status=CONVERGED if status == cp.OPTIMAL else INACCURATE,
            message=f"{solver} ({form}): {status}", nit=int(n_iter or 0), wall_time=wall, method="cvxpy",
            solver=solver, tau=tau_value, exact_fit=exact, **fit_summary(self.data_term, X), options=options,
            solver_time=None if stats is None else stats.solve_time,
        )  # fmt: skip
