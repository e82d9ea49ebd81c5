"""Partially observed matrices: the mean fill shared by every imputation baseline.

The input check itself is :func:`nldr._validation.check_masked_matrix` (re-exported here), the one
mask check of the library. ``mean_fill`` is the trusting inner version of
:func:`nldr.baselines.mean_impute` and every other method's starting point.
"""

from __future__ import annotations

import numpy as np

from .._validation import check_masked_matrix

__all__ = ["check_masked_matrix", "observed_column_means", "mean_fill"]


def observed_column_means(W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Mean of each column over its observed entries, shape (d,); input already validated.

    ``W`` must be 0 at the missing entries (as returned by :func:`check_masked_matrix`).
    """
    return W.sum(axis=0) / mask.sum(axis=0)


def mean_fill(W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``W`` at the observed entries, the observed column means elsewhere (input already validated:
    W zero at missing entries, every column observed)."""
    return np.where(mask, W, observed_column_means(W, mask)[None, :])
