"""One entry point for NRSfM reconstruction: :func:`reconstruct`, returning a :class:`Reconstruction`.

``cameras`` is the known cameras R (F, 2, 3) (Table 3) or ``"estimate"`` (Table 4: rigid factorisation,
:func:`~nldr.nrsfm.initialize_cameras`, then cameras refined with the shapes). ``prior`` is the
trace-norm heuristic (``"tnh"``, the paper's linear baseline) or the kernel regularizer (``"kernel"``,
the paper's method, started from a TNH reconstruction). ``loss="huber"`` is the Huber loss (threshold
``delta``) for the kernel method and, for TNH with known cameras, the l1 loss, its delta -> 0 limit
(:mod:`nldr.nrsfm._admm`), which is then the Huber kernel method's default start. What runs:

- TNH, known cameras: :func:`trace_norm_heuristic` or
  :func:`~nldr.nrsfm._admm.robust_trace_norm_heuristic`;
- TNH, estimated cameras: :func:`~nldr.nrsfm._camera_refinement.tnh_with_camera_refinement` from the
  rigid cameras, optionally followed by :func:`~nldr.nrsfm._basin_search.tnh_basin_search` (more
  starts, each with the camera search);
- kernel, known cameras: :func:`~nldr.regularizer.minimize_regularized` on the reprojection term;
- kernel, estimated cameras: cameras and shapes jointly in every penalty stage, from several starts
  (:func:`~nldr.nrsfm._joint_kernel.joint_kernel_multistart`).

The kernel method's width is a rule of the paper (``"d_max"``, ``"d_med"``) on the start's shapes, or a
gamma.
"""

from __future__ import annotations

import inspect
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .._options import solver_options
from .._validation import check_flag, check_positive
from ..data_terms import Huber
from ..kernels import d_max_width, d_med_width
from ..regularizer import minimize_regularized
from ..result import SolverResult
from ._admm import robust_trace_norm_heuristic, solve_admm
from ._basin_search import tnh_basin_search
from ._camera_refinement import tnh_with_camera_refinement
from ._factorization import initialize_cameras
from ._joint_kernel import joint_kernel_multistart, solve_joint_kernel
from ._reprojection import OrthographicReprojection, check_cameras, check_tracks, reprojection_error
from ._rotations import CameraFrameVariables
from ._tnh import TNHResult

__all__ = [
    "WIDTH_RULES",
    "PRIORS",
    "LOSSES",
    "METHODS",
    "Reconstruction",
    "reconstruct",
    "trace_norm_heuristic",
]

#: The paper's kernel-width rules: name -> gamma of the RBF kernel from shapes as rows.
WIDTH_RULES = {"d_max": d_max_width, "d_med": d_med_width}
PRIORS = ("tnh", "kernel")
LOSSES = ("squared", "huber")
#: The kernel method's trace-norm weight (the paper's, all NRSfM tables).
KERNEL_TAU = 1e-4
#: The solvers of :func:`trace_norm_heuristic` (``method`` is case-insensitive).
METHODS = ("admm", "cvxpy")
_CVXPY_OPTIONS = ("solver", "solver_options", "warm_start", "verbose")


