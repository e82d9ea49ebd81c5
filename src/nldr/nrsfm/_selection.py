"""Choosing NRSfM parameters from the image tracks alone: hold-out cross-validation of 2D points.

The paper fixes the kernel method's tau (1e-4) and width (the d_max / d_med rules) by hand, and tunes
the Table 4 TNH baseline's tau on the 3D error against ground truth (an oracle). Here each fold hides a
random share of the *observed* 2D points (both image coordinates), the method reconstructs from the
rest, and the fold's score is the mean squared reprojection error of the hidden points, ``mean
||w_f(x_j) - R_f s_f(x_j)||^2`` (squared unit of the tracks), invariant to the global gauge. Nothing
here sees the 3D ground truth.

The search is :class:`nldr.model_selection.HoldoutSearch` with the 2D points as its entries: the tracks
(F, 2P) with NaN at unobserved points are the matrix, and each candidate is a reconstruction
(:func:`~nldr.nrsfm.reconstruct`, the method the tables report) whose completion of W is its
reprojection R_f s_f of every point.

- :func:`visibility_folds`: the hidden points of each fold (same seed, same folds);
- :func:`select_tnh_tau`: TNH's tau with cameras estimated (Table 4's pipeline);
- :func:`select_kernel`: the kernel method's tau and width, with known cameras (Table 3) or after
  :func:`select_tnh_tau` (Table 4's kernel stage), keeping the paper's values unless the evidence is
  against them. The candidates of one (fold, width) are solved along tau from the smallest up, each
  warm-started from its neighbour with the last penalty stage only; a fold computes its start once.

Layouts as in :mod:`nldr.nrsfm._layout`; folds run in parallel with ``n_jobs``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, TransformerMixin

from .._cv import positive_grid
from .._options import last_stage_only
from .._validation import check_count, check_positive
from ..model_selection import HoldoutSearch
from ._factorization import initialize_cameras
from ._layout import visibility_folds
from ._reconstruct import WIDTH_RULES, Reconstruction, reconstruct, solver_arguments, trace_norm_heuristic
from ._reprojection import check_cameras, check_tracks

__all__ = [
    "DEFAULT_TNH_TAUS",
    "DEFAULT_KERNEL_TAUS",
    "PAPER_KERNEL",
    "MIN_MOVE",
    "WIDTH_MULTIPLES",
    "visibility_folds",
    "TrackReconstruction",
    "NRSfMSelection",
    "select_tnh_tau",
    "select_kernel",
]

#: TNH tau grid (unit of the tracks squared): 7 log-spaced values over Table 4's search interval [0.1, 100].
DEFAULT_TNH_TAUS = tuple(float(t) for t in np.logspace(-1, 2, 7))
#: Kernel tau grid: the paper's 1e-4 and half a decade either side, then 1e-3. Not 1e-5: with the paper's
#: schedule (rho up to 10) the solve at 1e-5 stops at its start, the TNH (the regularizer's gradient is
#: under L-BFGS's gtol; docs/REPRODUCTION.md#selection-nrsfm), so it is TNH, not a kernel candidate.
DEFAULT_KERNEL_TAUS = (3e-5, 1e-4, 3e-4, 1e-3)
#: The paper's kernel values as (tau, width multiple): the reference of ``rule="reference"``.
PAPER_KERNEL = (1e-4, 1.0)
#: A candidate whose fold solves all moved their start by less than this (relative Frobenius norm) is
#: inactive: the regularizer did not act, the "solution" is the start method's.
MIN_MOVE = 1e-3
#: Kernel widths as multiples of the width rule's gamma (0.5: wider kernel, 2: narrower).
WIDTH_MULTIPLES = (0.5, 1.0, 2.0)


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
    reprojections R_f s_f (F, 2P) of the fit on every point. Both priors run
    :func:`~nldr.nrsfm.reconstruct` with ``options``: ``prior="tnh"`` with estimated cameras at ``tau``
    from the rigid cameras of the observed points; ``prior="kernel"`` at ``tau`` and ``width_multiple``
    times the ``width_rule`` of its start, with the known ``cameras`` (``depth_scale``: camera-frame
    L-BFGS) or, with ``cameras=None``, estimated ones (Table 4's kernel stage). ``start``: a mapping of
    the options of the start to compute (the known-camera TNH's; with estimated cameras those of
    :func:`select_tnh_tau`'s TNH, ``tau`` included), or the start itself (shapes ``x``, and cameras
    ``R`` if estimated). With ``warm_start`` and the same observed points as the previous fit, the start
    is reused, and a fit at the previous width continues from its answer with the last penalty stage
    alone. Fitted: ``result_``, ``gamma_`` and ``move_``, the relative change of the start's shapes.
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
            self.result_ = reconstruct(W, vis, prior="tnh", tau=self.tau, **options)  # from the rigid cameras
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
        elif previous is not None:  # the last stage alone, in the full schedule's units
            options = last_stage_only(solver_arguments(options))
        if self.cameras is not None and self.depth_scale is not None:  # L-BFGS in the cameras' frames
            options["depth_scale"] = self.depth_scale
        self.gamma_ = gamma = float(self.width_multiple) * WIDTH_RULES[self.width_rule](start.x)
        self.result_ = reconstruct(
            W, vis, cameras="estimate" if self.cameras is None else self.cameras, prior="kernel",
            tau=float(self.tau), width=gamma, start=previous or start, **options,
        )  # fmt: skip
        self.visible_, self.fitted_width_ = vis, self.width_multiple
        self.move_ = float(np.linalg.norm(self.result_.x - start.x) / np.linalg.norm(start.x))
        return self

    def _start(self, W, vis):
        if not isinstance(self.start, Mapping):
            return self.start
        cameras = "estimate" if self.cameras is None else self.cameras
        return reconstruct(W, vis, cameras=cameras, prior="tnh", **dict(self.start))

    def transform(self, X):
        """The reprojections (F, 2P) of the fit (whatever X: the fit's own tracks are completed)."""
        R = self.result_.R
        return (R @ self.result_.x.reshape(R.shape[0], 3, -1)).reshape(R.shape[0], -1)


def search_points(W, mask, folds, estimator, grid, n_jobs, **options) -> HoldoutSearch:
    """HoldoutSearch of ``estimator`` over ``grid`` on the tracks (NaN at unobserved points)."""
    X = np.where(point_entries(mask), W, np.nan)
    search = HoldoutSearch(
        estimator, grid, folds=[point_entries(h) for h in folds], scoring=_point_error, refit=False,
        n_jobs=n_jobs, **options,
    )  # fmt: skip
    return search.fit(X)


@dataclass(repr=False)
class NRSfMSelection:
    """Outcome of :func:`select_tnh_tau` (TNH's tau) and :func:`select_kernel` (the kernel method's).

    Attributes
    ----------
    tau_ : float
        The chosen weight: TNH's (unit of the tracks squared) or the kernel method's trace-norm weight.
    width_multiple_, gamma_ : float
        :func:`select_kernel`: the chosen multiple of the width rule, and the refit's gamma (1 / unit of
        the tracks squared); NaN after :func:`select_tnh_tau`.
    cv_results_ : DataFrame
        One row per candidate (TNH by tau; kernel by width multiple, then tau): ``tau``,
        ``width_multiple``, ``mean_test_error`` and ``std_test_error`` (mean and sample sd over folds of
        the hidden points' mean squared reprojection error, unit of the tracks squared), ``fit_time``
        (mean seconds of a fold solve); the kernel's also ``max_move`` (largest relative change of the
        start shapes over the folds), ``active`` and, with ``rule="reference"``, ``mean_diff_reference``
        and ``se_diff_reference`` (paired differences from the reference in the same fold).
    fold_scores_ : DataFrame, shape (n_folds, n_candidates)
        The score of every candidate (columns as the rows of ``cv_results_``) in every fold.
    result_, folds_ : Reconstruction, list of bool arrays (F, P)
        The refit on every observed point at the chosen values; the hidden points of each fold.
    start_ : (R, X)
        Cameras (F, 2, 3) and shapes (F, 3P) the refit started from (TNH: the rigid cameras, no shapes).
    options_ : dict
        TNH: the alternation's options of the folds and the refit (:func:`select_kernel`'s fold starts).
    refit_time_ : float
        CPU time of the refit alone (seconds): the cost of one solve.
    """

    tau_: float
    width_multiple_: float
    gamma_: float
    cv_results_: pd.DataFrame
    fold_scores_: pd.DataFrame
    result_: Reconstruction
    folds_: list
    start_: tuple
    options_: dict
    refit_time_: float

    def __repr__(self) -> str:
        return (
            f"NRSfMSelection(tau_={self.tau_:.4g}, width_multiple_={self.width_multiple_:g}, "
            f"gamma_={self.gamma_:.4g}, candidates={len(self.cv_results_)}, folds={len(self.folds_)})"
        )


def _outcome(search, names, folds, **fields) -> NRSfMSelection:
    """The selection of a finished search over ``names``: its cv_results_ as a DataFrame and the
    fold scores, with the refit's ``fields``."""
    r = search.cv_results_
    cv = pd.DataFrame({name: np.asarray(r[f"param_{name}"], dtype=np.float64) for name in names})
    cv["mean_test_error"], cv["std_test_error"] = r["mean_test_error"], r["std_test_error"]
    cv["fit_time"] = r["mean_fit_time"]
    for extra in ("max_move", "active", "mean_diff_reference", "se_diff_reference"):
        if extra in r:
            cv[extra] = r[extra]
    columns = pd.MultiIndex.from_arrays([cv[name] for name in names[::-1]], names=names[::-1])
    splits = [r[f"split{k}_test_error"] for k in range(len(folds))]
    scores = pd.DataFrame(np.array(splits), columns=columns).rename_axis(index="fold")
    return NRSfMSelection(cv_results_=cv, fold_scores_=scores, folds_=folds, **fields)


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
) -> NRSfMSelection:
    """Choose TNH's tau for NRSfM with unknown cameras by hold-out reprojection error.

    Per fold and tau: TNH with estimated cameras (:func:`~nldr.nrsfm.reconstruct`, cold start, to
    convergence) from the rigid cameras of the training points, scored on the fold's hidden points. The
    tau of smallest mean score is refitted on every observed point: one evaluation of Table 4's oracle
    search (then the camera search, with ``camera_search``, as Table 4 does at its tau*).

    Parameters
    ----------
    W2d, mask : arrays (F, 2P) and (F, P), optional
        Centred tracks and visibility (:mod:`nldr.nrsfm._layout`; default all observed).
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
    NRSfMSelection
        ``result_`` TNH with estimated cameras at ``tau_`` on every observed point, from the rigid
        cameras ``start_[0]``. Ties go to the smallest tau.
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
    return _outcome(
        search, ["tau"], folds, tau_=tau, width_multiple_=np.nan, gamma_=np.nan, result_=result,
        start_=(R0, None), options_=dict(alternation_options), refit_time_=refit_time,
    )  # fmt: skip


def select_kernel(
    W2d,
    mask=None,
    *,
    R=None,
    tnh: NRSfMSelection | None = None,
    taus=None,
    width_multiples=None,
    width_rule: str = "d_med",
    n_folds: int = 3,
    holdout_fraction: float | None = None,
    random_state=0,
    warm_start: bool = True,
    rule: str = "reference",
    reference=PAPER_KERNEL,
    min_move: float = MIN_MOVE,
    tnh_options: Mapping | None = None,
    X_start=None,
    camera_options: Mapping | None = None,
    depth_scale: float | None = None,
    n_jobs: int = 1,
    **regularizer_options,
) -> NRSfMSelection:
    """Choose the kernel regularizer's tau and width for NRSfM by hold-out reprojection error.

    Give exactly one of ``R`` (known cameras, Table 3) or ``tnh`` (a :func:`select_tnh_tau` result,
    Table 4). Candidate gammas are ``width_multiples`` times the ``width_rule`` on each fold's start
    shapes, so the chosen quantity is the multiple; the refit applies it to its own start.

    Parameters
    ----------
    W2d, mask
        As in :func:`select_tnh_tau`; with ``tnh``, the mask it was selected on.
    R : array, shape (F, 2, 3), optional
        Known cameras. Each fold (and the refit) starts from the exact-fit TNH of its training points
        (:func:`~nldr.nrsfm._reconstruct.trace_norm_heuristic` with ``tnh_options``).
    tnh : NRSfMSelection, optional
        Unknown cameras: its folds are reused, each fold starts from that fold's TNH (cameras and shapes)
        at the selected tau; every fold solve and the refit (from ``tnh.result_``) optimise cameras and
        shapes jointly (:func:`~nldr.nrsfm.reconstruct`, the fold solves from one start each, the refit
        with ``camera_options``, e.g. ``multistart``).
    taus, width_multiples : sequences of float > 0, optional
        Defaults :data:`DEFAULT_KERNEL_TAUS` and :data:`WIDTH_MULTIPLES`.
    width_rule : {"d_med", "d_max"}, default "d_med"
        The paper's rule the multiples scale (:data:`~nldr.nrsfm._reconstruct.WIDTH_RULES`).
    n_folds, holdout_fraction, random_state, n_jobs
        As in :func:`select_tnh_tau` (the folds with known cameras only; ``tnh`` brings its own).
    warm_start : bool, default True
        Solve each (fold, width) along tau, smallest first, warm-starting with the last penalty stage.
    rule : {"reference", "min"}, default "reference"
        HoldoutSearch's rule over the eligible candidates. "min": the smallest mean hold-out error.
        "reference": the ``reference`` candidate, unless candidates beat it by more than one standard
        error of their per-fold (paired) score differences from it; then the one of those with the
        smallest mean (the score's spread over folds exceeds the candidates' differences:
        docs/REPRODUCTION.md#selection-nrsfm).
    reference : (tau, width_multiple), default :data:`PAPER_KERNEL`
        The default of ``rule="reference"`` (the paper's tau and width rule); must be on the grid.
    min_move : float >= 0, default :data:`MIN_MOVE`
        A candidate whose solve moved the start shapes by less than ``min_move`` (relative Frobenius
        norm) in every fold is inactive (its score is the start's, TNH's) and not eligible, unless no
        candidate is active.
    tnh_options : mapping, optional
        Options of the known-camera TNH (default: exact fit by ADMM).
    X_start : array, shape (F, 3P), optional
        With ``R``: the refit's start, the TNH on every observed point with ``tnh_options``, when the
        caller has it already (default: computed here).
    camera_options : mapping, optional
        With ``tnh``: options of the refit alone (e.g. ``multistart``).
    depth_scale : float > 0, optional
        With ``R``, the fold solves and the refit in :class:`~nldr.nrsfm.CameraFrameVariables` with this
        scale (the same minimisers, far fewer L-BFGS iterations; docs/REPRODUCTION.md#table-3-solver).
    **regularizer_options
        Passed to :func:`~nldr.regularizer.minimize_regularized` (``rho0, rho_growth, rho_max, center,
        max_inner, ...``) in the folds and the refit.

    Returns
    -------
    NRSfMSelection
        ``result_`` the kernel method's refit (known or, after :func:`select_tnh_tau`, estimated
        cameras). Ties go to the first row of ``cv_results_`` (smaller width multiple, then smaller tau).
    """
    W, mask = check_tracks(W2d, mask)
    if (R is None) == (tnh is None):
        raise ValueError("give exactly one of R (known cameras) or tnh (a select_tnh_tau result)")
    if width_rule not in WIDTH_RULES:
        raise ValueError(f"width_rule must be one of {tuple(WIDTH_RULES)}; got {width_rule!r}")
    for key in sorted({"gamma", "tau", "variables"} & set(regularizer_options)):
        raise ValueError(
            f"regularizer option {key!r} is set by select_kernel; remove it (or use depth_scale)"
        )
    if depth_scale is not None:
        depth_scale = check_positive(depth_scale, "depth_scale")
    n_jobs = check_count(n_jobs, "n_jobs")
    taus = positive_grid(DEFAULT_KERNEL_TAUS if taus is None else taus, "taus")
    multiples = positive_grid(
        WIDTH_MULTIPLES if width_multiples is None else width_multiples, "width_multiples"
    )
    if rule not in ("reference", "min"):
        raise ValueError(f"rule must be 'reference' or 'min'; got {rule!r}")
    search_rule = {"rule": rule}
    if rule == "reference":
        if np.shape(reference) != (2,):
            raise ValueError(f"reference must be a pair (tau, width_multiple); got {reference!r}")
        search_rule["reference"] = {"tau": float(reference[0]), "width_multiple": float(reference[1])}
    if R is not None:
        R = check_cameras(R, mask.shape[0])
        tnh_options = dict(tnh_options or {})
        folds = visibility_folds(mask, n_folds, random_state, holdout_fraction=holdout_fraction)
        start, fold_options = tnh_options, dict(regularizer_options)
    else:
        if tnh.folds_[0].shape != mask.shape or np.any(tnh.folds_[0] & ~mask):
            raise ValueError("tnh was selected on another mask; pass the mask of select_tnh_tau")
        folds, start = tnh.folds_, {"tau": tnh.tau_, **tnh.options_}
        fold_options = {"multistart": False, **regularizer_options}  # the fold solves: one start each
    estimator = TrackReconstruction(
        width_rule=width_rule, cameras=R, start=start, options=fold_options, depth_scale=depth_scale
    )
    grid = [{"width_multiple": [float(m)], "tau": taus.tolist()} for m in multiples]
    path = {"path": "tau"} if warm_start else {}
    search = search_points(W, mask, folds, estimator, grid, n_jobs, min_move=min_move, **search_rule, **path)
    best = search.best_params_
    if R is not None:  # the refit from the TNH of every observed point
        X0 = trace_norm_heuristic(W, mask, R, **tnh_options).x if X_start is None else X_start
        X0 = np.asarray(X0, dtype=np.float64)
        if X0.shape != (mask.shape[0], 3 * mask.shape[1]):
            raise ValueError(f"X_start must have shape (F, 3P) = {(mask.shape[0], 3 * mask.shape[1])}")
        refit = estimator.set_params(start=SimpleNamespace(x=X0), **best)
    else:  # from the TNH refit, with camera_options
        options = {**dict(camera_options or {}), **regularizer_options}
        refit = estimator.set_params(start=tnh.result_, options=options, **best)
    begin = time.process_time()
    refit.fit(np.where(point_entries(mask), W, np.nan))
    seconds = time.process_time() - begin
    return _outcome(
        search, ["tau", "width_multiple"], folds, tau_=float(best["tau"]),
        width_multiple_=float(best["width_multiple"]), gamma_=refit.gamma_, result_=refit.result_,
        start_=(R if R is not None else tnh.result_.R, refit.start_.x), options_={}, refit_time_=seconds,
    )  # fmt: skip
