"""Input checks shared by the public functions (validate at the edge, trust inside)."""

from __future__ import annotations

import numpy as np


def as_float_matrix(value, name: str, *, ndim: int = 2, allow_nan: bool = False) -> np.ndarray:
    """Return ``value`` as a float64 array of ``ndim`` dimensions or raise a ValueError naming it."""
    if np.iscomplexobj(value):
        raise ValueError(f"{name} is complex; pass real data (e.g. its real part or its modulus)")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array; got {type(value).__name__} ({exc})") from None
    if arr.ndim != ndim:
        raise ValueError(f"{name} must be a {ndim}-d array; got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"{name} must not be empty; got shape {arr.shape}")
    if not allow_nan and not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or infinite values; clean or mask them first")
    return arr


def check_positive(value, name: str, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a float, raising a ValueError naming it unless it is finite and > 0."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a real number; got {value!r}") from None
    ok = np.isfinite(x) and (x >= 0 if allow_zero else x > 0)
    if not ok:
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be finite and {bound}; got {value!r}")
    return x


def check_count(value, name: str) -> int:
    """Return ``value`` as an int; a ValueError naming it unless it is an integer >= 1 (bools refused)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ValueError(f"{name} must be a positive integer; got {value!r}")
    return int(value)


def check_flag(value, name: str) -> bool:
    """Return ``value`` as a bool; a ValueError naming it unless it is True or False (numpy's bools too).

    A string such as "no" is truthy in Python, so ``bool(value)`` would read it as True."""
    if not isinstance(value, bool | np.bool_):
        raise ValueError(f"{name} must be True or False; got {value!r}")
    return bool(value)


def check_symmetric_kernel(K, name: str = "K", *, rtol: float = 1e-8) -> np.ndarray:
    """Return a square, finite, symmetric float matrix (symmetrised exactly) or raise a ValueError."""
    K = as_float_matrix(K, name)
    if K.shape[0] != K.shape[1]:
        raise ValueError(f"{name} must be square; got shape {K.shape}")
    scale = max(float(np.max(np.abs(K))), 1.0)
    if np.max(np.abs(K - K.T)) > rtol * scale:
        raise ValueError(
            f"{name} must be symmetric (max |{name} - {name}.T| = {np.max(np.abs(K - K.T)):.3g}); "
            f"pass (K + K.T) / 2 if the asymmetry is rounding"
        )
    return 0.5 * (K + K.T)


def check_magnitude(values: np.ndarray, name: str, *, fix: str | None = None) -> None:
    """Refuse data whose sum of squares would overflow float64.

    The solvers square the data (residuals, pairwise distances): entries beyond about
    sqrt(max float / (4 m)) for m of them overflow to infinity, and the eigensolver then fails far from
    the cause. The bound holds for residuals and distances of points up to twice the data's range.
    ``fix`` replaces the message's last sentence (default: rescale ``name``).
    """
    if values.size == 0:
        return
    largest = float(np.max(np.abs(values)))
    limit = float(np.sqrt(np.finfo(np.float64).max / (16.0 * values.size)))
    if largest > limit:
        raise ValueError(
            f"{name} has entries up to {largest:.3g} in magnitude; squared errors overflow float64 "
            f"beyond about {limit:.3g} for {values.size} entries. "
            + (fix or f"Rescale {name} (e.g. standardise it)")
        )


def check_squares_representable(W: np.ndarray, mask: np.ndarray, name: str) -> None:
    """Refuse observed entries whose squares float64 cannot hold: too large at all, or too small in a column.

    The methods square differences of entries (distances between rows, residuals, variances). Beyond
    the bound of :func:`check_magnitude` (applied here) sums of squares overflow; in a column whose
    largest observed magnitude is below sqrt(smallest normal float64), every square underflows (to
    zero or a subnormal without precision), so the column's spread and its share of every distance are lost.
    Data in any ordinary units lies far inside both bounds. W (n, d) is zero where ``mask`` is False.
    """
    fix = f"Rescale the columns of {name} (e.g. divide each by a typical magnitude of its entries)"
    check_magnitude(W[mask], name, fix=fix)
    column_largest = np.max(np.where(mask, np.abs(W), 0.0), axis=0)
    floor = float(np.sqrt(np.finfo(np.float64).tiny))
    tiny = np.flatnonzero((column_largest > 0.0) & (column_largest < floor))
    if tiny.size:
        raise ValueError(
            f"column(s) {tiny[:10].tolist()}{' ...' if tiny.size > 10 else ''} of {name} have observed "
            f"entries below {floor:.3g} in magnitude: their squares underflow float64. {fix}"
        )


def check_masked_matrix(
    W, mask, *, require_observed_columns: bool = True, name: str = "W"
) -> tuple[np.ndarray, np.ndarray]:
    """The one check of a partially observed matrix; return ``(W, mask)`` with W zero where missing.

    Every entry point that takes data with an observation mask (the baselines, the data terms,
    :meth:`nldr.robust_kpca.RobustKernelPCA.complete`, the estimators of :mod:`nldr.impute`) calls this,
    so each refuses the same inputs with the same message.

    Parameters
    ----------
    W : array, shape (n, d)
        Data, samples as rows; entries where ``mask`` is False are ignored (they may be NaN).
    mask : array of bool, shape (n, d)
        True where ``W`` is observed. An integer or float array holding only 0 and 1 is read as
        bool; any other value is refused.
    require_observed_columns : bool
        Raise if some column has no observed entry (methods that start from column means need one).
    name : str
        What the messages call ``W``.

    Returns
    -------
    W : float array, shape (n, d), a copy with zeros at the missing entries
    mask : bool array, shape (n, d)
    """
    W = as_float_matrix(W, name, allow_nan=True)
    mask_arr = np.asarray(mask)
    if mask_arr.dtype != bool:
        if mask_arr.dtype.kind not in "iuf" or not np.isin(mask_arr, (0, 1)).all():
            raise ValueError(f"mask must be boolean (or 0/1): True where {name} is observed")
        mask_arr = mask_arr.astype(bool)
    if mask_arr.shape != W.shape:
        raise ValueError(
            f"mask must have the shape of {name} (the same shape); "
            f"got mask {mask_arr.shape} and {name} {W.shape}"
        )
    if not np.all(np.isfinite(W[mask_arr])):
        raise ValueError(f"{name} has NaN or infinite values at observed entries (where mask is True)")
    if require_observed_columns:
        empty = np.flatnonzero(~mask_arr.any(axis=0))
        if empty.size:
            raise ValueError(
                f"mask has no observed entry in column(s) {empty.tolist()} of {name}; "
                "drop those columns (nothing can be imputed from them)"
            )
    return np.where(mask_arr, W, 0.0), mask_arr