def trace_norm_heuristic(
    W2d, visible, R, *, tau: float | None = None, method: str = "admm", **options
) -> TNHResult:
    """Solve TNH with known cameras (:mod:`nldr.nrsfm._tnh`), exact-fit (``tau`` None or 0) or penalised.

    The paper's tau = 1e-7 (units of the data) makes the penalised problem the exact-fit one in practice,
    and the exact fit is the numerically sound way to solve it (docs/REPRODUCTION.md#table-3-tnh).

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Image tracks as rows (row f = x of the P points, then y), length unit of the data. Entries of
        unobserved points are ignored (they may be NaN).
    visible : bool array, shape (F, P), or None
        True where point j is observed in frame f (both coordinates); None: all observed.
    R : array, shape (F, 2, 3)
        Known orthographic cameras.
    tau : float >= 0 or None, default None
        Weight of ||X||_* against the sum of squared reprojection errors (unit of the tracks squared).
    method : {"admm", "cvxpy"}, default "admm"
        Case-insensitive. ``"admm"``: the exact fit only (:func:`~nldr.nrsfm._admm.solve_admm`, a certified
        duality gap); ``"cvxpy"``: either form as a semidefinite program, the small-problem reference (an
        optional dependency; :class:`~nldr.nrsfm._cvxpy_tnh.CvxpyTNH` compiles once for a tau sweep).
    **options
        The solver's: ``"admm"``: those of :func:`~nldr.nrsfm._admm.solve_admm` (``tol`` 1e-6, ``max_iter``,
        warm starts, ...); ``"cvxpy"``: ``solver`` (default ``"SCS"``), ``solver_options``,
        ``warm_start``, ``verbose``.

    Returns
    -------
    TNHResult
        ``x`` the shapes (F, 3P) in the unit of the tracks, ``fun`` the objective and the fit.

    Raises
    ------
    ValueError
        For malformed inputs, an unknown method or option, a negative tau, ``method="admm"`` with
        tau > 0, or an infeasible exact fit (ADMM).
    ImportError, TNHSolveError
        ``method="cvxpy"`` without cvxpy (``pip install nldr[cvxpy]``), or its conic solver failed.
    """
    name = method.lower() if isinstance(method, str) else method
    if name not in METHODS:
        raise ValueError(f"method must be one of {METHODS} (case-insensitive); got {method!r}")
    tau_value = 0.0 if tau is None else check_positive(tau, "tau", allow_zero=True)
    if name == "admm" and tau_value != 0.0:
        raise ValueError(
            f"method 'admm' solves the exact-fit form only (tau None or 0); got tau={tau_value:g}. "
            f"Use method='cvxpy' for tau > 0"
        )
    allowed = _CVXPY_OPTIONS if name == "cvxpy" else tuple(
        n for n, p in inspect.signature(solve_admm).parameters.items() if p.kind is p.KEYWORD_ONLY
    )  # fmt: skip
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise ValueError(f"unknown options for method {name!r}: {unknown}; allowed: {sorted(allowed)}")
    if name == "cvxpy":
        from ._cvxpy_tnh import CvxpyTNH  # cvxpy is optional: imported only here

        return CvxpyTNH(W2d, visible, R).solve(tau, **options)
    return solve_admm(OrthographicReprojection(W2d, visible, R), **options)  # the term validates the inputs


@dataclass(kw_only=True, repr=False)
class Reconstruction(SolverResult):
    """Result of :func:`reconstruct` (a :class:`~nldr.result.SolverResult`).

    Attributes
    ----------
    x, R : arrays (F, 3P) and (F, 2, 3)
        Shapes as rows (unit of the tracks; with estimated cameras up to the global gauge) and cameras.
    fun : float
        The prior's energy at the end: TNH's objective; the kernel method's energy (1) at its last rho.
    status, message, nit, wall_time
        Those of the solver that ran (``solver``, with its histories); ``wall_time`` excludes the start's.
    prior, loss, tau, gamma, delta
        As run (tau 0.0 for TNH's exact fit, gamma NaN for TNH, delta None for the squared loss).
    reprojection : float
        Sum of squared reprojection errors over the observed points.
    start : Reconstruction or None
        The TNH reconstruction the kernel method started from.
    other_widths : dict
        Estimated cameras with the multistart: label -> :class:`Reconstruction` at the other width rules
        it solved along the way (the same call at those widths gives them).
    """

    R: np.ndarray
    prior: str
    loss: str
    tau: float
    gamma: float
    delta: float | None
    reprojection: float
    start: Reconstruction | None = None
    solver: SolverResult | None = None
    other_widths: dict = field(default_factory=dict)


