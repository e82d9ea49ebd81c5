"""A data-only camera search for TNH with unknown cameras: re-seating cameras that break the motion.

The camera/shape alternation (:func:`~nldr.nrsfm.camera_refinement.tnh_with_camera_refinement`) is
block-coordinate descent on tau ||X||_* + reprojection error and can stop in a poor basin where a few
frames end with a camera turned over (90-180 degrees away, their shapes bent to fit), which its local
camera LM cannot repair (docs/REPRODUCTION.md#table-4-tnh).

:func:`propose_cameras` re-seats the frames whose camera is more than ``threshold_deg`` from the
prediction of its neighbours: at constant angular velocity from the two previous frames (forward, using
the frames already re-seated), the two next frames (backward), or the geodesic midpoint of the two
neighbours (local). :func:`tnh_camera_search` continues the alternation from each proposal and keeps
the one of lowest converged energy if it is lower than the start's, repeating from there while that
holds. Every decision uses the TNH energy at the given tau and the tracks alone (no ground truth): a
better optimiser of the same problem, not a different estimator.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from .._validation import check_count, check_positive
from .camera_refinement import CameraShapeResult, tnh_with_camera_refinement
from .reprojection import tnh_energy
from .rotations import complete_rotations

__all__ = ["PROPOSALS", "propose_cameras", "tnh_camera_search"]

PROPOSALS = ("forward", "backward", "local")


def propose_cameras(R, mode: str, threshold_deg: float = 30.0) -> tuple[np.ndarray, np.ndarray]:
    """Cameras with the frames that break the motion re-seated at their neighbours' prediction.

    Parameters
    ----------
    R : array, shape (F, 2, 3)
        Cameras (projected to orthonormal rows, completed to rotations by the cross product).
    mode : {"forward", "backward", "local"}
        "forward": frames 2..F-1 in order, predicted Q_f = Q_{f-1} Q_{f-2}^T Q_{f-1} (constant angular
        velocity) from the cameras already re-seated; "backward": the same from the end; "local": the
        geodesic midpoint of Q_{f-1} and Q_{f+1} (original cameras), frames 1..F-2, a frame taking it
        only if it is also more than ``threshold_deg`` from both one-sided predictions.
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
    if mode == "local":
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
    continued by :func:`~nldr.nrsfm.camera_refinement.tnh_with_camera_refinement` (cold shapes, the
    keyword options ``alternation``, e.g. ``max_outer``, ``tol``); the lowest converged energy is kept
    if it is below the best so far by more than ``rtol`` (relative), and the next round starts from
    it. Stops at the first round that keeps nothing, or after ``max_rounds``.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
    mask : bool array, shape (F, P) or None
    start : CameraShapeResult
        A converged alternation at this ``tau``.
    tau : float > 0
    max_rounds : int >= 1, default 2
    proposals : subset of :data:`PROPOSALS`
    threshold_deg : float > 0, default 30
    rtol : float > 0, default 1e-6

    Returns
    -------
    CameraShapeResult
        The alternation kept (a copy of ``start`` if none was better) with ``fun`` its TNH energy
        (:func:`~nldr.nrsfm.tnh_energy`), ``message`` followed by the search's, ``search`` the record.
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
