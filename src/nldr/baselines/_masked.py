"""Partially observed matrices: the input check and the mean fill shared by every imputation baseline.

One check for all of them, so that every method rejects the same bad inputs with the same messages.
``mean_fill`` is the trusting inner version of :func:`nldr.baselines.mean_impute` and every other
method's starting point.
"""

from __future__ import annotations

import numpy as np

from .._validation import as_float_matrix

__all__ = ["check_masked_matrix", "observed_column_means", "mean_fill"]


def check_masked_matrix(W, mask, *, require_observed_columns: bool = True) -> tuple[np.ndarray, np.ndarray]:
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


def observed_column_means(W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Mean of each column over its observed entries, shape (d,); input already validated.

    ``W`` must be 0 at the missing entries (as returned by :func:`check_masked_matrix`).
    """
    return W.sum(axis=0) / mask.sum(axis=0)


def mean_fill(W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``W`` at the observed entries, the observed column means elsewhere (input already validated:
    W zero at missing entries, every column observed)."""
    return np.where(mask, W, observed_column_means(W, mask)[None, :])
