"""Choosing NRSfM parameters from the image tracks alone: hold-out cross-validation of 2D points.

The paper fixes the kernel method's tau (1e-4) and width (the d_max / d_med rules) by hand, and
tunes the Table 4 TNH baseline's tau on the 3D error against ground truth (an oracle). Without
ground truth, the honest score of a setting is how well it predicts image points it did not see:
each fold hides a random share of the *observed* 2D points (a point in a frame is hidden with both
its image coordinates), the method reconstructs from the rest, and the fold's score is the mean
squared reprojection error of the hidden points, ``mean ||w_f(x_j) - R_f s_f(x_j)||^2`` over the
hidden (f, j), with the frame's camera R_f and the reconstructed 3D point s_f(x_j) (squared unit of
the tracks). The score is invariant to the global gauge (R_f Q, Q^T s), so estimated cameras need no
alignment. The chosen candidate (for TNH's tau: the smallest mean score over the folds) is refitted
on every observed point. Nothing here sees the 3D ground truth.

- :func:`visibility_folds`: the hidden points of each fold (same seed, same folds).
- :func:`select_tnh_tau`: TNH's tau with cameras estimated (Table 4's pipeline: rigid factorisation,
  then TNH alternating with the camera LM, every tau from the rigid cameras, as the oracle search of
  :func:`~nldr.experiments.table4.tune_tau` does). Each fold re-estimates the rigid cameras from
  its own training points.
- The kernel method's tau and width: :mod:`nldr.nrsfm.kernel_selection` (same folds and score).

Cost. TNH's taus are always cold starts from the rigid cameras (a continuation in tau lands in a
different basin, docs/REPRODUCTION.md#table-4-tnh). Folds run in parallel with ``n_jobs``.

Layouts as in :mod:`nldr.nrsfm.layout`: tracks W2d (F, 2P), shapes X (F, 3P), cameras R (F, 2, 3),
visibility masks (F, P), True where observed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from .._cv import positive_grid, run_jobs, summarise_folds
from .._validation import check_count, check_positive
from .factorization import initialize_cameras
from .reconstruct import Reconstruction, reconstruct
from .reprojection import check_tracks, reprojection_error

__all__ = [
    "DEFAULT_TNH_TAUS",
    "visibility_folds",
    "TNHTauSelection",
    "select_tnh_tau",
]

#: TNH tau grid (unit of the tracks squared): 7 log-spaced values over Table 4's search interval [0.1, 100].
DEFAULT_TNH_TAUS = tuple(float(t) for t in np.logspace(-1, 2, 7))


# --------------------------------------------------------------------------------------------------
# Folds and the score
# --------------------------------------------------------------------------------------------------


def visibility_folds(
    mask,
    n_folds: int = 3,
    random_state=0,
    *,
    holdout_fraction: float | None = None,
    min_per_frame: int = 3,
    min_per_point: int = 1,
) -> list[np.ndarray]:
    """Hidden 2D points of the cross-validation folds: disjoint subsets of the observed points.

    The observed (frame, point) pairs are shuffled with ``random_state``; fold k hides the k-th chunk
    of ``round(holdout_fraction * n_observed)`` of them (``holdout_fraction=None``: the k-th of
    ``n_folds`` equal shares, a partition). A fold then un-hides points, in shuffled order, until every
    frame keeps ``min_per_frame`` observed points for training (an orthographic camera has 5 degrees
    of freedom: with fewer, the frame's camera and shape are not determined) and every point keeps
    ``min_per_point`` frames (a point never seen has no track to reconstruct). A frame or point with
    fewer observations than that in ``mask`` itself is never hidden.

    Parameters
    ----------
    mask : bool array, shape (F, P)
        True where point j is observed in frame f.
    n_folds : int >= 2, default 3
    random_state : int or numpy Generator, default 0
        Seed of the shuffle: the same seed gives the same folds.
    holdout_fraction : float in (0, 1 / n_folds], optional
        Share of the observed points each fold hides (before the un-hiding above); default 1 / n_folds.
    min_per_frame, min_per_point : int >= 0, defaults 3 and 1
        Training observations every frame and every point keeps.

    Returns
    -------
    folds : list of n_folds bool arrays, shape (F, P)
        True at the points fold k hides: observed, disjoint across folds.
    """
    mask = np.asarray(mask)
    if mask.ndim != 2 or mask.dtype != bool:
        raise ValueError(f"mask must be a 2-d bool array (F, P); got dtype {mask.dtype}, shape {mask.shape}")
    n_folds = check_count(n_folds, "n_folds")
    if n_folds < 2:
        raise ValueError(f"n_folds must be >= 2; got {n_folds}")
    if holdout_fraction is None:
        frac = 1.0 / n_folds
    else:
        frac = check_positive(holdout_fraction, "holdout_fraction")
        if frac * n_folds > 1.0 + 1e-12:
            raise ValueError(
                f"holdout_fraction * n_folds must be <= 1 (the folds are disjoint); got {frac} * {n_folds}"
            )
    min_per_frame = check_count(min_per_frame, "min_per_frame") if min_per_frame else 0
    min_per_point = check_count(min_per_point, "min_per_point") if min_per_point else 0
    observed = np.flatnonzero(mask.ravel())
    if observed.size < n_folds:
        raise ValueError(f"mask has {observed.size} observed points, fewer than n_folds = {n_folds}")
    order = np.random.default_rng(random_state).permutation(observed)
    size = observed.size // n_folds if holdout_fraction is None else int(round(frac * observed.size))
    F, P = mask.shape
    folds = []
    for k in range(n_folds):
        chunk = order[k::n_folds] if holdout_fraction is None else order[k * size : (k + 1) * size]
        hidden = np.zeros(mask.size, dtype=bool)
        hidden[chunk] = True
        hidden = hidden.reshape(F, P)
        for axis, minimum in ((1, min_per_frame), (0, min_per_point)):
            train = (mask & ~hidden).sum(axis=axis)
            for idx in np.flatnonzero(train < minimum):
                # un-hide this frame's (point's) hidden points in shuffled order until it has enough
                line = chunk[(chunk // P == idx) if axis == 1 else (chunk % P == idx)]
                need = minimum - train[idx]
                for flat in line[:need]:
                    hidden[flat // P, flat % P] = False
        folds.append(hidden)
    return folds


# --------------------------------------------------------------------------------------------------
# TNH's tau with estimated cameras (Table 4)
# --------------------------------------------------------------------------------------------------


@dataclass(repr=False)
class TNHTauSelection:
    """Outcome of :func:`select_tnh_tau`.

    Attributes
    ----------
    tau_ : float
        The chosen TNH weight (unit of the tracks squared).
    cv_results_ : DataFrame
        One row per candidate, by tau: ``tau, mean_test_error`` (mean over folds of the mean squared
        reprojection error of the hidden points, unit of the tracks squared), ``std_test_error``
        (sample sd over folds), ``fit_time`` (mean CPU seconds of one fold solve).
    result_ : Reconstruction
        TNH with estimated cameras at ``tau_`` on every observed point, from ``rigid_cameras_``
        (:func:`~nldr.nrsfm.reconstruct`).
    rigid_cameras_ : array, shape (F, 2, 3)
        Rigid factorisation of every observed point (the refit's start).
    folds_ : list of bool arrays, shape (F, P)
        The hidden points of each fold.
    fold_results_ : list of Reconstruction
        Each fold's solve at ``tau_`` (start of :func:`select_kernel`'s folds).
    refit_time_ : float
        CPU seconds of the refit alone (rigid factorisation and one alternation): the cost of one solve.
    """

    tau_: float
    cv_results_: pd.DataFrame
    result_: Reconstruction
    rigid_cameras_: np.ndarray
    folds_: list
    fold_results_: list
    refit_time_: float

    def __repr__(self) -> str:
        n, k = len(self.cv_results_), len(self.folds_)
        return f"TNHTauSelection(tau_={self.tau_:.4g}, candidates={n}, folds={k})"


def _tnh_fold(W2d, train, hidden, taus, options):
    with threadpool_limits(1):
        R0 = initialize_cameras(W2d, train)
        rows, results = [], []
        for tau in taus:
            start = time.process_time()
            res = reconstruct(W2d, train, prior="tnh", tau=float(tau), initial_cameras=R0, **options)
            error = reprojection_error(W2d, hidden, res.R, res.x, mean=True)
            rows.append({"tau": float(tau), "test_error": error, "fit_time": time.process_time() - start})
            results.append(res)
        return rows, results


def select_tnh_tau(
    W2d,
    mask=None,
    *,
    taus=None,
    n_folds: int = 3,
    holdout_fraction: float | None = None,
    random_state=0,
    n_jobs: int = 1,
    camera_search=False,
    **alternation_options,
) -> TNHTauSelection:
    """Choose TNH's tau for NRSfM with unknown cameras by hold-out reprojection error.

    Per fold: rigid factorisation of the training points
    (:func:`~nldr.nrsfm.factorization.initialize_cameras`), then for every tau
    TNH with estimated cameras from those cameras (:func:`~nldr.nrsfm.reconstruct` with
    ``prior="tnh"``: a cold start, to convergence), scored on the fold's hidden points. The chosen tau
    is refitted on every observed point from the rigid cameras of all of them: exactly one evaluation
    of Table 4's oracle search (then the camera search, with ``camera_search``, as Table 4 does at
    its tau*).

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Centred image tracks as rows (entries of unobserved points are ignored).
    mask : bool array, shape (F, P), optional
        Visibility; default all observed.
    taus : sequence of float > 0, optional
        Candidates (unit of the tracks squared); default :data:`DEFAULT_TNH_TAUS`.
    n_folds, holdout_fraction, random_state
        Folds of :func:`visibility_folds` (every frame keeps 3 training points).
    n_jobs : int >= 1
        Processes over the folds, one BLAS thread each.
    camera_search : bool or mapping, default False
        The refit's camera search (:func:`~nldr.nrsfm.reconstruct`'s option).
    **alternation_options
        TNH's options in :func:`~nldr.nrsfm.reconstruct` (``max_outer``, ``tol``, ``window``), in the
        folds and the refit.

    Returns
    -------
    TNHTauSelection
        Ties go to the smallest tau.
    """
    W, mask = check_tracks(W2d, mask)
    n_jobs = check_count(n_jobs, "n_jobs")
    taus = positive_grid(DEFAULT_TNH_TAUS if taus is None else taus, "taus")
    folds = visibility_folds(mask, n_folds, random_state, holdout_fraction=holdout_fraction)
    W2d = W  # zeros where unobserved
    per_fold = run_jobs([(_tnh_fold, (W2d, mask & ~h, h, taus, alternation_options)) for h in folds], n_jobs)
    cv = summarise_folds([row for rows, _ in per_fold for row in rows], ["tau"])
    best = int(np.argmin(cv["mean_test_error"].to_numpy()))
    tau = float(cv["tau"].iloc[best])
    start = time.process_time()
    R0 = initialize_cameras(W2d, mask)
    result = reconstruct(
        W2d,
        mask,
        prior="tnh",
        tau=tau,
        initial_cameras=R0,
        camera_search=camera_search,
        **alternation_options,
    )
    refit_time = time.process_time() - start
    k = int(np.flatnonzero(taus == tau)[0])
    fold_results = [results[k] for _, results in per_fold]
    return TNHTauSelection(tau, cv, result, R0, folds, fold_results, refit_time)
