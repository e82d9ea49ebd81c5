"""Folds, default grids and the fold score of the hold-out selections of :mod:`nldr.model_selection`
(the bookkeeping they share with NRSfM's selection is in :mod:`nldr._cv`)."""

from __future__ import annotations

import numpy as np

from .._baselines._masked import check_masked_matrix, mean_fill
from .._validation import check_count
from ..kernels import squared_distances

__all__ = [
    "EntryFolds",
    "DEFAULT_TAUS",
    "GAMMA_MULTIPLES",
    "median_gamma",
    "holdout_folds",
    "fold_score",
    "SCORES",
]

#: Default tau grid: log-spaced over four decades around the paper's 0.1 (Table 2) and 10 (denoising).
DEFAULT_TAUS = tuple(float(t) for t in np.logspace(-2, 2, 9))
#: Default widths, as multiples of :func:`median_gamma` (the inverse median squared row distance). Wider
#: kernels than the median rule: on oil flow (Table 2) the paper's 0.075 is 0.26 times it, and 4 times it
#: scored worse than every smaller width in every fold.
GAMMA_MULTIPLES = (0.25, 0.5, 1.0)


def median_gamma(W, mask=None) -> float:
    """1 / median squared distance between the rows of W after mean imputation.

    Parameters
    ----------
    W : array, shape (n, d); entries where ``mask`` is False are ignored.
    mask : bool array, shape (n, d), True where observed; default: where W is not NaN.

    Returns
    -------
    gamma : float > 0, in 1 / (units of W)^2.
    """
    if mask is None:
        W = np.asarray(W, dtype=np.float64)
        mask = ~np.isnan(W)
    W, mask = check_masked_matrix(W, mask)
    D = squared_distances(mean_fill(W, mask))
    med = float(np.median(D[np.triu_indices(D.shape[0], 1)]))
    if not med > 0:
        raise ValueError("the rows of W (after mean imputation) coincide: no median distance to set gamma")
    return 1.0 / med


def holdout_folds(
    mask, n_folds: int = 5, random_state=0, *, holdout: float | None = None
) -> list[np.ndarray]:
    """Hidden-entry masks of the cross-validation folds.

    Parameters
    ----------
    mask : bool array, shape (n, d)
        True where observed; every column needs an observed entry.
    n_folds : int >= 2
        Number of folds.
    random_state : int or numpy Generator
        Seed of the shuffles; the same seed gives the same folds.
    holdout : float in (0, 1), optional
        None (default): the folds partition the observed entries (each hides about 1/n_folds of
        them). A share: each fold hides round(holdout * n_observed) observed entries drawn afresh
        (Monte-Carlo folds; they may overlap), so the fold problems are as dense as the caller wants.

    Returns
    -------
    folds : list of n_folds bool arrays, shape (n, d)
        True at the entries fold k hides: observed only, and never every observed entry of a column
        (one is kept for training; see the module docstring). Disjoint when ``holdout`` is None.
    """
    mask = np.asarray(mask, dtype=bool)
    n_folds = check_count(n_folds, "n_folds")
    if n_folds < 2:
        raise ValueError(f"n_folds must be >= 2 (one fold would hide every observed entry); got {n_folds}")
    if holdout is not None and not (isinstance(holdout, (int, float)) and 0.0 < holdout < 1.0):
        raise ValueError(f"holdout must be None or a share in (0, 1); got {holdout!r}")
    empty = np.flatnonzero(~mask.any(axis=0))
    if empty.size:
        raise ValueError(
            f"column(s) {empty.tolist()} have no observed entry (all missing): no fold can keep one "
            "for training or hide one to score; drop those columns before the search"
        )
    observed = np.flatnonzero(mask.ravel())
    if observed.size < n_folds:
        raise ValueError(f"mask has {observed.size} observed entries, fewer than n_folds = {n_folds}")
    rng = np.random.default_rng(random_state)
    size = None if holdout is None else max(1, int(round(holdout * observed.size)))
    order = rng.permutation(observed)
    folds = []
    for k in range(n_folds):
        if size is not None and k > 0:
            order = rng.permutation(observed)
        chosen = order[k::n_folds] if size is None else order[:size]
        hidden = np.zeros(mask.size, dtype=bool)
        hidden[chosen] = True
        hidden = hidden.reshape(mask.shape)
        for j in np.flatnonzero(~(mask & ~hidden).any(axis=0)):
            hidden[order[order % mask.shape[1] == j][0] // mask.shape[1], j] = False
        folds.append(hidden)
    return folds


#: Fold scores: mean squared error per hidden entry, or mean absolute error (robust to gross outliers
#: among the hidden entries: an outlier adds |o - x_hat|, whose differences between two estimates are
#: bounded by their difference at that entry, instead of a square dominated by the outlier).
SCORES = ("squared", "absolute")


def fold_score(X_hat: np.ndarray, W: np.ndarray, hidden: np.ndarray, score: str = "squared") -> float:
    """Mean squared (or absolute) error of X_hat against W on the ``hidden`` entries (not empty)."""
    diff = (X_hat - W)[hidden]
    if score == "absolute":
        return float(np.abs(diff).sum()) / diff.size
    return float(diff @ diff) / diff.size


class EntryFolds:
    """Masked-entry folds of the observed entries of X (:func:`~nldr.model_selection.holdout_folds`).

    Parameters
    ----------
    n_folds : int >= 2, default 5
    holdout : float in (0, 1) or None, default None
        None: the folds partition the observed entries; a share: each fold hides that share afresh.
    random_state : int, default 0
        Seed of the shuffles: same mask and seed, same folds.
    """

    def __init__(self, n_folds: int = 5, *, holdout: float | None = None, random_state=0):
        self.n_folds = n_folds
        self.holdout = holdout
        self.random_state = random_state

    def split(self, X) -> list[np.ndarray]:
        """Hidden-entry masks, one bool array of X's shape per fold (True: hidden)."""
        return holdout_folds(~np.isnan(X), self.n_folds, self.random_state, holdout=self.holdout)

    def __repr__(self) -> str:
        return f"EntryFolds(n_folds={self.n_folds}, holdout={self.holdout}, random_state={self.random_state})"
