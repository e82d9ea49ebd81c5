"""Choosing NRSfM parameters from the image tracks alone: hold-out cross-validation of 2D points.

The paper fixes the kernel method's tau (1e-4) and width (the d_max / d_med rules) by hand, and
tunes the Table 4 TNH baseline's tau on the 3D error against ground truth (an oracle). Without
ground truth, the honest score of a setting is how well it predicts image points it did not see:
each fold hides a random share of the *observed* 2D points (a point in a frame is hidden with both
its image coordinates), the method reconstructs from the rest, and the fold's score is the mean
squared reprojection error of the hidden points, ``mean ||w_f(x_j) - R_f s_f(x_j)||^2`` over the
hidden (f, j), with the frame's camera R_f and the reconstructed 3D point s_f(x_j) (squared unit of
the tracks). The score is invariant to the global gauge (R_f Q, Q^T s), so estimated cameras need no
alignment. Nothing here sees the 3D ground truth.

The search is :class:`nldr.model_selection.HoldoutSearch`, with the 2D points as its entries: the
tracks W (F, 2P) with NaN at unobserved points are the matrix, a fold hiding the points ``h`` (F, P)
hides the entries ``[h, h]``, and each candidate is a reconstruction whose completion of W is its
reprojection R_f s_f of every point.

- :func:`visibility_folds`: the hidden points of each fold (same seed, same folds).
- :func:`select_tnh_tau`: TNH's tau with cameras estimated (Table 4's pipeline).
- :func:`~nldr.nrsfm.kernel_selection.select_kernel`: the kernel method's tau and width, with known
  cameras (Table 3) or after :func:`select_tnh_tau` (Table 4's kernel stage), by default keeping the
  paper's values unless the evidence is against them.

Folds run in parallel with ``n_jobs``.

Layouts as in :mod:`nldr.nrsfm.layout`: tracks W2d (F, 2P), shapes X (F, 3P), cameras R (F, 2, 3),
visibility masks (F, P), True where observed.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, TransformerMixin

from .._cv import positive_grid
from .._options import last_stage_only
from .._validation import check_count, check_positive
from ..model_selection import HoldoutSearch
from ..regularizer import minimize_regularized
from .factorization import initialize_cameras
from .reconstruct import WIDTH_RULES, Reconstruction, reconstruct, solver_arguments, trace_norm_heuristic
from .reprojection import OrthographicReprojection, check_tracks
from .variables import CameraFrameVariables

__all__ = [
    "DEFAULT_TNH_TAUS",
    "visibility_folds",
    "point_entries",
    "TrackReconstruction",
    "search_points",
    "cv_table",
    "TNHTauSelection",
    "select_tnh_tau",
]

#: TNH tau grid (unit of the tracks squared): 7 log-spaced values over Table 4's search interval [0.1, 100].
DEFAULT_TNH_TAUS = tuple(float(t) for t in np.logspace(-1, 2, 7))

# --------------------------------------------------------------------------------------------------
# Folds, the score, and a reconstruction as an estimator of HoldoutSearch
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


def point_entries(hidden_points: np.ndarray) -> np.ndarray:
    """Hidden points (F, P) as hidden entries (F, 2P) of the tracks: both image coordinates."""
    return np.hstack([hidden_points, hidden_points])


def _point_error(W, W_hat, hidden) -> float:
    """HoldoutSearch's score: mean over the hidden points of ||w - R s||^2 (both coordinates), from
    the tracks W and a reconstruction's reprojections W_hat (F, 2P) and the hidden entries."""
    F, P = W.shape[0], W.shape[1] // 2
    squared = np.sum((W.reshape(F, 2, P) - W_hat.reshape(F, 2, P)) ** 2, axis=1)
    return float(squared[hidden[:, :P]].mean())


