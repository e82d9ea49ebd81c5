"""Mean imputation: the simplest baseline of the paper's Table 2 and every other method's start.

This module also holds the input check shared by all imputation baselines (``W`` with a boolean
``mask``), so that every method rejects the same bad inputs with the same messages.
"""

from __future__ import annotations

import numpy as np

from .._validation import as_float_matrix

__all__ = ["mean_impute"]


def _check_masked_matrix(W, mask, *, require_observed_columns: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Validate a partially observed matrix; return ``(W, mask)`` with missing entries of W set to 0.

    Parameters
    ----------
    W : array, shape (n, d)
        Data, samples as rows; entries where ``mask`` is False are ignored (they may be NaN).
    mask : array of bool (or 0/1), shape (n, d)
        True where ``W`` is observed.
    require_observed_columns : bool
        Raise if some column has no observed entry (methods that start from column means need one).

    Returns
    -------
    W : float array, shape (n, d), a copy with zeros at the missing entries
    mask : bool array, shape (n, d)
    """
    W = as_float_matrix(W, "W", allow_nan=True)
    mask_arr = np.asarray(mask)
    if mask_arr.dtype != bool:
        if mask_arr.dtype.kind not in "biuf" or not np.isin(mask_arr, (0, 1)).all():
            raise ValueError("mask must be boolean (or 0/1): True where W is observed")
        mask_arr = mask_arr.astype(bool)
    if mask_arr.shape != W.shape:
        raise ValueError(f"mask must have the shape of W; got mask {mask_arr.shape} and W {W.shape}")
    if not np.all(np.isfinite(W[mask_arr])):
        raise ValueError("W has NaN or infinite values at observed entries (where mask is True)")
    if require_observed_columns:
        empty = np.flatnonzero(~mask_arr.any(axis=0))
        if empty.size:
            raise ValueError(
                f"mask has no observed entry in column(s) {empty.tolist()} of W; "
                "drop those columns (nothing can be imputed from them)"
            )
    return np.where(mask_arr, W, 0.0), mask_arr


def _observed_column_means(W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Mean of each column over its observed entries, shape (d,); input already validated.

    ``W`` must be 0 at the missing entries (as returned by ``_check_masked_matrix``).
    """
    return W.sum(axis=0) / mask.sum(axis=0)


def _mean_fill(W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Trusting inner version of ``mean_impute`` (W zero at missing entries, every column observed)."""
    return np.where(mask, W, _observed_column_means(W, mask)[None, :])


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
    W, mask = _check_masked_matrix(W, mask)
    return _mean_fill(W, mask)
