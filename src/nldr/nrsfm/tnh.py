"""Trace-norm heuristic (TNH) for NRSfM with known cameras: the paper's linear baseline (eq. 12).

Penalised form, for tau > 0::

    min_X  tau ||X||_*  +  sum_{f,j} Z_fj ||w_f(x_j) - R_f s_f(x_j)||^2

Exact-fit form, the limit tau -> 0 (noise-free data; Dai, Li & He 2012)::

    min_X  ||X||_*   subject to   R_f s_f(x_j) = w_f(x_j)  for every observed (f, j)

X is the (F, 3P) shape matrix (shapes as rows; its nuclear norm equals that of the paper's (3P, F)
matrix). The paper runs TNH with ground-truth cameras and tau = 1e-7 in the data's original units; at
that strength the penalised problem is the exact-fit problem in practice, and the exact-fit form is the
numerically sound way to solve it. Measured on pickup (every 10th frame): the penalised form with
tau = 1e-7 has an optimal value ~1e-5, below what SCS resolves; SCS at eps 1e-5 stopped early at an
exact fit of the wrong nuclear norm (e3D 0.55) and at eps 1e-7 did not finish in reasonable time. With
tau = 1e-4 ... 1e-3 the penalised form solves normally and gives the exact fit's e3D (0.0475) to 4
digits.

:func:`trace_norm_heuristic` is the one entry point; ``method`` picks the solver:

``"admm"`` (default)
    The exact-fit form (tau None or 0) by ADMM (:mod:`nldr.nrsfm.admm`): cost per iteration linear in
    F, so full-length sequences are fine; a certified duality gap.
``"fista"``
    The penalised form (tau > 0) by accelerated proximal gradient (:mod:`nldr.nrsfm.fista`).
``"cvxpy"``
    Either form as a semidefinite program through cvxpy (:mod:`nldr.nrsfm.cvxpy_tnh`; an optional
    dependency): the reference oracle for small problems. For a tau sweep, use
    :class:`~nldr.nrsfm.cvxpy_tnh.CvxpyTNH` directly, which compiles once.

Every method returns a :class:`~nldr.nrsfm.tnh_result.TNHResult`.
"""

from __future__ import annotations

import inspect

from .._validation import check_positive
from .admm import solve_admm
from .fista import solve_fista
from .reprojection import OrthographicReprojection
from .tnh_result import TNHResult, TNHSolveError

__all__ = ["METHODS", "TNHResult", "TNHSolveError", "trace_norm_heuristic"]

#: The solvers of :func:`trace_norm_heuristic` (``method`` is case-insensitive).
METHODS = ("admm", "fista", "cvxpy")

_CVXPY_OPTIONS = ("solver", "solver_options", "warm_start", "verbose")


def _keyword_options(backend) -> tuple[str, ...]:
    return tuple(
        name for name, p in inspect.signature(backend).parameters.items() if p.kind is p.KEYWORD_ONLY
    )


def trace_norm_heuristic(
    W2d, R, mask=None, *, tau: float | None = None, method: str = "admm", **options
) -> TNHResult:
    """Solve TNH with known cameras, exact-fit (``tau`` None or 0) or penalised (``tau > 0``).

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Image tracks as rows (row f = x of the P points, then y), length unit of the data. Entries of
        unobserved points are ignored (they may be NaN).
    R : array, shape (F, 2, 3)
        Known orthographic cameras.
    mask : bool array, shape (F, P), optional
        True where point j is observed in frame f (both coordinates). Default: all observed.
    tau : float >= 0 or None, default None
        Weight of ||X||_* against the sum of squared reprojection errors (the data's squared unit per
        unit of nuclear norm). None or 0 solves the exact-fit form.
    method : {"admm", "fista", "cvxpy"}, default "admm"
        The solver, case-insensitive (see the module docstring). ``"admm"`` solves the exact fit only,
        ``"fista"`` the penalised form only, ``"cvxpy"`` both.
    **options
        Options of the method's solver:

        - ``"admm"``: ``tol`` (default 1e-6), ``max_iter``, ``beta``, ``X0``, ``Y0``, ``relaxation``,
          ``adaptive``, ``verbose``; see :func:`~nldr.nrsfm.admm.solve_admm`. Warm start from a
          previous result ``res``: ``X0=res.x, Y0=res.dual, beta=res.options["final_beta"]``.
        - ``"fista"``: ``X0``, ``max_iter``, ``tol``; see :func:`~nldr.nrsfm.fista.solve_fista`.
        - ``"cvxpy"``: ``solver`` (a conic solver, default ``"SCS"``), ``solver_options``,
          ``warm_start``, ``verbose``; see :meth:`~nldr.nrsfm.cvxpy_tnh.CvxpyTNH.solve`.

    Returns
    -------
    TNHResult
        ``x`` the shapes (F, 3P) in the unit of the tracks, ``fun`` the objective, ``success``,
        ``status``, ``message``, ``nit``, ``wall_time`` and the fit (``nuclear_norm``,
        ``reprojection_error``, ``max_abs_residual``); ADMM adds its ``dual`` and ``duality_gap``.

    Raises
    ------
    ValueError
        For malformed inputs, an unknown method or option, a negative tau, ``method="admm"`` with
        tau > 0, ``method="fista"`` without tau > 0, or an infeasible exact fit (ADMM).
    ImportError
        ``method="cvxpy"`` without cvxpy installed (``pip install nldr[cvxpy]``).
    TNHSolveError
        ``method="cvxpy"``: the conic solver failed or did not reach an optimal status.

    Examples
    --------
    >>> exact = trace_norm_heuristic(W2d, R, mask)                    # doctest: +SKIP
    >>> penalised = trace_norm_heuristic(W2d, R, mask, tau=0.1, method="fista")  # doctest: +SKIP
    """
    name = method.lower() if isinstance(method, str) else method
    if name not in METHODS:
        raise ValueError(f"method must be one of {METHODS} (case-insensitive); got {method!r}")
    tau_value = 0.0 if tau is None else check_positive(tau, "tau", allow_zero=True)
    if name == "admm" and tau_value != 0.0:
        raise ValueError(
            f"method 'admm' solves the exact-fit form only (tau None or 0); got tau={tau_value:g}. "
            f"Use method='fista' (or 'cvxpy') for tau > 0"
        )
    if name == "fista" and tau_value == 0.0:
        raise ValueError(
            "method 'fista' solves the penalised form, tau > 0; use method='admm' for the exact fit"
        )
    allowed = {
        "admm": _keyword_options(solve_admm),
        "fista": tuple(o for o in _keyword_options(solve_fista) if o != "tau"),  # tau is our argument
        "cvxpy": _CVXPY_OPTIONS,
    }[name]
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise ValueError(f"unknown options for method {name!r}: {unknown}; allowed: {sorted(allowed)}")

    if name == "cvxpy":
        from .cvxpy_tnh import CvxpyTNH  # cvxpy is optional: imported only here

        return CvxpyTNH(W2d, R, mask).solve(tau, **options)
    term = OrthographicReprojection(W2d, R, mask)  # validates the tracks, cameras and mask
    if name == "admm":
        return solve_admm(term, **options)
    return solve_fista(term, tau=tau_value, **options)
