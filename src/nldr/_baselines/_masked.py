"""Partially observed matrices: the mean fill and the standardisation shared by the imputers.

The input check itself is :func:`nldr._validation.check_masked_matrix` (re-exported here), the one
mask check of the library. ``mean_fill`` is the trusting inner version of
:func:`nldr._baselines.mean_impute` and every other method's starting point;
``observed_standardisation`` is the one column standardisation on the observed entries;
``neighbour_fill`` is the nearest rows' alternative to the mean fill.
"""

from __future__ import annotations

import numpy as np

from .._validation import check_masked_matrix

__all__ = [
    "check_masked_matrix",
    "observed_column_means",
    "observed_standardisation",
    "mean_fill",
    "neighbour_fill",
]


def observed_column_means(W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Mean of each column over its observed entries, shape (d,); input already validated.

    ``W`` must be 0 at the missing entries (as returned by :func:`check_masked_matrix`).
    """
    return W.sum(axis=0) / mask.sum(axis=0)


def observed_standardisation(W: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each column's mean and standard deviation over its observed entries, shapes (d,), units of W;
    a column whose observed entries are equal gets scale 1 (it is only centred). ``(W - mean) / scale``
    standardises the observed entries. Input already validated (W zero at missing entries, every
    column observed); the one standardisation of the imputers and the benchmark."""
    mean = observed_column_means(W, mask)
    squares = np.where(mask, W - mean, 0.0) ** 2
    sd = np.sqrt(squares.sum(axis=0) / mask.sum(axis=0))
    return mean, np.where(sd > 0, sd, 1.0)


def mean_fill(W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``W`` at the observed entries, the observed column means elsewhere (input already validated:
    W zero at missing entries, every column observed)."""
    return np.where(mask, W, observed_column_means(W, mask)[None, :])


def neighbour_fill(
    W: np.ndarray, mask: np.ndarray, n_neighbors: int, max_donors: int | None = None
) -> np.ndarray:
    """``W`` at the observed entries; a missing entry (i, j) gets the mean of column j over the
    ``n_neighbors`` rows nearest to row i among the donors that observe column j (scikit-learn's
    ``KNNImputer``: Euclidean distance on the columns both rows observe, rescaled to all columns). A row
    that observes nothing gets the donors' observed column means. The donors are every row, or beyond
    ``max_donors`` rows an evenly spaced subsample of that many (in the given order), which keeps the cost
    linear in the rows. Shape and units of W; input already validated (W zero at missing entries, every
    column observed)."""
    from sklearn.impute import KNNImputer

    n = W.shape[0]
    rows = slice(None)
    if max_donors is not None and n > max_donors:
        rows = np.linspace(0, n - 1, max_donors).astype(int)
    nan = np.where(mask, W, np.nan)
    imputer = KNNImputer(n_neighbors=int(n_neighbors), keep_empty_features=True).fit(nan[rows])
    return np.where(mask, W, imputer.transform(nan))