def reconstruct(
    W2d,
    visible=None,
    *,
    cameras="estimate",
    prior: str = "tnh",
    loss: str = "squared",
    tau: float | None = None,
    width="d_med",
    delta: float | None = None,
    start=None,
    tnh: Mapping | None = None,
    **options,
) -> Reconstruction:
    """Reconstruct shapes (and cameras) from orthographic image tracks.

    Parameters
    ----------
    W2d : array (F, 2P)
        Centred image tracks as rows (row f = x of the P points, then y). Unobserved entries are
        ignored (they may be NaN).
    visible : bool array (F, P), optional
        True where point j is observed in frame f. Default: all observed.
    cameras : "estimate" or array (F, 2, 3), default "estimate"
        Known orthographic cameras, or estimate them (see the module docstring).
    prior : {"tnh", "kernel"}, default "tnh"
    loss : {"squared", "huber"}, default "squared"
        "huber": the kernel method with the Huber loss (needs ``delta``); TNH with the l1 loss (robust
        TNH, known cameras only).
    tau : float, optional
        Trace-norm weight, unit of the tracks squared (robust TNH: dimensionless, required). TNH with
        known cameras: None or 0 is the exact fit; with estimated cameras it is required. Kernel:
        default 1e-4 (the paper's).
    width : "d_max", "d_med" or float, default "d_med"
        The kernel method's width rule (on the start's shapes) or gamma.
    delta : float > 0, optional
        The kernel method's Huber threshold, unit of the tracks.
    start : Reconstruction, optional
        The kernel method's start (a TNH reconstruction; with estimated cameras its cameras too);
        default: ``reconstruct(W2d, visible, cameras=cameras, prior="tnh", loss=loss, **tnh)``.
    tnh : mapping, optional
        Options of the default start (e.g. ``tau`` with estimated cameras).
    **options
        Solver options. TNH, known cameras: :func:`trace_norm_heuristic`'s (``method``,
        ``tol``, ...) or the robust TNH's. TNH, estimated cameras: ``max_outer``, ``tol``, ``window``
        of the alternation, ``initial_cameras`` (default: the rigid factorisation) and
        ``camera_search`` (bool, default False, or a mapping of the options of
        :func:`~nldr.nrsfm._basin_search.tnh_basin_search` such as ``starts`` and ``max_rounds``).
        Kernel, known cameras: :func:`~nldr.regularizer.minimize_regularized`'s, flat (its ``options``
        beside its arguments, e.g. ``rho0`` and ``tol``) or as it takes them, and ``depth_scale``
        (L-BFGS in :class:`~nldr.nrsfm.CameraFrameVariables`). Kernel, estimated cameras:
        :func:`~nldr.nrsfm._joint_kernel.solve_joint_kernel`'s (the schedule ``rho0``, ``rho_growth``,
        ``rho_max``, tolerances) and ``multistart`` (bool, default True).

    Returns
    -------
    Reconstruction

    Warns
    -----
    UserWarning
        If, in some frame, the observed points' centroid lies farther from the origin than their RMS
        spread (plus what a random subset of centred points strays by chance): the cameras have no
        translation, so tracks off centre give wrong shapes.

    Raises
    ------
    ValueError
        If an argument is out of range or an option does not belong to the solver that runs (the
        kernel method checks its width and options before its default start is solved).
    """
    W, vis = check_tracks(W2d, visible)
    F = vis.shape[0]
    if prior != "kernel" or start is not None:  # the kernel method's default start checks them
        _warn_if_not_centred(W, vis)
    known = not isinstance(cameras, str)
    if not known and cameras != "estimate":
        raise ValueError(f"cameras must be 'estimate' or an array (F, 2, 3); got {cameras!r}")
    R = check_cameras(cameras, F, name="cameras") if known else None
    if prior not in PRIORS:
        raise ValueError(f"prior must be one of {PRIORS}; got {prior!r}")
    if loss not in LOSSES:
        raise ValueError(f"loss must be one of {LOSSES}; got {loss!r}")
    if loss == "huber" and prior == "kernel":
        if delta is None:
            raise ValueError("loss='huber' needs delta (the Huber threshold, unit of the tracks)")
        delta = check_positive(delta, "delta")
    elif delta is not None:
        raise ValueError("delta is the kernel method's Huber threshold; pass prior='kernel', loss='huber'")
    begin = time.perf_counter()
    common = dict(prior=prior, loss=loss, delta=delta)
    if prior == "tnh":
        if start is not None or tnh is not None:
            raise ValueError("start and tnh are the kernel method's start; TNH takes its options directly")
        if known and loss == "huber":  # the robust TNH: l1, the Huber loss's delta -> 0 limit
            res = robust_trace_norm_heuristic(W2d, vis, R, tau=check_positive(tau, "tau"), **options)
            return _result(res, W, vis, R, tau=res.tau, gamma=np.nan, **common)
        if known:
            res = trace_norm_heuristic(W2d, vis, R, tau=tau, **options)
            return _result(res, W, vis, R, tau=res.tau, gamma=np.nan, **common)
        if loss == "huber":
            raise ValueError("the robust TNH (loss='huber') needs known cameras: pass cameras=R")
        if tau is None:
            raise ValueError(
                "tau is required with estimated cameras (prior='tnh'): pass tau > 0 (unit of the tracks "
                "squared), e.g. chosen from the tracks by nldr.nrsfm.select_tnh_tau"
            )
        tau = check_positive(tau, "tau")
        search = options.pop("camera_search", False)
        if not isinstance(search, Mapping):
            search = check_flag(search, "camera_search (or a mapping of its options)")
        R0 = options.pop("initial_cameras", None)
        unknown = sorted(set(options) - {"max_outer", "tol", "window"})
        if unknown:
            raise ValueError(f"unknown options for TNH with estimated cameras: {unknown}")
        R0 = initialize_cameras(W, vis) if R0 is None else check_cameras(R0, F, name="initial_cameras")
        res = tnh_with_camera_refinement(W, vis, R0, tau, **options)
        if search:
            alternation = {k: v for k, v in options.items() if k in ("max_outer", "tol")}
            search = dict(search if isinstance(search, Mapping) else {})
            res = tnh_basin_search(W, vis, R0, tau, rigid=res, **search, **alternation)
        return _result(res, W, vis, res.R, tau=tau, gamma=np.nan, wall=time.perf_counter() - begin, **common)

    tau = KERNEL_TAU if tau is None else check_positive(tau, "tau")
    _check_kernel_options(options, known, width)  # before the default start is solved
    if start is None:
        start = reconstruct(W2d, vis, cameras=cameras, prior="tnh", loss=loss, **dict(tnh or {}))
        begin = time.perf_counter()
    elif tnh is not None:
        raise ValueError("give start or tnh (the options of the default start), not both")
    X0 = np.asarray(start.x, dtype=np.float64)
    gamma = _gamma(width, X0)
    options = _flat(options)
    if known:
        depth_scale = options.pop("depth_scale", None)
        variables = None if depth_scale is None else CameraFrameVariables(R, vis, depth_scale)
        term = OrthographicReprojection(W, vis, R)
        res = minimize_regularized(
            term if delta is None else Huber(term, delta), X0, gamma=gamma, tau=tau, variables=variables,
            **solver_arguments(options),
        )  # fmt: skip
        return _result(res, W, vis, R, tau=tau, gamma=gamma, start=start, **common)
    multistart = check_flag(options.pop("multistart", True), "multistart")
    label = width if isinstance(width, str) else "gamma"
    gammas = {label: gamma}
    if multistart:  # the paper's width rules are the other starts' source
        gammas.update({rule: fn(X0) for rule, fn in WIDTH_RULES.items() if rule != label})
    solved = joint_kernel_multistart(
        W, vis, start.R, X0, gammas, tau=tau, multistart=multistart, delta=delta, **options
    )
    wall = time.perf_counter() - begin
    out = {}
    for name, (res, energy) in solved.items():
        res.fun = energy
        out[name] = _result(res, W, vis, res.R, tau=tau, gamma=gammas[name], start=start, wall=wall, **common)
    main = out.pop(label)
    main.other_widths = out
    return main


