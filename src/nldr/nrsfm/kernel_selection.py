"""Choosing the kernel method's tau and width for NRSfM from the image tracks alone.

Same folds and score as :mod:`nldr.nrsfm.selection` (hidden observed 2D points, their mean squared
reprojection error); nothing here sees the 3D ground truth.

:func:`select_kernel` chooses the kernel regularizer's tau and width (a multiple of the paper's
d_med or d_max rule, computed on the start shapes). By default it keeps the paper's values unless a
candidate beats them by more than one standard error of the paired fold differences, and it ignores
candidates at which the regularizer did not move its start (those score the start method, TNH, whose
linear completion of the image tracks the 2D score favours although it is worse in depth,
docs/REPRODUCTION.md#selection-nrsfm). With known cameras (Table 3) every fold starts from the
exact-fit TNH of its training points; after :func:`select_tnh_tau` (Table 4) every fold starts from
that fold's TNH at the selected tau, and every fold solve and the refit are Table 4's kernel stage:
cameras and shapes optimised jointly (:func:`~nldr.nrsfm.reconstruct` with estimated cameras; the
fold solves from one start each, the refit with the multistart of ``camera_options``).

Cost. The kernel candidates of one (fold, width) pair are solved along tau from the smallest up, each
after the first warm-started from its neighbour with the last penalty stage only (the argument of
:mod:`nldr.model_selection`); ``warm_start=False`` solves each from the fold's start with the full
schedule. Folds run in parallel with ``n_jobs``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from .._cv import positive_grid, run_jobs, summarise_folds
from .._validation import check_count, check_positive
from ..regularizer import minimize_regularized
from .reconstruct import WIDTH_RULES, reconstruct, solver_arguments
from .reprojection import OrthographicReprojection, check_cameras, check_tracks, reprojection_error
from .selection import TNHTauSelection, visibility_folds
from .tnh import trace_norm_heuristic
from .variables import CameraFrameVariables

__all__ = [
    "DEFAULT_KERNEL_TAUS",
    "PAPER_KERNEL",
    "MIN_MOVE",
    "WIDTH_MULTIPLES",
    "WIDTH_RULES",
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
        ``fit_time`` (mean CPU seconds per fold solve; warm-started candidates are cheaper),
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
        CPU seconds of the refit's kernel solve (or alternation) alone: the cost of one solve.
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


def _kernel_fold(W2d, train, hidden, R, start, rule, multiples, taus, warm_start, options, depth_scale):
    with threadpool_limits(1):
        X_start = start.x
        if R is not None:
            term = OrthographicReprojection(W2d, R, train)
            if depth_scale is not None:  # the fold's cameras are fixed: L-BFGS in their frames
                options = {**options, "variables": CameraFrameVariables(R, train, depth_scale)}
        rho_max = options.get("rho_max", 1e4 if R is not None else 10.0)
        base_gamma = WIDTH_RULES[rule](X_start)
        rows = []
        for m in multiples:
            previous = None
            for tau in taus:
                begin = time.process_time()
                stage = options
                if warm_start and previous is not None:
                    stage = {**options, "rho0": rho_max, "rho_max": rho_max}
                if R is None:  # Table 4's kernel stage from one start (the previous candidate's, warm)
                    res = reconstruct(
                        W2d, train, prior="kernel", tau=float(tau), width=m * base_gamma,
                        start=previous or start, multistart=False, **stage,
                    )  # fmt: skip
                else:
                    if stage is not options:  # the last stage alone, in the full schedule's units
                        stage = {"scale": float(np.sqrt(options.get("rho0", 1.0))), **stage}
                    X0 = X_start if previous is None else previous.x
                    res = minimize_regularized(
                        term, X0, gamma=m * base_gamma, tau=float(tau), **solver_arguments(stage)
                    )
                previous = res if warm_start else None
                error = reprojection_error(W2d, hidden, R if R is not None else res.R, res.x, mean=True)
                rows.append(
                    {
                        "tau": float(tau),
                        "width_multiple": float(m),
                        "test_error": error,
                        "fit_time": time.process_time() - begin,
                        "move": float(np.linalg.norm(res.x - X_start) / np.linalg.norm(X_start)),
                    }
                )
        return rows


def _choose_kernel(rows: list[dict], rule: str, reference, min_move: float):
    """Summarise the fold rows (each with its ``fold``) per candidate and pick one (see select_kernel):
    ``(cv_results, fold_scores, index of the choice)``."""
    frame = pd.DataFrame(rows)
    keys = ["width_multiple", "tau"]
    cv = summarise_folds(rows, keys)[
        ["tau", "width_multiple", "mean_test_error", "std_test_error", "fit_time"]
    ]
    by = frame.groupby(keys, sort=True)
    cv["max_move"] = by["move"].max().to_numpy()
    cv["active"] = cv["max_move"] >= min_move
    eligible = cv["active"].to_numpy() if cv["active"].any() else np.ones(len(cv), dtype=bool)
    mean = cv["mean_test_error"].to_numpy()
    scores = frame.pivot(index="fold", columns=keys, values="test_error").sort_index(axis=1)
    if rule == "min":
        return cv, scores, int(np.flatnonzero(eligible)[np.argmin(mean[eligible])])
    ref = np.flatnonzero(np.isclose(cv["tau"], reference[0]) & np.isclose(cv["width_multiple"], reference[1]))
    diff = scores.to_numpy() - scores.to_numpy()[:, [ref[0]]]  # (n_folds, n_candidates), paired by fold
    cv["mean_diff_reference"] = diff.mean(axis=0)
    cv["se_diff_reference"] = diff.std(axis=0, ddof=1) / np.sqrt(diff.shape[0])
    better = eligible & (cv["mean_diff_reference"] + cv["se_diff_reference"] < 0).to_numpy()
    if not better.any():
        return cv, scores, int(ref[0])
    return cv, scores, int(np.flatnonzero(better)[np.argmin(mean[better])])


def _known_camera_start(W2d, R, train, tnh_options):
    with threadpool_limits(1):
        return trace_norm_heuristic(W2d, R, train, **tnh_options)


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
        The paper's rule the multiples scale (:data:`WIDTH_RULES`).
    n_folds, holdout_fraction, random_state
        Folds of :func:`visibility_folds` (known cameras only; ``tnh`` brings its own).
    warm_start : bool, default True
        Solve each (fold, width) along tau, smallest first, warm-starting with the last penalty stage.
    rule : {"reference", "min"}, default "reference"
        "min": the eligible candidate with the smallest mean hold-out error. "reference": the
        ``reference`` candidate, unless eligible candidates beat it by more than one standard error
        of their per-fold (paired) score differences from it; then the one of those with the
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
        Run the fold solves (their cameras are fixed: ``R``, or each fold's TNH cameras) and, with
        ``R``, the refit in :class:`~nldr.nrsfm.CameraFrameVariables` with this scale: the same
        minimisers, far fewer L-BFGS iterations (docs/REPRODUCTION.md#table-3-solver). Default:
        L-BFGS on the shapes themselves.
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
    multiples = positive_grid(
        WIDTH_MULTIPLES if width_multiples is None else width_multiples, "width_multiples"
    )
    if rule not in ("reference", "min"):
        raise ValueError(f"rule must be 'reference' or 'min'; got {rule!r}")
    if rule == "reference":
        if np.shape(reference) != (2,):
            raise ValueError(f"reference must be a pair (tau, width_multiple); got {reference!r}")
        if not (np.isclose(taus, reference[0]).any() and np.isclose(multiples, reference[1]).any()):
            raise ValueError(
                f"reference {tuple(reference)} must be on the grid: tau in {taus.tolist()}, "
                f"width multiple in {multiples.tolist()}"
            )
    min_move = float(min_move)
    if not (np.isfinite(min_move) and min_move >= 0):
        raise ValueError(f"min_move must be finite and >= 0; got {min_move}")
    W2d = W
    if R is not None:
        R = check_cameras(R, mask.shape[0])
        tnh_options = dict(tnh_options or {})
        folds = visibility_folds(mask, n_folds, random_state, holdout_fraction=holdout_fraction)
        starts = run_jobs([(_known_camera_start, (W2d, R, mask & ~h, tnh_options)) for h in folds], n_jobs)
        fold_cameras = [R] * len(folds)
    else:
        if tnh.folds_[0].shape != mask.shape or np.any(tnh.folds_[0] & ~mask):
            raise ValueError("tnh was selected on another mask; pass the mask of select_tnh_tau")
        folds = tnh.folds_
        starts = list(tnh.fold_results_)
        fold_cameras = [None] * len(folds)  # estimated, by every fold solve
    args = [
        (W2d, mask & ~h, h, Rk, Xk, width_rule, multiples, taus, warm_start, regularizer_options, depth_scale)
        for h, Rk, Xk in zip(folds, fold_cameras, starts, strict=True)
    ]
    per_fold = run_jobs([(_kernel_fold, a) for a in args], n_jobs)
    rows = [{**row, "fold": k} for k, fold in enumerate(per_fold) for row in fold]
    cv, scores, best = _choose_kernel(rows, rule, reference, min_move)
    tau, multiple = float(cv["tau"].iloc[best]), float(cv["width_multiple"].iloc[best])
    if R is not None:
        if X_start is None:
            X0 = _known_camera_start(W2d, R, mask, tnh_options).x
        else:
            X0 = np.asarray(X_start, dtype=np.float64)
            if X0.shape != (mask.shape[0], 3 * mask.shape[1]):
                raise ValueError(f"X_start must have shape (F, 3P) = {(mask.shape[0], 3 * mask.shape[1])}")
        gamma = multiple * WIDTH_RULES[width_rule](X0)
        refit = dict(regularizer_options)
        if depth_scale is not None:
            refit["variables"] = CameraFrameVariables(R, mask, depth_scale)
        begin = time.process_time()
        term = OrthographicReprojection(W2d, R, mask)
        result = minimize_regularized(term, X0, gamma=gamma, tau=tau, **solver_arguments(refit))
        start = (R, X0)
    else:
        R0, X0 = tnh.result_.R, tnh.result_.x
        gamma = multiple * WIDTH_RULES[width_rule](X0)
        begin = time.process_time()
        result = reconstruct(
            W2d, mask, prior="kernel", tau=tau, width=gamma, start=tnh.result_,
            **dict(camera_options or {}), **regularizer_options,
        )  # fmt: skip
        start = (R0, X0)
    return KernelSelection(
        tau, multiple, gamma, cv, scores, result, folds, start, time.process_time() - begin
    )
