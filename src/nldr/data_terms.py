"""Data terms f(W, S) for the regularizer: the interface, and masked least squares (completion).

Interface (one mechanism for every experiment). A data term is an object with

- ``shape``: the shape (n_samples, n_features) of the variable S it scores (samples as rows);
- ``residuals(S) -> r``, shape (m,): f(S) = ||r||^2 (least-squares form, for Levenberg-Marquardt);
- ``jacobian(S) -> J``, scipy.sparse matrix (m, S.size): dr / d vec(S), vec in C order (row-major);
- ``value(S) -> float``: f(S) = r @ r;
- ``gradient(S) -> G``, shape (n_samples, n_features): df/dS = 2 J^T r reshaped.

Data terms with extra variables of their own (NRSfM cameras) expose them as attributes and update
them in methods of their own; the regularizer only ever sees the functions above.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
import scipy.sparse as sp

from ._validation import as_float_matrix, check_magnitude

__all__ = ["DataTerm", "MaskedLeastSquares", "check_start"]


@runtime_checkable
class DataTerm(Protocol):
    """Protocol of a least-squares data term f(S) = ||r(S)||^2; see the module docstring."""

    shape: tuple[int, int]

    def residuals(self, S: np.ndarray) -> np.ndarray: ...

    def jacobian(self, S: np.ndarray) -> sp.spmatrix: ...

    def value(self, S: np.ndarray) -> float: ...

    def gradient(self, S: np.ndarray) -> np.ndarray: ...


def check_start(data_term, S, name: str = "S") -> np.ndarray:
    """Validate a data term and an estimate of its variable; return ``S`` as a float64 array.

    Raises a ValueError unless ``data_term`` implements :class:`DataTerm` and ``S`` is a finite 2-d
    array of shape ``data_term.shape``; the message names ``name``.
    """
    if not isinstance(data_term, DataTerm):
        raise ValueError(
            "data_term must implement the nldr.data_terms.DataTerm protocol "
            f"(shape, residuals, jacobian, value, gradient); got {type(data_term).__name__}"
        )
    S = as_float_matrix(S, name)
    if S.shape != tuple(data_term.shape):
        raise ValueError(f"{name} must have the data term's shape {tuple(data_term.shape)}; got {S.shape}")
    return S


class MaskedLeastSquares:
    """f(S) = ||Z o (W - S)||_F^2, the matrix-completion data term.

    Parameters
    ----------
    W : array, shape (n, d)
        Observed matrix; entries where ``mask`` is False are ignored (they may be NaN).
    mask : bool array, shape (n, d)
        True where W is observed (the paper's Z).
    """

    def __init__(self, W, mask):
        mask = np.asarray(mask)
        if mask.dtype != bool:
            if not np.isin(mask, (0, 1)).all():
                raise ValueError("mask must be boolean (or 0/1): True where W is observed")
            mask = mask.astype(bool)
        W = as_float_matrix(W, "W", allow_nan=True)
        if mask.shape != W.shape:
            raise ValueError(f"mask and W must have the same shape; got {mask.shape} and {W.shape}")
        if not np.all(np.isfinite(W[mask])):
            raise ValueError("W has NaN or infinite values at observed entries (where mask is True)")
        check_magnitude(W[mask], "W")
        self.W = np.where(mask, W, 0.0)
        self.mask = mask
        self.shape = W.shape
        self._observed = np.flatnonzero(mask.ravel())
        m = self._observed.size
        # r = vec(W)[obs] - vec(S)[obs]  ->  J = -P, P the row selection of the observed entries.
        self._J = sp.csr_matrix(
            (-np.ones(m), (np.arange(m), self._observed)), shape=(m, int(np.prod(self.shape)))
        )

    def residuals(self, S: np.ndarray) -> np.ndarray:
        return (self.W - S).ravel()[self._observed]

    def jacobian(self, S: np.ndarray) -> sp.csr_matrix:
        return self._J

    def value(self, S: np.ndarray) -> float:
        r = self.residuals(S)
        return float(r @ r)

    def gradient(self, S: np.ndarray) -> np.ndarray:
        return -2.0 * np.where(self.mask, self.W - S, 0.0)
