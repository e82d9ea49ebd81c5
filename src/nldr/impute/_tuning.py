"""The :class:`~nldr.impute.KernelRegularizerImputer`'s own searches, as functions of the estimator:
gamma and tau by hold-out folds of the observed entries (:func:`tune`), ``transform``'s
(n_neighbors, starts) by row folds of the training rows (:func:`tune_transform`), and the report of
a choice that predicts hidden entries no better than the column means (:func:`report_holdout`).

Both searches run on the rows in their canonical order (:func:`~nldr.impute._base.canonical_row_order`)
with folds from the estimator's ``_tune_seed()``, so what they choose depends on the data only.
"""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.exceptions import ConvergenceWarning

from ..model_selection import HoldoutSearch
from ..result import INACCURATE
from ._base import canonical_row_order
from ._defaults import (
    TUNE_FOLDS,
    TUNE_HOLDOUT,
    TUNE_ROW_HIDDEN,
    TUNE_ROW_SHARE,
    TUNE_STOP_FACTOR,
    TUNE_TRANSFORM,
)
from ._new_rows import row_folds, search_transform_knobs

__all__ = ["is_auto", "mean_fill_holdout", "report_holdout", "transform_candidates", "tune", "tune_transform"]


def is_auto(value) -> bool:
    """Whether a knob is ``"auto"`` (searched, or set by the data and the solver path)."""
    return isinstance(value, str) and value == "auto"


def tune(est, W, mask, grid: dict) -> dict:
    """Choose gamma and tau among ``grid`` by the hold-out search on the observed entries of W.

    :class:`~nldr.model_selection.HoldoutSearch` with :data:`TUNE_FOLDS` Monte-Carlo folds, each
    hiding :data:`TUNE_HOLDOUT` of the observed entries (drawn from seed 0 on the rows in their
    canonical order, :func:`~nldr.impute._base.canonical_row_order`, so the choice does not depend
    on the order of the rows or on ``random_state``),
    the candidates of a fold solved as warm-started paths along tau from the smallest up (one
    cold solve per fold), looser tolerances, and the Nystroem kernel above
    :data:`AUTO_EXACT_MAX_ROWS` rows; the smallest mean squared hold-out error wins (in the units
    of W: standardised when ``standardize``). Returns the chosen ``{"gamma", "tau"}`` and sets
    ``cv_results_`` (its folds index the rows in canonical order), and ``_holdout_against_means``
    to (the choice's error, the column means' error on the same folds)."""
    seed = est._tune_seed()
    base = est.get_params()
    base.update(gamma=grid["gamma"][0], tau=grid["tau"][0], warm_start=False, verbose=False)
    base.update(n_neighbors=TUNE_TRANSFORM[1][0], starts="mean")  # transform is not scored here
    estimator = type(est)(**base)
    fold_params = est._fold_solver(W.shape[0])
    search = HoldoutSearch(
        estimator,
        grid,
        n_folds=TUNE_FOLDS,
        holdout=TUNE_HOLDOUT,
        random_state=seed,
        path="tau",
        stop_factor=TUNE_STOP_FACTOR,
        fold_params=fold_params,
        refit=False,
        verbose=bool(est.verbose),
    )
    order = canonical_row_order(W, mask)
    with warnings.catch_warnings():  # a fold's mean fill is the search's business, scored as such
        warnings.simplefilter("ignore", ConvergenceWarning)
        search.fit(np.where(mask, W, np.nan)[order])
    est.cv_results_ = search.cv_results_
    means = mean_fill_holdout(W[order], mask[order], search.folds_)
    est._holdout_against_means = (float(search.best_score_), means)
    return dict(search.best_params_)


def transform_candidates(est) -> list[tuple[int, str]]:
    """The (n_neighbors, starts) pairs the row folds compare: the "auto" ones over their grid."""
    pairs = [c for c in TUNE_TRANSFORM if is_auto(est.n_neighbors) or c[0] == est.n_neighbors]
    pairs = [c for c in pairs if est.starts == "auto" or c[1] == est.starts]
    if not pairs:  # a fixed n_neighbors or starts outside the grid
        k = TUNE_TRANSFORM[1][0] if is_auto(est.n_neighbors) else int(est.n_neighbors)
        pairs = [(k, s) for s in ("mean", "each") if est.starts in ("auto", s)]
    return pairs


def tune_transform(est, W, mask, gamma: float, tau: float) -> tuple[int, str]:
    """Choose ``transform``'s (n_neighbors, starts) by :data:`TUNE_FOLDS` row folds of the training rows.

    Each fold (:func:`~nldr.impute._new_rows.row_folds`, seed 0, rows in canonical order) fits the
    manifold (at ``gamma``, ``tau``, the tuning's fold solver) on the other rows, hides a share (the
    training matrix's missing share, at least :data:`TUNE_ROW_HIDDEN`) of the observed entries of
    :data:`TUNE_ROW_SHARE` of the rows, completes them with every candidate, and scores the mean
    squared error on the hidden entries (units of W: standardised when ``standardize``); the
    smallest mean wins (:class:`~nldr.model_selection.HoldoutSearch`, one fit per fold shared by
    the candidates). Sets ``transform_results_`` (candidate -> mean error)."""
    candidates = transform_candidates(est)
    if len(candidates) == 1:
        return candidates[0]
    share = max(TUNE_ROW_HIDDEN, 1.0 - mask.mean())
    order = canonical_row_order(W, mask)
    W, mask = W[order], mask[order]
    folds = row_folds(mask, TUNE_FOLDS, TUNE_ROW_SHARE, share, est._tune_seed())
    base = est.get_params()
    base.update(gamma=gamma, tau=tau, warm_start=False, verbose=False, **est._fold_solver(W.shape[0]))
    X, found = np.where(mask, W, np.nan), None
    if folds:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            found = search_transform_knobs(type(est)(**base), X, candidates, folds, bool(est.verbose))
    if found is None:  # nothing to hide, or a fold's manifold has no component
        return TUNE_TRANSFORM[1] if TUNE_TRANSFORM[1] in candidates else candidates[0]
    est.transform_results_, best = found
    return best


def report_holdout(est, result) -> None:
    """A tuned choice whose hold-out error is no better than the column means' says so."""
    errors = getattr(est, "_holdout_against_means", None)
    if errors is None or errors[0] < errors[1]:
        return
    result.status = INACCURATE
    result.message = (
        f"{result.message}; the chosen gamma and tau predict the hidden entries no better than the "
        f"column means (hold-out error {errors[0]:.4g} against {errors[1]:.4g})"
    )
    warnings.warn(
        f"KernelRegularizerImputer: the hold-out search's best (gamma = {est.gamma_:g}, tau = "
        f"{est.tau_:g}) predicts hidden entries no better than the observed column means (mean "
        f"squared error {errors[0]:.4g} against {errors[1]:.4g}); the columns may carry no shared "
        "structure, or the data's units dominate (use standardize=True)",
        ConvergenceWarning,
        stacklevel=4,
    )


def mean_fill_holdout(W: np.ndarray, mask: np.ndarray, folds) -> float:
    """The column means' mean squared error on each fold's hidden entries (means of the entries the
    fold keeps), averaged over the folds: the score a mean fill gets in the search (units of W^2)."""
    errors = []
    for hidden in folds:
        keep = mask & ~hidden
        means = np.where(keep, W, 0.0).sum(axis=0) / np.maximum(keep.sum(axis=0), 1)
        diff = (W - means[None, :])[hidden]
        errors.append(float(diff @ diff) / diff.size)
    return float(np.mean(errors))