#: How many standard errors of a random subset's centroid the observed centroid may stray beyond the
#: observed points' RMS spread before the tracks are called off centre.
_CENTRE_STANDARD_ERRORS = 3.0


def _warn_if_not_centred(W: np.ndarray, vis: np.ndarray) -> None:
    """Warn when, in some frame, the observed points' centroid lies far from the origin.

    The tracks should be centred per frame on all P points; with m < P points observed, the observed
    centroid strays from 0 by chance. Maintenance note: for m of P centred points drawn at random,
    E ||centroid||^2 = r^2 (P - m) / (m (P - 1)), r^2 the points' mean squared distance from their
    centroid (the finite-population variance of a sample mean). A frame is off centre when its
    observed centroid lies farther from the origin than r (1 + k se), se = sqrt((P - m) / (m (P - 1)))
    and k = :data:`_CENTRE_STANDARD_ERRORS`, with r estimated by the observed points: complete
    frames need a centroid within their RMS spread, frames with missing points more, as chance
    allows. W (F, 2P) with zeros where unobserved, vis (F, P).
    """
    F, P = vis.shape
    m = vis.sum(axis=1)
    points = W.reshape(F, 2, P)
    centroid = points.sum(axis=2) / m[:, None]  # unobserved entries are zero
    spread = np.where(vis[:, None, :], points - centroid[:, :, None], 0.0)
    rms = np.sqrt(np.einsum("fcp,fcp->f", spread, spread) / m)
    se = np.sqrt((P - m) / (m * max(P - 1, 1)))
    distance = np.linalg.norm(centroid, axis=1)
    off = np.flatnonzero(distance > rms * (1.0 + _CENTRE_STANDARD_ERRORS * se))
    if off.size:
        warnings.warn(
            f"W2d looks not centred: in frame(s) {off[:10].tolist()}{' ...' if off.size > 10 else ''} "
            "the observed points' centroid lies farther from the origin than their spread allows "
            "(orthographic cameras have no translation, so the shapes would be wrong). Subtract each "
            "frame's centroid from its x and y rows first (nldr.nrsfm.center_per_frame does this for "
            "shapes as rows)",
            UserWarning,
            stacklevel=3,
        )