class TrackReconstruction(TransformerMixin, BaseEstimator):
    """A reconstruction as an imputer of image tracks, for :class:`~nldr.model_selection.HoldoutSearch`.

    ``fit(X)``: X (F, 2P) are the tracks with NaN at the unobserved points; ``transform`` returns the
    reprojections R_f s_f (F, 2P) of the fit on every point. ``prior="tnh"``: TNH with estimated
    cameras at ``tau`` from the rigid cameras of the observed points (``options``: the alternation's).
    ``prior="kernel"``: the kernel method at ``tau`` and ``width_multiple`` times the ``width_rule``
    of its start, minimize_regularized with the known ``cameras`` (``depth_scale``: camera-frame
    L-BFGS) or, with ``cameras=None``, Table 4's kernel stage (:func:`~nldr.nrsfm.reconstruct`);
    ``options`` are the regularizer's. ``start``: a mapping of the options of the start to compute
    (the known-camera TNH's; with estimated cameras those of :func:`select_tnh_tau`'s TNH, ``tau``
    included), or the start itself (a result with shapes ``x``, and cameras ``R`` if estimated).
    With ``warm_start`` and the same observed points as the previous fit, the start is reused, and a
    fit at the previous fit's width continues from its answer with the last penalty stage alone.
    Fitted: ``result_``, ``gamma_`` and ``move_``, the relative change of the start's shapes.
    """

    def __init__(self, prior="kernel", tau=1.0, width_multiple=1.0, width_rule="d_med", cameras=None,
                 start=None, options=None, depth_scale=None, warm_start=False):  # fmt: skip
        self.prior = prior
        self.tau = tau
        self.width_multiple = width_multiple
        self.width_rule = width_rule
        self.cameras = cameras
        self.start = start
        self.options = options
        self.depth_scale = depth_scale
        self.warm_start = warm_start

    def fit(self, X, y=None):
        X = np.asarray(X, dtype=np.float64)
        vis = ~np.isnan(X[:, : X.shape[1] // 2])
        W = np.where(np.isnan(X), 0.0, X)
        options = dict(self.options or {})
        if self.prior == "tnh":
            R0 = initialize_cameras(W, vis)
            self.result_ = reconstruct(W, vis, prior="tnh", tau=self.tau, initial_cameras=R0, **options)
            self.move_ = np.inf
            return self
        warm = self.warm_start and hasattr(self, "start_") and np.array_equal(self.visible_, vis)
        if not warm:
            self.start_ = self._start(W, vis)
        start, previous = self.start_, self.result_ if warm else None
        if previous is not None and self.width_multiple != self.fitted_width_:
            previous = None  # another width: from the start, with the full schedule
        if previous is not None and self.cameras is None:  # the last stage alone
            options.update(rho0=options.get("rho_max", 10.0), rho_max=options.get("rho_max", 10.0))
        self.gamma_ = gamma = float(self.width_multiple) * WIDTH_RULES[self.width_rule](start.x)
        if self.cameras is None:  # Table 4's kernel stage (from the previous answer, warm)
            self.result_ = reconstruct(
                W, vis, prior="kernel", tau=float(self.tau), width=gamma, start=previous or start, **options
            )
        else:
            if self.depth_scale is not None:  # the cameras are fixed: L-BFGS in their frames
                options["variables"] = CameraFrameVariables(self.cameras, vis, self.depth_scale)
            term, X0 = OrthographicReprojection(W, self.cameras, vis), (previous or start).x
            arguments = solver_arguments(options)
            if previous is not None:  # the last stage alone, in the full schedule's units
                arguments = last_stage_only(arguments)
            self.result_ = minimize_regularized(term, X0, gamma=gamma, tau=float(self.tau), **arguments)
        self.visible_, self.fitted_width_ = vis, self.width_multiple
        self.move_ = float(np.linalg.norm(self.result_.x - start.x) / np.linalg.norm(start.x))
        return self

    def _start(self, W, vis):
        if not isinstance(self.start, Mapping):
            return self.start
        options = dict(self.start)
        if self.cameras is not None:
            return trace_norm_heuristic(W, self.cameras, vis, **options)
        R0 = initialize_cameras(W, vis)
        return reconstruct(W, vis, prior="tnh", tau=options.pop("tau"), initial_cameras=R0, **options)

    def transform(self, X):
        """The reprojections (F, 2P) of the fit (whatever X: the fit's own tracks are completed)."""
        res = self.result_
        R = self.cameras if self.cameras is not None and self.prior == "kernel" else res.R
        return (R @ res.x.reshape(R.shape[0], 3, -1)).reshape(R.shape[0], -1)


def search_points(W, mask, folds, estimator, grid, n_jobs, **options) -> HoldoutSearch:
    """HoldoutSearch of ``estimator`` over ``grid`` on the tracks (NaN at unobserved points)."""
    X = np.where(point_entries(mask), W, np.nan)
    search = HoldoutSearch(
        estimator, grid, folds=[point_entries(h) for h in folds], scoring=_point_error, refit=False,
        n_jobs=n_jobs, **options,
    )  # fmt: skip
    return search.fit(X)


def cv_table(search, names) -> pd.DataFrame:
    """cv_results_ of a search as a DataFrame: ``names``, ``mean_test_error``, ``std_test_error``,
    ``fit_time`` and the rule's columns."""
    r = search.cv_results_
    out = pd.DataFrame({name: np.asarray(r[f"param_{name}"], dtype=np.float64) for name in names})
    out["mean_test_error"], out["std_test_error"] = r["mean_test_error"], r["std_test_error"]
    out["fit_time"] = r["mean_fit_time"]
    for extra in ("max_move", "active", "mean_diff_reference", "se_diff_reference"):
        if extra in r:
            out[extra] = r[extra]
    return out


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
        (sample sd over folds), ``fit_time`` (mean seconds of one fold solve).
    result_ : Reconstruction
        TNH with estimated cameras at ``tau_`` on every observed point, from ``rigid_cameras_``
        (:func:`~nldr.nrsfm.reconstruct`).
    rigid_cameras_ : array, shape (F, 2, 3)
        Rigid factorisation of every observed point (the refit's start).
    folds_ : list of bool arrays, shape (F, P)
        The hidden points of each fold.
    options_ : dict
        The alternation's options of the folds and the refit (:func:`select_kernel`'s fold starts).
    refit_time_ : float
        CPU seconds of the refit alone (rigid factorisation and one alternation): the cost of one solve.
    """

    tau_: float
    cv_results_: pd.DataFrame
    result_: Reconstruction
    rigid_cameras_: np.ndarray
    folds_: list
    options_: dict
    refit_time_: float

    def __repr__(self) -> str:
        n, k = len(self.cv_results_), len(self.folds_)
        return f"TNHTauSelection(tau_={self.tau_:.4g}, candidates={n}, folds={k})"


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
    (:func:`~nldr.nrsfm.factorization.initialize_cameras`), then for every tau TNH with estimated
    cameras from those cameras (:func:`~nldr.nrsfm.reconstruct` with ``prior="tnh"``: a cold start, to
    convergence), scored on the fold's hidden points. The tau of smallest mean score is refitted on
    every observed point from the rigid cameras of all of them: exactly one evaluation of Table 4's
    oracle search (then the camera search, with ``camera_search``, as Table 4 does at its tau*).

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
    estimator = TrackReconstruction(prior="tnh", options=dict(alternation_options))
    search = search_points(W, mask, folds, estimator, {"tau": taus.tolist()}, n_jobs)
    tau = float(search.best_params_["tau"])
    start = time.process_time()
    R0 = initialize_cameras(W, mask)
    result = reconstruct(
        W, mask, prior="tnh", tau=tau, initial_cameras=R0, camera_search=camera_search, **alternation_options
    )
    refit_time = time.process_time() - start
    cv = cv_table(search, ["tau"])
    return TNHTauSelection(tau, cv, result, R0, folds, dict(alternation_options), refit_time)
