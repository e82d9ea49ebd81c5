"""Mean imputation: the simplest baseline of the paper's Table 2 and every other method's start."""

from __future__ import annotations

import numpy as np

from ._masked import check_masked_matrix, mean_fill

__all__ = ["mean_impute"]


def mean_impute(W, mask) -> np.ndarray:
    """Replace every missing entry by the mean of the observed entries of its column.

    Parameters
    ----------
    W : array, shape (n, d)
        Data, samples as rows; entries where ``mask`` is False are ignored (they may be NaN).
    mask : array of bool, shape (n, d)
        True where ``W`` is observed. Every column needs at least one observed entry.

    Returns
    -------
    X : array, shape (n, d)
        ``W`` at the observed entries, the observed column means elsewhere.

    Raises
    ------
    ValueError
        If the shapes disagree, an observed entry is not finite or a column is fully missing.
    """
    W, mask = check_masked_matrix(W, mask)
    return mean_fill(W, mask)