#: :func:`~nldr.regularizer.minimize_regularized`'s own arguments; every other option goes in its ``options``.
_SOLVER_ARGUMENTS = ("method", "center", "rho0", "rho_growth", "rho_max", "callback", "verbose", "variables")


def solver_arguments(options: Mapping) -> dict:
    """Flat kernel-method options (``rho0``, ``tol``, ``max_inner``, ...) as the keyword arguments of
    :func:`~nldr.regularizer.minimize_regularized`: its own arguments, the rest in ``options``."""
    flat = _flat(options)
    out = {k: flat.pop(k) for k in _SOLVER_ARGUMENTS if k in flat}
    return {**out, "options": flat} if flat else out


def _flat(options: Mapping) -> dict:
    """The options with a nested ``options`` mapping (the solver's own form) merged in."""
    flat = {k: v for k, v in options.items() if k != "options"}
    return {**flat, **dict(options.get("options") or {})}


def _check_kernel_options(options: Mapping, known: bool, width) -> None:
    """Refuse a width or an option the kernel method's solver does not take, as its solve would."""
    if isinstance(width, str) and width not in WIDTH_RULES:
        _gamma(width, None)
    elif not isinstance(width, str):
        check_positive(width, "width (a gamma)")
    flat = _flat(options)
    if known:
        arguments = solver_arguments({k: v for k, v in flat.items() if k != "depth_scale"})
        solver_options(arguments.get("method", "exact"), arguments.get("options"))
        return
    check_flag(flat.get("multistart", True), "multistart")
    parameters = inspect.signature(solve_joint_kernel).parameters.items()
    allowed = {name for name, p in parameters if p.kind is p.KEYWORD_ONLY} - {"gamma", "tau", "delta"}
    allowed |= {"multistart"}
    unknown = sorted(set(flat) - allowed)
    if unknown:
        raise ValueError(
            f"unknown options for the kernel method with estimated cameras: {unknown}; "
            f"allowed: {sorted(allowed)}"
        )


def _gamma(width, X0) -> float:
    if isinstance(width, str):
        if width not in WIDTH_RULES:
            raise ValueError(f"width must be one of {tuple(WIDTH_RULES)} or a gamma > 0; got {width!r}")
        return float(WIDTH_RULES[width](X0))
    return check_positive(width, "width (a gamma)")


def _result(res, W, vis, R, *, wall=None, **fields) -> Reconstruction:
    return Reconstruction(
        x=res.x, fun=float(res.fun), status=res.status, message=res.message, nit=res.nit, R=R, solver=res,
        wall_time=res.wall_time if wall is None else wall, reprojection=reprojection_error(W, vis, R, res.x),
        **fields,
    )  # fmt: skip
