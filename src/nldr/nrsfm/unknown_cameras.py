"""NRSfM with unknown cameras (paper Section 4.3, Table 4): the TNH baseline, its tau search, and the
kernel regularizer alternating with the cameras (:func:`kernel_with_camera_refinement`).

The paper initialises the cameras by rigid factorisation, then alternates shapes and cameras, and
chooses the TNH weight tau per sequence "by golden section search and parabolic interpolation" on the
3D error (Brent's bounded minimiser). Two findings shape this module (docs/REPRODUCTION.md#table-4-tnh):

- The alternation must run to convergence. It is block-coordinate descent on the joint energy
  tau ||X||_* + reprojection error, and the number of outer iterations it needs grows roughly like
  1 / tau. Stopped early it leaves e3D two to four times the converged value. So the shape step is the
  proximal-gradient TNH (:func:`~nldr.nrsfm.fista.fista_tnh`, warm-started) rather than the
  semidefinite program, and convergence is judged over a window of outer iterations.
- Every tau starts from the rigid initialisation (a cold start). A continuation in tau (each tau
  from the previous solution) lands in a different, better basin on yoga than the paper's number.

Maintenance note (speed). Four things make an outer iteration cheap, none of which moves the
alternation's fixed point: the singular value thresholding goes through the small Gram matrix
(:mod:`~nldr.nrsfm.svt`); the shape step's FISTA tolerance follows the alternation's progress and its
momentum carries over from one outer iteration to the next (:func:`tnh_with_camera_refinement`); the
camera LM forms its normal equations from 3x3 summaries and stops a frame once its cost changes only
by rounding (:func:`~nldr.nrsfm.camera_refinement.refine_cameras`). The first implementation is kept as
:func:`nldr.reference.nrsfm.tnh_with_camera_refinement_reference` for tests and benchmarks
(benchmarks/bench_table4.py measures the difference).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from .._cv import say
from .._validation import check_count, check_positive
from ..regularizer import minimize_regularized
from ..result import SolverResult, status_from
from .camera_refinement import CameraShapeResult, refine_cameras_and_shapes
from .fista import fista_tnh
from .reprojection import (
    OrthographicReprojection,
    check_shapes,
    check_tracks,
    masked_residual,
    visibility_weights,
)
from .svt import soft_threshold_singular_values_gram

__all__ = ["TauSearchResult", "tnh_with_camera_refinement", "kernel_with_camera_refinement", "tune_tau"]


def tnh_with_camera_refinement(
    W2d,
    mask,
    R0,
    tau: float,
    *,
    max_outer: int = 20_000,
    tol: float = 1e-8,
    window: int = 10,
    shape_max_iter: int = 300,
    shape_tol: float = 1e-12,
    shape_tol_ratio: float = 1e-2,
    shape_tol_max: float = 1e-6,
    shape_momentum: bool = True,
    camera_max_iter: int = 50,
    callback: Callable[[int, np.ndarray, np.ndarray], None] | None = None,
    svt: Callable[[np.ndarray, float], tuple[np.ndarray, float]] = soft_threshold_singular_values_gram,
    X0=None,
) -> CameraShapeResult:
    """TNH with the cameras refined in alternation, from R0 to convergence of the joint energy.

    Outer iteration: the shapes minimise tau ||X||_* + reprojection error at the current cameras
    (:func:`~nldr.nrsfm.fista.fista_tnh`, warm-started from the previous shapes), then
    Levenberg-Marquardt refines every camera's quaternion with the shapes fixed
    (:func:`~nldr.nrsfm.camera_refinement.refine_cameras_and_shapes`). Stops when the joint energy
    fell by less than ``tol`` (relative) over the last ``window`` iterations.

    The shape step is solved only as accurately as the alternation needs: its FISTA tolerance (relative
    objective decrease per iteration) is ``shape_tol_ratio`` times the relative decrease of the joint
    energy in the previous outer iteration, clipped to [``shape_tol``, ``shape_tol_max``]
    (``shape_tol_max`` for the first two). While the alternation moves fast (relative decreases of
    1e-3 per outer iteration early on), a shape step to 1e-6 moves it as far as one to 1e-12; as it
    slows down the tolerance tightens with it (to 1e-11 when the default stopping test triggers). The
    fixed point is that of the fixed-tolerance alternation (``shape_tol_ratio=0``,
    ``shape_momentum=False``); the path is not, so a run stops at a slightly different point on its
    way there and at a slightly different global rotation (up to 1 degree on Table 4's sequences,
    which e3D and the camera error align away). Both stop equally far from the fixed point: against
    runs with tol = 1e-13, the two differ by 5e-5 in e3D at most (stretch, tau = 0.1) where the
    fixed-tolerance run is itself 7e-5 from the tighter one (tests/test_unknown_cameras_speed.py).

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Centred image tracks as rows.
    mask : bool array, shape (F, P) or None
        Visibility (None: all observed).
    R0 : array, shape (F, 2, 3)
        Initial cameras, e.g. :func:`~nldr.nrsfm.factorization.initialize_cameras`.
    tau : float > 0
        Trace-norm weight, in the unit of the tracks squared.
    max_outer : int, default 20000
    tol : float > 0, default 1e-8
    window : int, default 10
    shape_max_iter : int, default 300
        FISTA iterations per shape step.
    shape_tol : float > 0, default 1e-12
        FISTA's relative objective decrease tolerance near convergence (the floor of the adaptive
        tolerance).
    shape_tol_ratio : float >= 0, default 1e-2
        FISTA's tolerance relative to the last outer iteration's relative energy decrease; 0 keeps
        ``shape_tol`` throughout.
    shape_tol_max : float > 0, default 1e-6
        Ceiling of the adaptive tolerance.
    shape_momentum : bool, default True
        Start each shape step with the previous one's FISTA momentum (extrapolation weight and
        previous iterate) instead of a plain proximal step: the cameras, hence the shape problem,
        change little from one outer iteration to the next. The restart test still guards every
        step, so the joint energy never increases; at a fixed point the momentum vanishes.
    camera_max_iter : int, default 50
        LM iterations per camera step.
    callback : callable, optional
        ``callback(k, R_k, X_k)`` after every outer iteration.
    svt : callable, default :func:`~nldr.nrsfm.svt.soft_threshold_singular_values_gram`
        Singular value soft-thresholding of the shape step, ``svt(Y, t) -> (X, nuclear norm)``; the
        reference alternation (:mod:`nldr.reference.nrsfm`) passes the full-SVD
        :func:`~nldr.nrsfm.svt.soft_threshold_singular_values`.
    X0 : array, shape (F, 3P), optional
        Start of the first shape step (default zeros, the cold start Table 4's protocol uses); the
        camera search (:mod:`~nldr.nrsfm.camera_search`) passes the shapes it re-fitted.

    Returns
    -------
    CameraShapeResult
        Shapes ``x``, cameras ``R``, histories (``energy_history`` is the joint energy, ``fun`` its
        last value), ``nit`` outer iterations, ``success``.
    """
    tau = check_positive(tau, "tau")
    shape_tol = check_positive(shape_tol, "shape_tol")
    shape_tol_ratio = check_positive(shape_tol_ratio, "shape_tol_ratio", allow_zero=True)
    shape_tol_max = max(check_positive(shape_tol_max, "shape_tol_max"), shape_tol)
    shape_max_iter = check_count(shape_max_iter, "shape_max_iter")
    if not callable(svt):
        raise ValueError(f"svt must be a callable (Y, t) -> (X, nuclear norm); got {type(svt).__name__}")
    W, vis = check_tracks(W2d, mask)
    F, P = vis.shape
    W3 = W.reshape(F, 2, P)
    m3 = visibility_weights(vis)
    # The latest shapes (F, 3, P) and their nuclear norm (warm start and penalty), the number of shape
    # steps so far and the joint energy after the previous camera step (for the shape step's tolerance).
    state = {"X": np.zeros((F, 3, P)), "nuclear": 0.0, "k": 0, "energy": None, "momentum": None}
    if X0 is not None:
        X0 = check_shapes(X0, F, P, name="X0")
        state["X"] = X0.reshape(F, 3, P).copy()
        state["nuclear"] = float(np.linalg.svd(X0, compute_uv=False).sum())

    def shape_step(R):
        X = state["X"]
        state["k"] += 1
        inner_tol = shape_tol_max if shape_tol_ratio > 0 else shape_tol
        if shape_tol_ratio > 0 and state["k"] > 1:
            # the joint energy after outer iteration k - 1 (its shapes, and the cameras R it produced)
            E = masked_residual(W3, m3, R, X)
            energy = tau * state["nuclear"] + float(np.vdot(E, E))
            if state["energy"] is not None:
                decrease = (state["energy"] - energy) / max(energy, 1e-300)
                inner_tol = min(shape_tol_max, max(shape_tol, shape_tol_ratio * decrease))
            state["energy"] = energy
        momentum = state["momentum"] if shape_momentum else None
        out = fista_tnh(W3, m3, R, X, state["nuclear"], tau, shape_max_iter, inner_tol, svt, momentum)
        state["X"], state["nuclear"], state["momentum"] = out.x, out.nuclear_norm, out.momentum
        return out.x.reshape(F, 3 * P)

    def penalty(X):
        return tau * state["nuclear"]  # X is the latest shape step's

    return refine_cameras_and_shapes(
        W2d,
        mask,
        R0,
        shape_step,
        max_outer=max_outer,
        tol=tol,
        window=window,
        camera_max_iter=camera_max_iter,
        penalty=penalty,
        callback=callback,
    )


@dataclass(kw_only=True, repr=False)
class TauSearchResult(SolverResult):
    """Result of :func:`tune_tau` (a :class:`~nldr.result.SolverResult`).

    Attributes
    ----------
    x : float
        The best tau evaluated (lowest objective); also available as ``tau``.
    fun : float
        Its objective value.
    status, message, wall_time
        As in :class:`~nldr.result.SolverResult`; CONVERGED when Brent's method met ``xatol``.
    nit : int
        Iterations of Brent's method.
    nfev : int
        Objective evaluations (``len(history)``).
    history : list of (tau, value)
        Every evaluation, in order.
    """

    nfev: int
    history: list

    @property
    def tau(self) -> float:
        """The best tau evaluated, same as ``x``."""
        return self.x


def kernel_with_camera_refinement(
    W2d, mask, R_start, X_start, *, gamma, tau, max_outer=20, tol=1e-4, camera_atol_deg=None, **options
):
    """The kernel regularizer alternating with the camera LM (the paper's kernel NRSfM with unknown
    cameras, Table 4's kernel stage), from the cameras ``R_start`` and shapes ``X_start`` (a TNH's).

    Each shape step runs :func:`~nldr.regularizer.minimize_regularized` (RBF width ``gamma``, weight
    ``tau``, further ``options`` such as the rho schedule) from the previous shapes, with the data
    term of the current cameras; :func:`~nldr.nrsfm.refine_cameras_and_shapes` stops when the
    reprojection error falls by less than ``tol`` (relative) over 3 outer iterations, when a camera
    step moved the cameras by less than ``camera_atol_deg`` degrees on average (None: no such test;
    the next shape step would re-solve the problem it just solved), or after ``max_outer``.

    Why the cameras barely move (issue 17): at the paper's tau = 1e-4 the kernel shape step fits the
    observed tracks almost exactly at any cameras, so the camera LM, which sees only the reprojection
    error, has next to nothing to decrease; the regularizer's pull on the cameras never reaches them
    in this block-coordinate scheme (measured: about 1e-4 degree per camera step on Table 4's
    sequences). :func:`~nldr.nrsfm.joint_kernel.kernel_joint_cameras_shapes` moves cameras and depths
    together and reaches a lower energy (Table 4's default since issue 17, config
    ``table4.kernel_cameras``); this alternation is kept as ``kernel_cameras: alternate``. Returns its
    :class:`~nldr.nrsfm.CameraShapeResult` (shapes ``x``, cameras ``R``).
    """
    state = {"X": X_start}

    def kernel_shape_step(R):
        res = minimize_regularized(
            OrthographicReprojection(W2d, R, mask), state["X"], gamma=gamma, tau=tau, **options
        )
        state["X"] = res.x
        return res.x

    return refine_cameras_and_shapes(
        W2d,
        mask,
        R_start,
        kernel_shape_step,
        max_outer=max_outer,
        tol=tol,
        window=3,
        camera_atol_deg=camera_atol_deg,
    )


def tune_tau(
    objective: Callable[[float], float],
    *,
    log10_bounds: tuple[float, float] = (-1.0, 2.0),
    xatol: float = 0.02,
    verbose: bool = False,
) -> TauSearchResult:
    """Minimise ``objective(tau)`` over log10(tau) in ``log10_bounds`` by Brent's bounded method.

    Golden-section search with parabolic interpolation (``scipy.optimize.minimize_scalar`` with
    ``method="bounded"``, the algorithm of MATLAB's ``fminbound``), as the paper describes for the
    TNH baseline of Table 4. The objective is typically the 3D error against ground truth, so the
    tuned baseline is an oracle: say so wherever its numbers are shown.

    Parameters
    ----------
    objective : callable
        ``objective(tau) -> float`` for tau > 0.
    log10_bounds : (float, float), default (-1, 2)
        Search interval of log10(tau).
    xatol : float > 0, default 0.02
        Absolute tolerance on log10(tau).
    verbose : bool, default False
        Print a line per evaluation (tau, objective, seconds so far) to stdout: one evaluation of
        Table 4's objective is a full camera/shape alternation, about 5-15 s.

    Returns
    -------
    TauSearchResult
    """
    start = time.perf_counter()
    lo, hi = (float(b) for b in log10_bounds)
    if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
        raise ValueError(f"log10_bounds must be two finite numbers, low < high; got {log10_bounds!r}")
    xatol = check_positive(xatol, "xatol")
    if not callable(objective):
        raise ValueError(f"objective must be a callable tau -> float; got {type(objective).__name__}")
    history: list[tuple[float, float]] = []

    def f(log_tau):
        tau = float(10.0**log_tau)
        value = float(objective(tau))
        if not np.isfinite(value):
            raise ValueError(f"objective({tau:g}) returned {value!r}; it must be finite")
        history.append((tau, value))
        elapsed = time.perf_counter() - start
        line = f"evaluation {len(history)}: tau={tau:.5g} objective={value:.5g} ({elapsed:.1f} s)"
        say(verbose, "tune_tau", line)
        return value

    res = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": xatol})
    best_tau, best_value = min(history, key=lambda tv: tv[1])
    return TauSearchResult(
        x=best_tau,
        fun=best_value,
        status=status_from(bool(res.success)),
        message=str(res.message),
        nit=int(res.nit),
        wall_time=time.perf_counter() - start,
        nfev=len(history),
        history=history,
    )
