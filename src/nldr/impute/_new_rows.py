"""New rows against :class:`~nldr.impute.KernelRegularizerImputer`'s fitted manifold: the principal
subspace in :mod:`nldr._preimage`'s form, and the row-fold search of ``transform``'s knobs."""

from __future__ import annotations

import numpy as np

from .._preimage import Subspace
from ..kernels import center_kernel, rbf_kernel
from ..model_selection import HoldoutSearch

__all__ = ["NoComponentsError", "regularizer_subspace", "row_folds", "search_transform_knobs"]


class NoComponentsError(ValueError):
    """``transform`` of new rows against a fitted manifold with no component."""


def regularizer_subspace(S: np.ndarray, gamma: float, C: np.ndarray, center: bool) -> Subspace:
    """The principal subspace spanned by the rows of the kernel factor C (k, n) of the solved rows S
    (n, d) at width gamma: C = diag(l) U^T, so the unit axes are the rows of C normalised, u_i, with
    eigenvalues u_i^T K u_i of the (centred when ``center``) kernel K of S."""
    K = rbf_kernel(S, gamma)
    column_means = K.mean(axis=0) if center else None
    if center:
        K = center_kernel(K)
    U = C / np.linalg.norm(C, axis=1, keepdims=True)  # rows u_i^T of C = diag(l) U^T
    lam = np.einsum("in,nm,im->i", U, K, U)  # u_i^T K u_i, the eigenvalues of the kept axes
    return Subspace(X_fit=S, gamma=gamma, V=U.T / np.sqrt(lam)[None, :], column_means=column_means)


def row_folds(
    mask: np.ndarray, n_folds: int, row_share: float, hidden_share: float, seed: int
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Row folds as :class:`~nldr.model_selection.HoldoutSearch` takes them, ``(fit_rows, hidden)``
    (bool (n,) and (n, d)), for the observation mask (n, d) of a training matrix.

    Each fold (drawn in turn from ``numpy.random.default_rng(seed)``) holds out ``row_share`` of the
    rows (at least one), hides each of their observed entries with probability ``hidden_share`` and
    gives one hidden entry back to every held row left with none observed (it has one to be
    completed from); the other rows are fitted on. A fold that hides nothing is dropped.
    """
    n = mask.shape[0]
    rng = np.random.default_rng(seed)
    folds = []
    for _ in range(n_folds):
        held = np.zeros(n, dtype=bool)
        held[rng.choice(n, max(1, int(round(row_share * n))), replace=False)] = True
        observed = mask[held]
        hidden = observed & (rng.random(observed.shape) < hidden_share)
        for i in np.flatnonzero(observed.any(axis=1) & ~(observed & ~hidden).any(axis=1)):
            hidden[i, rng.choice(np.flatnonzero(observed[i]))] = False  # each row keeps an entry
        if hidden.any():
            entries = np.zeros(mask.shape, dtype=bool)
            entries[held] = hidden
            folds.append((~held, entries))
    return folds


def search_transform_knobs(estimator, X: np.ndarray, candidates, folds, verbose: bool = False):
    """Score ``transform``'s (n_neighbors, starts) ``candidates`` on the row ``folds`` of X (n, d), NaN
    where missing: :class:`~nldr.model_selection.HoldoutSearch` of ``estimator`` (whose fit knobs
    are fixed), the mean squared error on each fold's hidden entries. The candidates of a fold are one
    warm path along ``n_neighbors``, so with a ``warm_start`` estimator that keeps its solve when only
    ``transform``'s knobs change, every fold costs one fit.

    Returns ``({candidate: mean error over the folds}, chosen candidate)`` (the smallest mean; ties:
    the first candidate), or None when a fold's manifold has no component to complete rows against.
    """
    grid = [{"n_neighbors": [int(k)], "starts": [str(s)]} for k, s in candidates]
    search = HoldoutSearch(estimator, grid, folds=folds, path="n_neighbors", refit=False, verbose=verbose)
    try:
        search.fit(X)
    except NoComponentsError:
        return None
    errors = search.cv_results_["mean_test_error"]
    results = {tuple(c): float(errors[i]) for i, c in enumerate(candidates)}
    return results, tuple(candidates[search.best_index_])
