"""NRSfM with unknown cameras (paper Section 4.3, Table 4): the TNH baseline and its tau search.

The paper initialises the cameras by rigid factorisation, then alternates shapes and cameras, and
chooses the TNH weight tau per sequence "by golden section search and parabolic interpolation" on the
3D error (Brent's bounded minimiser). Two findings shape this module (docs/REPRODUCTION.md#table-4-tnh):

- The alternation must run to convergence. It is block-coordinate descent on the joint energy
  tau ||X||_* + reprojection error, and the number of outer iterations it needs grows roughly like
  130 / tau (pickup, every 10th frame: about 1350 at tau = 0.1). Stopped after 20-60 iterations it
  leaves e3D two to four times the converged value. So the shape step is the proximal-gradient TNH
  (:func:`~nldr.nrsfm.proximal.tnh_proximal`, milliseconds per warm-started solve) rather than the
  semidefinite program, and convergence is judged over a window of outer iterations.
- Every tau starts from the rigid initialisation (a cold start). A continuation in tau (each tau
  from the previous solution) lands in a different, better basin on yoga than the paper's number.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from .._validation import check_positive
from .cameras import CameraShapeResult, refine_cameras_and_shapes
from .proximal import tnh_proximal

__all__ = ["TauSearchResult", "tnh_with_camera_refinement", "tune_tau"]


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
    camera_max_iter: int = 50,
    callback: Callable[[int, np.ndarray, np.ndarray], None] | None = None,
) -> CameraShapeResult:
    """TNH with the cameras refined in alternation, from R0 to convergence of the joint energy.

    Outer iteration: the shapes minimise tau ||X||_* + reprojection error at the current cameras
    (FISTA, warm-started from the previous shapes), then Levenberg-Marquardt refines every camera's
    quaternion with the shapes fixed (:func:`~nldr.nrsfm.cameras.refine_cameras_and_shapes`). Stops
    when the joint energy fell by less than ``tol`` (relative) over the last ``window`` iterations.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Centred image tracks as rows.
    mask : bool array, shape (F, P) or None
        Visibility (None: all observed).
    R0 : array, shape (F, 2, 3)
        Initial cameras, e.g. :func:`~nldr.nrsfm.cameras.initialize_cameras`.
    tau : float > 0
        Trace-norm weight, in the unit of the tracks squared.
    max_outer : int, default 20000
    tol : float > 0, default 1e-8
    window : int, default 10
    shape_max_iter : int, default 300
        FISTA iterations per shape step.
    shape_tol : float, default 1e-12
        FISTA's relative objective decrease tolerance.
    camera_max_iter : int, default 50
        LM iterations per camera step.
    callback : callable, optional
        ``callback(k, R_k, X_k)`` after every outer iteration.

    Returns
    -------
    CameraShapeResult
        Cameras, shapes, histories (``energy_history`` is the joint energy), ``converged``.
    """
    tau = check_positive(tau, "tau")
    last = {}  # the latest shape step's result: warm start, and its nuclear norm for the penalty

    def shape_step(R):
        last["res"] = tnh_proximal(
            W2d, R, mask, tau=tau, X0=last["res"].X if last else None, max_iter=shape_max_iter, tol=shape_tol
        )
        return last["res"].X

    def penalty(X):
        return tau * last["res"].nuclear_norm  # X is that result's X

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


@dataclass
class TauSearchResult:
    """Result of :func:`tune_tau`.

    Attributes
    ----------
    tau : float
        The best tau evaluated (lowest objective).
    value : float
        Its objective value.
    history : list of (tau, value)
        Every evaluation, in order.
    n_eval : int
    message : str
    """

    tau: float
    value: float
    history: list
    n_eval: int
    message: str


def tune_tau(
    objective: Callable[[float], float],
    *,
    log10_bounds: tuple[float, float] = (-1.0, 2.0),
    xatol: float = 0.02,
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

    Returns
    -------
    TauSearchResult
    """
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
        return value

    res = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": xatol})
    best_tau, best_value = min(history, key=lambda tv: tv[1])
    return TauSearchResult(
        tau=best_tau, value=best_value, history=history, n_eval=len(history), message=str(res.message)
    )
