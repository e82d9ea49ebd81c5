"""Table 4's TNH with estimated cameras: the camera LM, the shape/camera alternation, the camera search.

After the rigid initialisation (:mod:`nldr.nrsfm._factorization`) the paper alternates between the 3D
shapes and the cameras, "parameterising each R_i with quaternions ... using LM" (Section 4.3):

- :func:`camera_lm`: Levenberg-Marquardt on the per-frame quaternions with the shapes fixed,
  vectorised over frames (given the shapes, the frames are independent 4-parameter problems);
- :func:`tnh_with_camera_refinement`: the alternation of a FISTA shape step
  (:func:`~nldr.nrsfm._tnh.fista_tnh`) with the camera LM, block-coordinate descent on
  tau ||X||_* + reprojection error, run to convergence (stopped early it leaves e3D two to four times
  the converged value; every tau starts from the rigid cameras: docs/REPRODUCTION.md#table-4-tnh);
- :func:`tnh_camera_search`: the alternation can stop where a few frames end with a camera turned over
  (90-180 degrees away, their shapes bent to fit), which the local LM cannot repair; the search re-seats
  those frames (:func:`propose_cameras`) and keeps what lowers the TNH energy (tracks alone, no ground
  truth: a better optimiser of the same problem);
- the same search from several starts, with explicit ties: :mod:`nldr.nrsfm._basin_search`.

The shape step's adaptive tolerance, its carried momentum and the LM's 3x3 normal equations
(:func:`lm_normal_equations`) keep the fixed point of the plain alternation,
:func:`nldr.reference.nrsfm.tnh_with_camera_refinement_reference` (tests/test_unknown_cameras_speed.py).
Tracks are centred (w = R s); the estimates are defined up to the global gauge (R_f Q, Q^T S_f), so they
are compared with the ground truth after one alignment (:func:`~nldr.nrsfm._metrics.e3d`, ``align=True``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from .._validation import check_count, check_positive
from ..result import SolverResult, status_from
from ._reprojection import (
    check_cameras,
    check_shapes,
    check_tracks,
    masked_residual,
    tnh_energy,
    visibility_weights,
)
from ._rotations import (
    camera_to_quaternion,
    complete_rotations,
    nearest_orthonormal_rows,
    quaternion_rotation,
)
from ._tnh import fista_tnh

__all__ = [
    "CameraShapeResult",
    "lm_normal_equations",
    "camera_lm",
    "tnh_with_camera_refinement",
    "tnh_alternation",
    "PROPOSALS",
    "propose_cameras",
    "tnh_camera_search",
]


def lm_normal_equations(J, C2, SE):
    """J^T J (n, 4, 4) and -J^T r (n, 4) of the per-frame camera LM from 3x3 and 3x2 summaries.

    With J_c (3 x 4) the Jacobian d R / d q of image row c (``J`` (n, 2, 3, 4)), C = S diag(mask) S^T and
    E the masked residual: J^T J = sum_c J_c^T C J_c and -J^T r = sum_c J_c^T (S E^T)[:, c], which avoids
    the (2, P, 4) array dR/dq_i S per frame. ``C2`` (n, 6, 6) is diag(C, C), ``SE`` (n, 3, 2) is S E^T.
    """
    n = J.shape[0]
    Js = J.reshape(n, 6, 4)
    JtJ = Js.transpose(0, 2, 1) @ (C2 @ Js)
    g = (SE.transpose(0, 2, 1).reshape(n, 1, 6) @ Js)[:, 0]
    return JtJ, g


def camera_lm(Wf3, mask, q, Sf, max_iter=100, ftol=1e-12, xtol=1e-12):
    """Levenberg-Marquardt on the per-frame quaternions q (F, 4), shapes Sf (F, 3, P) fixed; no validation.

    Minimises sum_f sum_j mask_fj ||w_f(x_j) - R(q_f) s_f(x_j)||^2 (Wf3 (F, 2, P), zero where
    unobserved). Given the shapes the frames decouple, so LM runs on all frames at once with a damping
    factor per frame (one batched 4x4 solve per iteration). A frame stops when its step is accepted
    with a relative cost decrease <= ftol, when a step is rejected with a relative cost increase
    <= ftol although the Gauss-Newton model predicted a relative decrease <= ftol (the cost no longer
    changes beyond rounding, MINPACK's ftol test), or when its step is <= xtol (in unit quaternion).
    Steps are taken in q and renormalised; the radial direction, along which the cost is constant, is
    penalised in the normal equations.

    Returns
    -------
    (q (F, 4), R (F, 2, 3), cost history (n_iter + 1,), per-frame cost (F,), n_iter, converged, message)
    """
    F = q.shape[0]
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    R, J = quaternion_rotation(q, jacobian=True, rows=2)  # the cameras and their Jacobian
    m3 = visibility_weights(mask)
    C = (Sf if m3 is None else Sf * m3) @ Sf.transpose(0, 2, 1)  # S diag(mask) S^T, (F, 3, 3)
    C2 = np.zeros((F, 6, 6))
    C2[:, :3, :3] = C2[:, 3:, 3:] = C
    E = Wf3 - R @ Sf
    E *= mask[:, None, :]
    cost = np.einsum("fcp,fcp->f", E, E)
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
        R_new, J_new = quaternion_rotation(q_new, jacobian=True, rows=2)
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


@dataclass(kw_only=True, repr=False)
class CameraShapeResult(SolverResult):
    """Result of :func:`tnh_with_camera_refinement` (a :class:`~nldr.result.SolverResult`).

    Attributes
    ----------
    x, R : arrays (F, 3P) and (F, 2, 3)
        Shapes of the last shape step and cameras of the last camera step (unit of the tracks).
    fun : float
        The joint energy tau ||X||_* + reprojection error after the last outer iteration.
    status, message, nit
        CONVERGED when the windowed relative decrease of the joint energy fell below ``tol``, MAX_ITER
        when ``max_outer`` was reached first; ``nit`` outer iterations (shape step + camera step).
    history, energy_history : arrays (nit,)
        The reprojection error (sum of squares over observed points) and the joint energy after each.
    search : dict or None
        After :func:`tnh_camera_search`: ``energies`` (the start's TNH energy, then each accepted
        round's), ``trials`` (round, mode, frames re-seated, energy) and ``n_alternations``.
    """

    R: np.ndarray
    history: np.ndarray
    energy_history: np.ndarray
    search: dict | None = None


def tnh_with_camera_refinement(
    W2d, mask, R0, tau: float, *, max_outer: int = 20_000, tol: float = 1e-8, window: int = 10, X0=None
) -> CameraShapeResult:
    """TNH with the cameras refined in alternation, from R0 to convergence of the joint energy.

    Outer iteration k: the shapes minimise tau ||X||_* + reprojection error at the current cameras
    (:func:`~nldr.nrsfm._tnh.fista_tnh`, warm-started from the previous shapes and their momentum, at
    most 300 iterations), then :func:`camera_lm` refines every camera with the shapes fixed (50 LM
    iterations). The shape step's FISTA tolerance is 1e-2 times the relative decrease of the joint
    energy in the previous outer iteration, clipped to [1e-12, 1e-6] (1e-6 for the first two). Stops
    when the relative decrease (E_{k-window} - E_k) / E_{k-window} of the joint energy is below ``tol``,
    increases included, or after ``max_outer`` iterations; a window of about 10 keeps a slow but steady
    block-coordinate descent going where a one-step test would stop it.

    Parameters
    ----------
    W2d, mask : arrays (F, 2P) and (F, P) or None
        Centred tracks and visibility (:mod:`nldr.nrsfm._layout`); every frame needs 3 observed points.
    R0 : array, shape (F, 2, 3)
        Initial cameras (projected to orthonormal rows), e.g. :func:`~nldr.nrsfm.initialize_cameras`.
    tau : float > 0
        Trace-norm weight, in the unit of the tracks squared.
    max_outer, tol, window : int, float > 0, int
    X0 : array, shape (F, 3P), optional
        Start of the first shape step (default zeros, the cold start Table 4's protocol uses).

    Returns
    -------
    CameraShapeResult
    """
    return tnh_alternation(W2d, mask, R0, tau, max_outer, tol, window, X0)


def tnh_alternation(
    W2d, mask, R0, tau, max_outer, tol, window, X0, shape_tol=(1e-12, 1e-2, 1e-6), momentum=True, svt=None
):
    """:func:`tnh_with_camera_refinement` with the shape step's knobs, for :mod:`nldr.reference.nrsfm`:
    ``shape_tol`` = (floor, ratio, ceiling) of its FISTA tolerance (ratio 0: the floor throughout),
    ``momentum`` (carry FISTA's momentum across outer iterations) and ``svt`` (None: FISTA's default
    thresholding). Positional as :func:`tnh_with_camera_refinement`'s; no other caller."""
    start = time.perf_counter()
    tau = check_positive(tau, "tau")
    floor, ratio, ceiling = shape_tol
    W, vis = check_tracks(W2d, mask)
    F, P = vis.shape
    W3 = W.reshape(F, 2, P)
    m3 = visibility_weights(vis)
    X, nuclear, carried, previous = np.zeros((F, 3, P)), 0.0, None, None
    if X0 is not None:
        X0 = check_shapes(X0, F, P, name="X0")
        X, nuclear = X0.reshape(F, 3, P).copy(), float(np.linalg.svd(X0, compute_uv=False).sum())
    R = nearest_orthonormal_rows(check_cameras(R0, F, name="R0"))
    max_outer, window = check_count(max_outer, "max_outer"), check_count(window, "window")
    tol = check_positive(tol, "tol")
    thresholding = {} if svt is None else {"svt": svt}
    q = camera_to_quaternion(R)
    history, energy = [], []
    converged, message = False, f"reached max_outer={max_outer} outer iterations"
    for k in range(1, max_outer + 1):
        inner_tol = ceiling if ratio > 0 else floor
        if ratio > 0 and k > 1:  # the joint energy after outer iteration k - 1 (its shapes and cameras)
            E = masked_residual(W3, m3, R, X)
            now = tau * nuclear + float(np.vdot(E, E))
            if previous is not None:
                inner_tol = min(ceiling, max(floor, ratio * (previous - now) / max(now, 1e-300)))
            previous = now
        out = fista_tnh(W3, m3, R, X, nuclear, tau, 300, inner_tol, momentum=carried if momentum else None,
                        **thresholding)  # fmt: skip
        X, nuclear, carried = out.x.reshape(F, 3, P), out.nuclear_norm, out.momentum
        q, R, _, frame_cost, _, _, _ = camera_lm(W3, vis, q, X, 50)
        history.append(float(frame_cost.sum()))
        energy.append(tau * nuclear + history[-1])
        if k > window:
            before = energy[-1 - window]
            decrease = (before - energy[-1]) / before if before > 0 else 0.0
            if decrease < tol:
                converged = True
                message = (
                    f"relative decrease of the joint energy over {window} iteration(s) {decrease:.3g} < tol "
                    f"after {k} iterations"
                )
                break
    return CameraShapeResult(
        x=X.reshape(F, 3 * P), fun=energy[-1], status=status_from(converged), message=message,
        nit=len(history), wall_time=time.perf_counter() - start, R=R, history=np.asarray(history),
        energy_history=np.asarray(energy),
    )  # fmt: skip


PROPOSALS = ("forward", "backward", "local", "worst")


def propose_cameras(R, mode: str, threshold_deg: float = 30.0) -> tuple[np.ndarray, np.ndarray]:
    """Cameras with the frames that break the motion re-seated at their neighbours' prediction.

    Parameters
    ----------
    R : array, shape (F, 2, 3)
        Cameras (projected to orthonormal rows, completed to rotations by the cross product).
    mode : {"forward", "backward", "local", "worst"}
        "forward": frames 2..F-1 in order, predicted Q_f = Q_{f-1} Q_{f-2}^T Q_{f-1} (constant angular
        velocity) from the cameras already re-seated; "backward": the same from the end; "local": the
        geodesic midpoint of Q_{f-1} and Q_{f+1} (original cameras), frames 1..F-2, a frame taking it
        only if it is also more than ``threshold_deg`` from both one-sided predictions; "worst": the
        one frame furthest from its prediction (the midpoint of its neighbours inside, the constant
        velocity extrapolation of the two nearest at either end), alone, if more than
        ``threshold_deg / 2`` from it (a single frame left a little off, which the sweeps, moving
        several frames at once, and the 30-degree test miss).
    threshold_deg : float > 0, default 30
        A frame is re-seated when its camera is further than this (degrees) from the prediction.

    Returns
    -------
    (R_new (F, 2, 3), changed (int array of frames))
    """
    if mode not in PROPOSALS:
        raise ValueError(f"mode must be one of {PROPOSALS}; got {mode!r}")
    threshold = np.radians(check_positive(threshold_deg, "threshold_deg"))
    M = complete_rotations(R)
    F = M.shape[0]
    out = M.copy()
    changed = []
    if F < 3:
        return M[:, :2].copy(), np.zeros(0, dtype=int)
    if mode == "worst":
        Q = Rotation.from_matrix(M)
        mid = Rotation.from_rotvec(0.5 * (Q[2:] * Q[:-2].inv()).as_rotvec()) * Q[:-2]
        first, last = Q[1] * Q[2].inv() * Q[1], Q[F - 2] * Q[F - 3].inv() * Q[F - 2]
        pred = Rotation.concatenate([first, mid, last])
        off = (pred * Q.inv()).magnitude()
        f = int(np.argmax(off))  # the first of equal deviations: a fixed rule
        if off[f] > threshold / 2:
            out[f] = pred[f].as_matrix()
            changed = [f]
    elif mode == "local":
        Q = Rotation.from_matrix(M)
        a, c = Q[:-2], Q[2:]
        mid = Rotation.from_rotvec(0.5 * (c * a.inv()).as_rotvec()) * a
        fwd = a * Q[np.r_[0, : F - 3]].inv() * a  # from f-1, f-2 (f-2 clipped at 0)
        bwd = c * Q[np.r_[3:F, F - 1]].inv() * c
        off = [(p * Q[1:-1].inv()).magnitude() > threshold for p in (mid, fwd, bwd)]
        idx = np.flatnonzero(off[0] & off[1] & off[2]) + 1
        out[idx] = mid.as_matrix()[idx - 1]
        changed = list(idx)
    else:
        step, order = (-1, range(2, F)) if mode == "forward" else (1, range(F - 3, -1, -1))
        for f in order:
            Qa, Qb = Rotation.from_matrix(out[f + step]), Rotation.from_matrix(out[f + 2 * step])
            pred = Qa * Qb.inv() * Qa
            if (pred * Rotation.from_matrix(out[f]).inv()).magnitude() > threshold:
                out[f] = pred.as_matrix()
                changed.append(f)
    return out[:, :2].copy(), np.asarray(sorted(changed), dtype=int)


def tnh_camera_search(
    W2d,
    mask,
    start: CameraShapeResult,
    tau: float,
    *,
    max_rounds: int = 2,
    proposals=PROPOSALS,
    threshold_deg: float = 30.0,
    rtol: float = 1e-6,
    **alternation,
) -> CameraShapeResult:
    """Improve a converged TNH alternation ``start`` at weight ``tau`` by re-seating cameras.

    Each round: every proposal of :func:`propose_cameras` that re-seats at least one frame is
    continued by :func:`tnh_with_camera_refinement` (cold shapes, the
    keyword options ``alternation``, e.g. ``max_outer``, ``tol``); the lowest converged energy is kept
    if it is below the best so far by more than ``rtol`` (relative), and the next round starts from
    it. Stops at the first round that keeps nothing, or after ``max_rounds``.

    Parameters
    ----------
    W2d, mask, tau
        As in :func:`tnh_with_camera_refinement`.
    start : CameraShapeResult
        A converged alternation at this ``tau``.
    max_rounds, proposals, threshold_deg, rtol : int >= 1, subset of :data:`PROPOSALS`, float, float

    Returns
    -------
    CameraShapeResult
        The alternation kept (a copy of ``start`` if none was better) with ``fun`` its TNH energy
        (:func:`~nldr.nrsfm._reprojection.tnh_energy`), ``message`` followed by the search's,
        ``search`` the record.
    """
    tau = check_positive(tau, "tau")
    max_rounds = check_count(max_rounds, "max_rounds")
    rtol = check_positive(rtol, "rtol")
    proposals = tuple(proposals)
    if not proposals or any(p not in PROPOSALS for p in proposals):
        raise ValueError(f"proposals must be a non-empty subset of {PROPOSALS}; got {proposals!r}")
    if not isinstance(start, CameraShapeResult):
        raise ValueError(
            f"start must be a CameraShapeResult (a converged alternation); got {type(start).__name__}"
        )
    best = start
    best_energy = tnh_energy(W2d, mask, start.R, start.x, tau)
    history, trials, runs = [best_energy], [], 0
    message, k = "no proposal lowered the energy", 0
    for k in range(1, max_rounds + 1):  # noqa: B007 (k is reported)
        found = None
        for mode in proposals:
            R1, changed = propose_cameras(best.R, mode, threshold_deg)
            if changed.size == 0:
                continue
            res = tnh_with_camera_refinement(W2d, mask, R1, tau, **alternation)
            runs += 1
            energy = tnh_energy(W2d, mask, res.R, res.x, tau)
            trials.append((k, mode, changed, energy))
            if found is None or energy < found[0]:
                found = (energy, res, mode)
        if found is None or not found[0] < best_energy * (1 - rtol):
            message = f"round {k}: no proposal lowered the energy"
            break
        best_energy, best = found[0], found[1]
        history.append(best_energy)
        message = f"round {k}: {found[2]} proposal, energy {best_energy:.6g}"
    record = {"energies": history, "trials": trials, "n_alternations": runs}
    summary = f"{best.message}; camera search: {runs} alternations, {message}"
    return replace(best, fun=best_energy, message=summary, search=record)
