"""TNH with estimated cameras from several starts, with explicit ties between near-equal energies.

- :func:`tnh_basin_search`: the alternation and the camera search
  (:func:`~nldr.nrsfm._camera_refinement.tnh_camera_search`) from several starts (the rigid cameras,
  and a continuation in tau from them, :func:`tnh_continuation`), keeping the lowest TNH energy;
- :func:`lowest_energy`: energies within a relative tolerance count as one basin and the choice among
  them follows a fixed rule, so that the basin kept does not hang on the last bit of the arithmetic
  (the kernel stage's multistart uses it too).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .._validation import check_positive
from ._camera_refinement import (
    PROPOSALS,
    CameraShapeResult,
    tnh_camera_search,
    tnh_with_camera_refinement,
)
from ._reprojection import check_cameras, check_tracks

__all__ = ["STARTS", "lowest_energy", "tnh_continuation", "tnh_basin_search"]


#: The starts of :func:`tnh_basin_search`, in the order that breaks ties (the rigid cameras first: the
#: paper's start).
STARTS = ("rigid", "continuation")


def lowest_energy(candidates, rtol: float, priority=()) -> str:
    """The label of the lowest energy, with near-ties broken by a fixed rule rather than by rounding.

    Energies (>= 0) within ``rtol`` (relative) of the lowest are tied: two runs that end in one basin
    differ by their stopping tests' precision, far less than two basins do, and which of them is lower
    by that much can change with the BLAS kernel. Among the tied labels, the first of ``priority``
    wins, then the smallest label. The choice depends on the set of (label, energy) pairs only, never
    on their order.

    Parameters
    ----------
    candidates : iterable of (str, float)
        Labels (distinct) and energies.
    rtol : float >= 0
    priority : sequence of str, optional
        Labels in order of preference among tied energies; labels not in it come after, by name.

    Returns
    -------
    str
    """
    pairs = [(str(label), float(energy)) for label, energy in candidates]
    if not pairs:
        raise ValueError("candidates must hold at least one (label, energy) pair")
    if len({label for label, _ in pairs}) != len(pairs):
        raise ValueError(f"candidates' labels must be distinct; got {[label for label, _ in pairs]}")
    rtol = check_positive(rtol, "rtol", allow_zero=True)
    lowest = min(energy for _, energy in pairs)
    tied = [label for label, energy in pairs if energy <= lowest + rtol * abs(lowest)]
    rank = {label: k for k, label in enumerate(priority)}
    return min(tied, key=lambda label: (rank.get(label, len(rank)), label))


def tnh_continuation(
    W2d, mask, R0, tau: float, *, log10_tau_high: float = 2.0, log10_step: float = 0.5, **alternation
) -> CameraShapeResult:
    """The alternation at ``tau`` at the end of a path in tau from the cameras R0.

    Runs :func:`tnh_with_camera_refinement` from R0 at tau = 10**log10_tau_high, then at every rung
    log10_tau_high - k log10_step above ``tau``, each from the previous rung's cameras and shapes, and
    last at ``tau``. A large tau asks for a nearly rigid shape, whose cameras the alternation finds
    from far; the rungs then let the shapes deform gradually, so that frames the cold start at ``tau``
    would turn over follow their neighbours instead.

    Parameters
    ----------
    W2d, mask, R0, tau
        As in :func:`tnh_with_camera_refinement`.
    log10_tau_high : float, default 2
        First rung (Table 4's tau search interval ends there); none is run if it is not above tau.
    log10_step : float > 0, default 0.5
    **alternation
        ``max_outer``, ``tol``, ``window`` of every alternation.

    Returns
    -------
    CameraShapeResult
        The last alternation, ``nit`` counting the outer iterations of every rung, ``search`` =
        ``{"n_alternations": rungs + 1}``.
    """
    tau = check_positive(tau, "tau")
    step = check_positive(log10_step, "log10_step")
    high, low = float(log10_tau_high), float(np.log10(tau))
    rungs = [high - k * step for k in range(int(np.floor((high - low) / step)) + 2)]
    rungs = [r for r in rungs if r > low + 1e-9]
    R, X, nit = R0, None, 0
    for rung in rungs:
        res = tnh_with_camera_refinement(W2d, mask, R, 10.0**rung, X0=X, **alternation)
        R, X, nit = res.R, res.x, nit + res.nit
    res = tnh_with_camera_refinement(W2d, mask, R, tau, X0=X, **alternation)
    message = f"continuation over {len(rungs)} rung(s) from tau = {10.0**high:.3g}; {res.message}"
    return replace(res, nit=res.nit + nit, message=message, search={"n_alternations": len(rungs) + 1})


def tnh_basin_search(
    W2d,
    mask,
    R0,
    tau: float,
    *,
    starts=STARTS,
    tie_rtol: float = 1e-4,
    rigid: CameraShapeResult | None = None,
    log10_tau_high: float = 2.0,
    log10_step: float = 0.5,
    max_rounds: int = 2,
    proposals=PROPOSALS,
    threshold_deg: float = 30.0,
    rtol: float = 1e-6,
    **alternation,
) -> CameraShapeResult:
    """TNH with estimated cameras at ``tau``: the lowest energy over several starts and the camera search.

    From each start the alternation at ``tau`` (:func:`tnh_with_camera_refinement`), then
    :func:`tnh_camera_search` from its end point; the result with the lowest TNH energy is kept,
    energies within ``tie_rtol`` (relative) of each other counting as equal and going to the earlier
    start of :data:`STARTS` (:func:`lowest_energy`). The starts, from the tracks alone:

    - ``"rigid"``: the cameras R0 (``rigid``: the alternation from them, if already run);
    - ``"continuation"``: :func:`tnh_continuation` from R0.

    Parameters
    ----------
    W2d, mask, tau
        As in :func:`tnh_with_camera_refinement`.
    R0 : array, shape (F, 2, 3)
        The rigid cameras (:func:`~nldr.nrsfm.initialize_cameras`).
    starts : non-empty subset of :data:`STARTS`
    tie_rtol : float >= 0, default 1e-4
        Relative energy difference below which two results count as one basin.
    rigid : CameraShapeResult, optional
        The converged alternation from R0 at ``tau``, to reuse.
    log10_tau_high, log10_step
        Of :func:`tnh_continuation`.
    max_rounds, proposals, threshold_deg, rtol
        Of :func:`tnh_camera_search`.
    **alternation
        ``max_outer``, ``tol`` of every alternation.

    Returns
    -------
    CameraShapeResult
        The kept result, ``fun`` its TNH energy; ``search`` is its camera search's record with
        ``start`` (the start kept), ``start_energies`` (start -> final TNH energy) and
        ``n_alternations`` (over every start).
    """
    tau = check_positive(tau, "tau")
    starts = tuple(starts)
    if not starts or any(s not in STARTS for s in starts) or len(set(starts)) != len(starts):
        raise ValueError(f"starts must be a non-empty subset of {STARTS} without repeats; got {starts!r}")
    tie_rtol = check_positive(tie_rtol, "tie_rtol", allow_zero=True)
    R0 = check_cameras(R0, check_tracks(W2d, mask)[1].shape[0], name="R0")
    search = dict(max_rounds=max_rounds, proposals=proposals, threshold_deg=threshold_deg, rtol=rtol)
    found, runs = {}, 0
    for label in starts:
        if label == "rigid":
            begin = rigid
            if begin is None:
                begin = tnh_with_camera_refinement(W2d, mask, R0, tau, **alternation)
                runs += 1
        else:
            begin = tnh_continuation(
                W2d, mask, R0, tau, log10_tau_high=log10_tau_high, log10_step=log10_step, **alternation
            )
            runs += begin.search["n_alternations"]
        found[label] = tnh_camera_search(W2d, mask, begin, tau, **search, **alternation)
        runs += found[label].search["n_alternations"]
    energies = {label: float(res.fun) for label, res in found.items()}
    choice = lowest_energy(energies.items(), tie_rtol, STARTS)
    best = found[choice]
    record = dict(best.search, start=choice, start_energies=energies, n_alternations=runs)
    listed = ", ".join(f"{label} {energy:.10g}" for label, energy in energies.items())
    message = f"{best.message}; kept the {choice} start (TNH energy by start: {listed})"
    return replace(best, message=message, search=record)
