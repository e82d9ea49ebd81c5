"""Choosing the kernel method's tau and width for NRSfM from the image tracks alone.

Same folds, score and search as :mod:`nldr.nrsfm.selection` (hidden observed 2D points, their mean
squared reprojection error, :class:`~nldr.model_selection.HoldoutSearch`); nothing here sees the 3D
ground truth. The kernel candidates of one (fold, width) pair are solved along tau from the smallest
up, each after the first warm-started from its neighbour with the last penalty stage only
(HoldoutSearch's ``path``); a fold computes its start once.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pandas as pd

from .._cv import positive_grid
from .._validation import check_count, check_positive
from .reconstruct import WIDTH_RULES, trace_norm_heuristic
from .reprojection import check_cameras, check_tracks
from .selection import (
    TNHTauSelection,
    TrackReconstruction,
    cv_table,
    point_entries,
    search_points,
    visibility_folds,
)

__all__ = [
    "DEFAULT_KERNEL_TAUS",
    "PAPER_KERNEL",
    "MIN_MOVE",
    "WIDTH_MULTIPLES",
    "KernelSelection",
    "select_kernel",
]

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


# --------------------------------------------------------------------------------------------------
# The kernel regularizer's tau and width (Tables 3 and 4)
# --------------------------------------------------------------------------------------------------


@dataclass(repr=False)
class KernelSelection:
    """Outcome of :func:`select_kernel`.

    Attributes
    ----------
    tau_ : float
        The chosen trace-norm weight.
    width_multiple_ : float
        The chosen multiple of the width rule's gamma.
    gamma_ : float
        ``width_multiple_`` times the rule on the refit's start shapes (1 / unit of the tracks squared).
    cv_results_ : DataFrame
        One row per candidate, by width multiple then tau: ``tau, width_multiple, mean_test_error``
        (mean squared hidden reprojection error, unit of the tracks squared), ``std_test_error``,
        ``fit_time`` (mean seconds per fold solve; warm-started candidates are cheaper),
        ``max_move`` (largest relative change of the start shapes over the folds), ``active``
        (``max_move >= min_move``); with ``rule="reference"`` also ``mean_diff_reference`` and
        ``se_diff_reference``: mean and standard error over folds of the score minus the
        reference's score in the same fold.
    result_ : RegularizerResult or Reconstruction
        The refit on every observed point: the regularizer with the known cameras, or (after
        :func:`select_tnh_tau`) Table 4's kernel stage, which also has cameras ``R``.
    fold_scores_ : DataFrame, shape (n_folds, n_candidates)
        Hold-out score of every candidate (columns: (width_multiple, tau), as the rows of
        ``cv_results_``) in every fold (rows): the paired values behind ``rule="reference"``.
    folds_ : list of bool arrays, shape (F, P)
    start_ : (R, X)
        Cameras (F, 2, 3) and shapes (F, 3P) the refit started from.
    refit_time_ : float
        CPU seconds of the refit's kernel solve alone: the cost of one solve.
    """

    tau_: float
    width_multiple_: float
    gamma_: float
    cv_results_: pd.DataFrame
    fold_scores_: pd.DataFrame
    result_: object
    folds_: list
    start_: tuple
    refit_time_: float

    def __repr__(self) -> str:
        return (
            f"KernelSelection(tau_={self.tau_:.4g}, width_multiple_={self.width_multiple_:g}, "
            f"gamma_={self.gamma_:.4g}, candidates={len(self.cv_results_)})"
        )


def select_kernel(
    W2d,
    mask=None,
    *,
    R=None,
    tnh: TNHTauSelection | None = None,
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
) -> KernelSelection:
    """Choose the kernel regularizer's tau and width for NRSfM by hold-out reprojection error.

    Give exactly one of ``R`` (known cameras, Table 3) or ``tnh`` (a :func:`select_tnh_tau` result,
    Table 4). Candidate gammas are ``width_multiples`` times the ``width_rule`` on each fold's start
    shapes, so the chosen quantity is the multiple; the refit applies it to its own start.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Centred image tracks as rows.
    mask : bool array, shape (F, P), optional
        Visibility; default all observed. With ``tnh``, must be the mask it was selected on.
    R : array, shape (F, 2, 3), optional
        Known cameras. Each fold (and the refit) starts from the exact-fit TNH of its training points
        (:func:`~nldr.nrsfm.trace_norm_heuristic` with ``tnh_options``).
    tnh : TNHTauSelection, optional
        Unknown cameras: its folds are reused, each fold starts from that fold's TNH (cameras and shapes)
        at the selected tau; every fold solve and the refit (from ``tnh.result_``) optimise cameras and
        shapes jointly (:func:`~nldr.nrsfm.reconstruct`, the fold solves from one start each, the refit
        with ``camera_options``, e.g. ``multistart``).
    taus : sequence of float > 0, optional
        Default :data:`DEFAULT_KERNEL_TAUS`.
    width_multiples : sequence of float > 0, optional
        Default :data:`WIDTH_MULTIPLES`.
    width_rule : {"d_med", "d_max"}, default "d_med"
        The paper's rule the multiples scale (:data:`~nldr.nrsfm.reconstruct.WIDTH_RULES`).
    n_folds, holdout_fraction, random_state
        Folds of :func:`visibility_folds` (known cameras only; ``tnh`` brings its own).
    warm_start : bool, default True
        Solve each (fold, width) along tau, smallest first, warm-starting with the last penalty stage.
    rule : {"reference", "min"}, default "reference"
        HoldoutSearch's rule over the eligible candidates. "min": the smallest mean hold-out error.
        "reference": the ``reference`` candidate, unless candidates beat it by more than one standard
        error of their per-fold (paired) score differences from it; then the one of those with the
        smallest mean. The hold-out score of 2D points separates the candidates by a few percent,
        less than its spread over folds (docs/REPRODUCTION.md#selection-nrsfm), so "min" follows
        the noise; "reference" leaves a default only on evidence.
    reference : (tau, width_multiple), default :data:`PAPER_KERNEL`
        The default of ``rule="reference"`` (the paper's tau and width rule); must be on the grid.
    min_move : float >= 0, default :data:`MIN_MOVE`
        A candidate whose solve moved the start shapes by less than ``min_move`` (relative Frobenius
        norm) in every fold is inactive and not eligible: the regularizer did not act, so its score
        is the start method's (TNH), not the kernel method's. All candidates are eligible if none is
        active.
    tnh_options : mapping, optional
        Options of the known-camera TNH (default: exact fit by ADMM).
    X_start : array, shape (F, 3P), optional
        With ``R``: the refit's start, the TNH on every observed point with ``tnh_options``, when the
        caller has it already (default: computed here).
    depth_scale : float > 0, optional
        With ``R``, run the fold solves and the refit in :class:`~nldr.nrsfm.CameraFrameVariables`
        with this scale: the same minimisers, far fewer L-BFGS iterations
        (docs/REPRODUCTION.md#table-3-solver). Default: L-BFGS on the shapes themselves.
    n_jobs : int >= 1
        Processes over the folds.
    **regularizer_options
        Passed to :func:`~nldr.regularizer.minimize_regularized` (``rho0, rho_growth, rho_max, center,
        max_inner, ...``) in the folds and the refit.

    Returns
    -------
    KernelSelection
        Ties go to the first row of ``cv_results_`` (smaller width multiple, then smaller tau).
    """
    W, mask = check_tracks(W2d, mask)
    if (R is None) == (tnh is None):
        raise ValueError("give exactly one of R (known cameras) or tnh (a select_tnh_tau result)")
    if width_rule not in WIDTH_RULES:
        raise ValueError(f"width_rule must be one of {tuple(WIDTH_RULES)}; got {width_rule!r}")
    for key in ("gamma", "tau"):
        if key in regularizer_options:
            raise ValueError(f"regularizer option {key!r} is set by select_kernel; remove it")
    if "variables" in regularizer_options:
        raise ValueError("regularizer option 'variables' is set by select_kernel (use depth_scale)")
    if depth_scale is not None:
        depth_scale = check_positive(depth_scale, "depth_scale")
    n_jobs = check_count(n_jobs, "n_jobs")
    taus = positive_grid(DEFAULT_KERNEL_TAUS if taus is None else taus, "taus")
    multiples = WIDTH_MULTIPLES if width_multiples is None else width_multiples
    multiples = positive_grid(multiples, "width_multiples")
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
    cv = cv_table(search, ["tau", "width_multiple"])
    columns = pd.MultiIndex.from_arrays([cv["width_multiple"], cv["tau"]], names=["width_multiple", "tau"])
    splits = [search.cv_results_[f"split{k}_test_error"] for k in range(len(folds))]
    scores = pd.DataFrame(np.array(splits), columns=columns).rename_axis(index="fold")
    best = search.best_params_
    if R is not None:  # the refit from the TNH of every observed point
        X0 = trace_norm_heuristic(W, R, mask, **tnh_options).x if X_start is None else X_start
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
    start = (R if R is not None else tnh.result_.R, refit.start_.x)
    return KernelSelection(
        float(best["tau"]), float(best["width_multiple"]), refit.gamma_, cv, scores, refit.result_, folds,
        start, seconds,
    )  # fmt: skip
