"""Camera refinement for NRSfM with unknown cameras: camera LM and the shape/camera alternation.

After the rigid initialisation (:mod:`nldr.nrsfm.factorization`) the paper alternates between the 3D
shapes and the cameras, "parameterising each R_i with quaternions ... using LM" (Section 4.3):

- :func:`refine_cameras`: Levenberg-Marquardt on the per-frame quaternions with the shapes fixed,
  vectorised over frames (given the shapes, the frames are independent 4-parameter problems);
- :func:`refine_cameras_and_shapes`: alternation of a shape step (any callable R -> X, e.g. TNH, see
  :func:`~nldr.nrsfm.unknown_cameras.tnh_with_camera_refinement`) with the camera LM;
  :func:`rigid_shape_step` is the rigid shape step (a rigid bundle adjustment);
- :func:`reprojection_error`: the quantity both steps decrease.

Layouts as in :mod:`nldr.nrsfm.layout`: image tracks W2d (F, 2P), shapes X (F, 3P), cameras R (F, 2, 3),
visibility masks (F, P); the tracks are assumed centred (orthographic model w = R s without
translation).

Gauge. With unknown cameras, (R_f Q, Q^T S_f) reproduces the tracks for any orthogonal Q, det -1
included (the reflected cameras R_f Q still have orthonormal rows, and the images are unchanged).
Estimated cameras and shapes are therefore compared with the ground truth after ONE global
orthogonal alignment per sequence (:func:`~nldr.nrsfm.metrics.e3d` with ``align=True`` and
:func:`~nldr.nrsfm.metrics.camera_error`); the benchmark's ``compareStructs.m`` does the same (see
:mod:`nldr.nrsfm.metrics`), and a per-frame alignment would hide camera errors.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .._validation import check_count, check_positive
from ..result import SolverResult, status_from
from .reprojection import (
    check_cameras,
    check_shapes,
    check_tracks,
    masked_residual,
    visibility_weights,
)
from .rotations import camera_to_quaternion, nearest_orthonormal_rows, quaternion_to_camera_batch

__all__ = [
    "CameraRefinementResult",
    "CameraShapeResult",
    "reprojection_error",
    "lm_normal_equations",
    "refine_cameras",
    "rigid_shape_step",
    "refine_cameras_and_shapes",
    "camera_movement_deg",
]


# --------------------------------------------------------------------------------------------------
# Camera LM (quaternions, shapes fixed)
# --------------------------------------------------------------------------------------------------


def _frame_costs(Wf3, mask, R, Sf):
    E = Wf3 - R @ Sf
    E *= mask[:, None, :]
    return np.einsum("fcp,fcp->f", E, E), E


def reprojection_error(W2d, mask, R, X) -> float:
    """Sum over observed points of ||w_f(x_j) - R_f s_f(x_j)||^2 (unit of the tracks, squared).

    Parameters
    ----------
    W2d : array, shape (F, 2P)
    mask : bool array, shape (F, P) or None (all observed)
    R : array, shape (F, 2, 3)
    X : array, shape (F, 3P)

    Returns
    -------
    float
    """
    W, mask = check_tracks(W2d, mask, min_points=0)
    F, P = mask.shape
    R = check_cameras(R, F)
    X = check_shapes(X, F, P)
    return float(_frame_costs(W.reshape(F, 2, P), mask, R, X.reshape(F, 3, P))[0].sum())


@dataclass(kw_only=True, repr=False)
class CameraRefinementResult(SolverResult):
    """Result of :func:`refine_cameras` (a :class:`~nldr.result.SolverResult`).

    Attributes
    ----------
    x : array, shape (F, 2, 3)
        Refined cameras (orthonormal rows); also available as ``R``.
    fun : float
        Final sum of squared reprojection errors over all frames (``cost_history[-1]``).
    status, message, wall_time
        As in :class:`~nldr.result.SolverResult`; CONVERGED when every frame met a tolerance before
        ``max_iter``.
    nit : int
        LM iterations (each: one batched 4x4 solve per active frame and one cost evaluation).
    q : array, shape (F, 4)
        Their unit quaternions (w >= 0).
    cost_history : array, shape (nit + 1,)
        Sum of squared reprojection errors over all frames, initially and after every LM iteration.
    frame_cost : array, shape (F,)
        Final per-frame sum of squared reprojection errors.
    """

    q: np.ndarray
    cost_history: np.ndarray
    frame_cost: np.ndarray

    @property
    def R(self) -> np.ndarray:
        """The refined cameras (F, 2, 3), same as ``x`` (named like :attr:`CameraShapeResult.R`)."""
        return self.x


def lm_normal_equations(J, C2, SE):
    """J^T J (n, 4, 4) and -J^T r (n, 4) of the per-frame camera LM from 3x3 and 3x2 summaries.

    With the residual r = mask o (W - R S) of a frame and D_i = dR/dq_i S (2 x P), the normal equations
    need J^T J = sum D_i . D_j and J^T r = -sum D_i . E over the observed entries (E the masked residual).
    With J_c (3 x 4) the camera Jacobian of image row c, C = S diag(mask) S^T (3 x 3, fixed while the
    shapes are) and S E^T (3 x 2): J^T J = sum_c J_c^T C J_c and -J^T r = sum_c J_c^T (S E^T)[:, c], which
    avoids the (2, P, 4) array D per frame. Stacking J_0 over J_1 (6 x 4), both are matrix products.

    Parameters
    ----------
    J : array, shape (n, 2, 3, 4)
        d R / d q.
    C2 : array, shape (n, 6, 6)
        Block diagonal diag(C, C).
    SE : array, shape (n, 3, 2)
        S E^T.
    """
    n = J.shape[0]
    Js = J.reshape(n, 6, 4)
    JtJ = Js.transpose(0, 2, 1) @ (C2 @ Js)
    g = (SE.transpose(0, 2, 1).reshape(n, 1, 6) @ Js)[:, 0]
    return JtJ, g


def _refine_cameras(Wf3, mask, q, Sf, max_iter, ftol, xtol):
    """Batched LM over frames; Wf3 (F, 2, P) zero where unobserved, Sf (F, 3, P). Returns q, history, ..."""
    F = q.shape[0]
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    R, J = quaternion_to_camera_batch(q, True)
    m3 = visibility_weights(mask)
    C = (Sf if m3 is None else Sf * m3) @ Sf.transpose(0, 2, 1)  # S diag(mask) S^T, (F, 3, 3)
    C2 = np.zeros((F, 6, 6))
    C2[:, :3, :3] = C2[:, 3:, 3:] = C
    cost, E = _frame_costs(Wf3, mask, R, Sf)
    SE = Sf @ E.transpose(0, 2, 1)  # S E^T, (F, 3, 2)
    scale = np.einsum("fcp,fcp->f", Wf3, Wf3) + 1e-300
    lam = np.full(F, 1e-3)
    active = np.ones(F, dtype=bool)
    history = [float(cost.sum())]
    n_iter = 0
    for n_iter in range(1, max_iter + 1):  # noqa: B007 (n_iter is reported)
        idx = np.flatnonzero(active)
        rows = slice(None) if idx.size == F else idx  # views while every frame is active
        qi, cost_i, lam_i, S_i = q[rows], cost[idx], lam[idx], Sf[rows]
        JtJ, g = lm_normal_equations(J[rows], C2[rows], SE[rows])  # g = -J^T r
        diag = JtJ.diagonal(axis1=1, axis2=2)
        # J q = 0 (scale invariance): penalising the radial component keeps the system regular and the
        # step tangent to the unit sphere. Marquardt damping lam (diag(J^T J) + 1e-12).
        A = JtJ + (qi[:, :, None] * qi[:, None, :]) * (diag.max(axis=1) + 1e-300)[:, None, None]
        A.reshape(-1, 16)[:, ::5] += lam_i[:, None] * (diag + 1e-12)
        step = np.linalg.solve(A, g[..., None])
        # decrease of the Gauss-Newton model ||r + J step||^2, relative
        predicted = (2 * g - (JtJ @ step)[..., 0]) * step[..., 0]
        predicted = predicted.sum(axis=1) / np.maximum(cost_i, 1e-300)
        step = step[..., 0]
        step_norm = np.sqrt(np.einsum("fi,fi->f", step, step))
        q_new = qi + step
        q_new /= np.sqrt(np.einsum("fi,fi->f", q_new, q_new))[:, None]
        R_new, J_new = quaternion_to_camera_batch(q_new, True)
        E_new = masked_residual(Wf3[rows], None if m3 is None else m3[rows], R_new, S_i)
        cost_new = np.einsum("fcp,fcp->f", E_new, E_new)
        better = cost_new < cost_i
        decrease = (cost_i - cost_new) / np.maximum(cost_i, 1e-300)
        acc = idx[better]
        q[acc], R[acc], J[acc], cost[acc] = q_new[better], R_new[better], J_new[better], cost_new[better]
        SE[acc] = S_i[better] @ E_new[better].transpose(0, 2, 1)
        lam[idx] = np.where(better, np.maximum(lam_i / 3, 1e-12), lam_i * 4)
        # converged: an accepted step gained <= ftol, or a rejected one lost <= ftol where the model
        # promised <= ftol (the change is rounding; MINPACK's test), or the step or the cost vanished
        done = np.where(better, decrease <= ftol, (-decrease <= ftol) & (predicted <= ftol))
        done |= (step_norm <= xtol) | (cost[idx] <= 1e-30 * scale[idx]) | (lam[idx] > 1e16)
        active[idx[done]] = False
        history.append(float(cost.sum()))
        if not active.any():
            break
    if active.any():
        msg = f"LM reached max_iter={max_iter} with {int(active.sum())} of {F} frames still improving"
    else:
        msg = "every frame met ftol or xtol"
    return q, R, np.asarray(history), cost, n_iter, not active.any(), msg


def refine_cameras(
    W2d, mask, R0, X, *, max_iter: int = 100, ftol: float = 1e-12, xtol: float = 1e-12
) -> CameraRefinementResult:
    """Levenberg-Marquardt on the per-frame quaternions, shapes fixed, analytic Jacobian.

    Minimises sum_f sum_j mask_fj ||w_f(x_j) - R(q_f) s_f(x_j)||^2 over q_1..q_F. Given the shapes
    the frames decouple, so LM runs on all frames at once with a damping factor per frame (one
    batched 4x4 solve per iteration; a frame stops when its step is accepted with a relative cost
    decrease <= ftol, when a step is rejected with a relative cost increase <= ftol although the
    Gauss-Newton model predicted a relative decrease <= ftol (the cost no longer changes beyond
    rounding, MINPACK's ftol test), or when its step is <= xtol). Steps are taken in q and renormalised;
    the radial direction, along which the cost is constant, is penalised in the normal equations.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Centred image tracks as rows.
    mask : bool array, shape (F, P) or None
        Visibility (None: all observed).
    R0 : array, shape (F, 2, 3)
        Initial cameras (projected to orthonormal rows first).
    X : array, shape (F, 3P)
        Shapes as rows, held fixed.
    max_iter : int, default 100
    ftol, xtol : float > 0, default 1e-12
        Relative cost decrease and step-length (in unit quaternion) tolerances.

    Returns
    -------
    CameraRefinementResult
    """
    start = time.perf_counter()
    W, mask = check_tracks(W2d, mask, min_points=0)
    F, P = mask.shape
    R0 = check_cameras(R0, F, name="R0")
    X = check_shapes(X, F, P)
    max_iter = check_count(max_iter, "max_iter")
    ftol, xtol = check_positive(ftol, "ftol"), check_positive(xtol, "xtol")
    q0 = camera_to_quaternion(R0)
    q, R, history, cost, n_iter, ok, msg = _refine_cameras(
        W.reshape(F, 2, P), mask, q0, X.reshape(F, 3, P), max_iter, ftol, xtol
    )
    return CameraRefinementResult(
        x=R,
        fun=float(history[-1]),
        status=status_from(ok),
        message=msg,
        nit=n_iter,
        wall_time=time.perf_counter() - start,
        q=q,
        cost_history=history,
        frame_cost=cost,
    )


# --------------------------------------------------------------------------------------------------
# Alternation of shapes and cameras
# --------------------------------------------------------------------------------------------------


def rigid_shape_step(W2d, mask=None) -> Callable[[np.ndarray], np.ndarray]:
    """Shape step of a rigid model: given cameras, the one shape S (3, P) minimising the reprojection
    error, repeated for every frame.

    Per point j, s_j solves the 3x3 normal equations sum_f mask_fj R_f^T R_f s_j = sum_f mask_fj R_f^T
    w_f(x_j). Alternated with :func:`refine_cameras` by :func:`refine_cameras_and_shapes`, this is a
    rigid bundle adjustment with orthonormal cameras (a refinement of
    :func:`~nldr.nrsfm.factorization.initialize_cameras`).

    Parameters
    ----------
    W2d : array, shape (F, 2P)
    mask : bool array, shape (F, P), optional

    Returns
    -------
    step : callable, R (F, 2, 3) -> X (F, 3P)
    """
    W, mask = check_tracks(W2d, mask)
    F, P = mask.shape
    Wf3 = W.reshape(F, 2, P)

    def step(R):
        R = check_cameras(R, F)
        A = np.einsum("fp,fck,fcl->pkl", mask.astype(float), R, R)
        b = np.einsum("fck,fcp->pk", R, Wf3)
        A = A + 1e-12 * np.trace(A, axis1=1, axis2=2)[:, None, None] * np.eye(3)
        S = np.linalg.solve(A, b[..., None])[..., 0].T  # (3, P)
        return np.broadcast_to(S.ravel(), (F, 3 * P)).copy()

    return step


@dataclass(kw_only=True, repr=False)
class CameraShapeResult(SolverResult):
    """Result of :func:`refine_cameras_and_shapes` (a :class:`~nldr.result.SolverResult`).

    Attributes
    ----------
    x : array, shape (F, 3P)
        Shapes of the last shape step (the pair (R, x) has reprojection error ``history[-1]``).
    fun : float
        The monitored quantity after the last outer iteration: the joint energy
        ``energy_history[-1]`` when a ``penalty`` was given, else the reprojection error ``history[-1]``.
    status, message
        As in :class:`~nldr.result.SolverResult`; CONVERGED when the relative decrease of the monitored
        quantity fell below ``tol``, MAX_ITER when ``max_outer`` was reached first.
    nit : int
        Outer iterations (shape step + camera step).
    wall_time : float
        Seconds in the whole alternation.
    R : array, shape (F, 2, 3)
        Cameras after the last camera step.
    history : array, shape (nit,)
        Reprojection error (sum of squares over observed points) after each outer iteration's camera step.
    shape_history : array, shape (nit,)
        Reprojection error after each shape step (with the previous cameras).
    energy_history : array, shape (nit,) or None
        ``penalty(x) + history``, the joint energy after each outer iteration, when ``penalty`` was given.
    shape_time, camera_time : float
        Seconds spent in the shape steps and in the camera LM.
    """

    R: np.ndarray
    history: np.ndarray
    shape_history: np.ndarray
    energy_history: np.ndarray | None
    shape_time: float
    camera_time: float


def refine_cameras_and_shapes(
    W2d,
    mask,
    R0,
    shape_step: Callable[[np.ndarray], np.ndarray],
    *,
    max_outer: int = 20,
    tol: float = 1e-4,
    camera_max_iter: int = 100,
    camera_ftol: float = 1e-12,
    penalty: Callable[[np.ndarray], float] | None = None,
    callback: Callable[[int, np.ndarray, np.ndarray], None] | None = None,
    window: int = 1,
    camera_atol_deg: float | None = None,
) -> CameraShapeResult:
    """Alternate a shape step X = shape_step(R) with the camera LM (:func:`refine_cameras`).

    Outer iteration k: X_k = shape_step(R_{k-1}), then R_k = LM from R_{k-1} with X_k fixed. If the
    shape step minimises an energy ``penalty(X) + reprojection(R, X)`` (TNH with tau > 0, the kernel
    regulariser), every step decreases that joint energy. Stops when the relative decrease
    (E_{k-1} - E_k) / E_{k-1} of the monitored quantity after the camera step is below ``tol``
    (increases included), or after ``max_outer`` iterations. The monitored quantity is the joint
    energy ``penalty(X_k) + e_k`` when ``penalty`` is given, else the reprojection error e_k. Pass the
    penalty for a regularised shape step: its reprojection error alone need not decrease (on pickup
    with TNH, tau = 10, it rose by 5% in the second iteration while the joint energy fell), so the
    reprojection-only test can stop a descending alternation at once. Note that an exact-fit shape
    step (TNH with tau -> 0) reprojects any cameras exactly, so it cannot drive the cameras.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Centred image tracks as rows.
    mask : bool array, shape (F, P) or None
    R0 : array, shape (F, 2, 3)
        Initial cameras (e.g. :func:`~nldr.nrsfm.factorization.initialize_cameras`).
    shape_step : callable
        ``shape_step(R) -> X`` with R (F, 2, 3) and X (F, 3P), e.g.
        ``lambda R: trace_norm_heuristic(W2d, R, mask, tau=tau, method="fista").x``; use a closure
        to warm-start.
    max_outer : int, default 20
    tol : float > 0, default 1e-4
    camera_max_iter : int, default 100
    camera_ftol : float > 0, default 1e-12
        Passed to :func:`refine_cameras`.
    penalty : callable, optional
        ``penalty(X) -> float``, the regulariser the shape step minimises with the reprojection error
        (for TNH with tau: ``lambda X: tau * nuclear norm of X``). Monitored with the reprojection error.
    callback : callable, optional
        ``callback(k, R_k, X_k)`` after every outer iteration (k from 1).
    window : int, default 1
        Measure the decrease over this many outer iterations: stop when
        (E_{k-window} - E_k) / E_{k-window} < tol. Block-coordinate alternations crawl; a window of
        about 10 keeps a slow but steady descent going where a one-step test would stop it (Table 4's
        TNH alternation, :func:`~nldr.nrsfm.unknown_cameras.tnh_with_camera_refinement`).

    camera_atol_deg : float > 0, optional
        Also stop (converged) after an outer iteration whose camera step moved the cameras by less
        than this mean angle in degrees: the next shape step would then solve the problem it has
        just solved (a fixed point, up to the shape step's own tolerance). Default: no such test.

    Returns
    -------
    CameraShapeResult
    """
    start = time.perf_counter()
    W, mask = check_tracks(W2d, mask)
    F, P = mask.shape
    R = nearest_orthonormal_rows(check_cameras(R0, F, name="R0"))
    if not callable(shape_step):
        raise ValueError(
            f"shape_step must be a callable R (F, 2, 3) -> X (F, 3P); got {type(shape_step).__name__}"
        )
    max_outer = check_count(max_outer, "max_outer")
    tol = check_positive(tol, "tol")
    camera_max_iter = check_count(camera_max_iter, "camera_max_iter")
    camera_ftol = check_positive(camera_ftol, "camera_ftol")
    window = check_count(window, "window")
    if camera_atol_deg is not None:
        camera_atol_deg = check_positive(camera_atol_deg, "camera_atol_deg")
    Wf3 = W.reshape(F, 2, P)
    q = camera_to_quaternion(R)
    history, shape_history, energy = [], [], []
    if penalty is not None and not callable(penalty):
        raise ValueError(
            f"penalty must be a callable X (F, 3P) -> float or None; got {type(penalty).__name__}"
        )
    shape_time = camera_time = 0.0
    converged, message = False, f"reached max_outer={max_outer} outer iterations"
    X = None
    for k in range(1, max_outer + 1):
        t0 = time.perf_counter()
        X = check_shapes(shape_step(R.copy()), F, P, name="shape_step(R)")
        t1 = time.perf_counter()
        Sf = X.reshape(F, 3, P)
        shape_history.append(float(_frame_costs(Wf3, mask, R, Sf)[0].sum()))
        R_before = R
        q, R, _, frame_cost, _, _, _ = _refine_cameras(Wf3, mask, q, Sf, camera_max_iter, camera_ftol, 1e-12)
        moved = np.inf if camera_atol_deg is None else camera_movement_deg(R_before, R)
        camera_time += time.perf_counter() - t1
        shape_time += t1 - t0
        history.append(float(frame_cost.sum()))
        monitored = history
        if penalty is not None:
            energy.append(float(penalty(X)) + history[-1])
            monitored = energy
        if callback is not None:
            callback(k, R.copy(), X.copy())
        if camera_atol_deg is not None and moved < camera_atol_deg:
            converged = True
            message = f"cameras moved by {moved:.3g} deg < camera_atol_deg after {k} iterations"
            break
        if k > window:
            previous = monitored[-1 - window]
            decrease = (previous - monitored[-1]) / previous if previous > 0 else 0.0
            if decrease < tol:
                converged = True
                what = "joint energy" if penalty is not None else "reprojection error"
                message = (
                    f"relative decrease of the {what} over {window} iteration(s) {decrease:.3g} < tol "
                    f"after {k} iterations"
                )
                break
    return CameraShapeResult(
        x=X,
        fun=monitored[-1],
        status=status_from(converged),
        message=message,
        nit=len(history),
        wall_time=time.perf_counter() - start,
        R=R,
        history=np.asarray(history),
        shape_history=np.asarray(shape_history),
        energy_history=np.asarray(energy) if penalty is not None else None,
        shape_time=shape_time,
        camera_time=camera_time,
    )


def camera_movement_deg(R_a, R_b) -> float:
    """Mean over frames of the rotation angle between cameras ``R_a`` and ``R_b`` (F, 2, 3), in degrees
    (no global alignment: how far one step moved the cameras)."""
    A = nearest_orthonormal_rows(check_cameras(R_a, name="R_a"))
    B = nearest_orthonormal_rows(check_cameras(R_b, A.shape[0], name="R_b"))
    A3 = np.concatenate([A, np.cross(A[:, 0], A[:, 1])[:, None]], axis=1)
    B3 = np.concatenate([B, np.cross(B[:, 0], B[:, 1])[:, None]], axis=1)
    # chordal distance ||A3 - B3||_F = 2 sqrt(2) sin(theta / 2), well conditioned for small angles
    chord = np.linalg.norm(A3 - B3, axis=(1, 2))
    return float(np.degrees(2 * np.arcsin(np.clip(chord / (2 * np.sqrt(2)), 0, 1))).mean())
