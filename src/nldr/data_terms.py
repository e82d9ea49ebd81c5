"""Data terms f(W, S) for the regularizer: the interface, masked least squares (completion), and the
Huber loss on the residuals of any of them (robust completion, robust NRSfM).

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

from ._validation import as_float_matrix, check_magnitude, check_masked_matrix, check_positive

__all__ = ["DataTerm", "MaskedLeastSquares", "Huber", "MaskedHuber", "huber_loss"]


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
        W, mask = check_masked_matrix(W, mask, require_observed_columns=False)
        if not mask.any():
            raise ValueError("mask is all False: W has no observed entry to fit (True marks observed)")
        check_magnitude(W[mask], "W")
        self.W = W
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


# --------------------------------------------------------------------------------------------------
# Robust data terms: the Huber loss on the residuals of any least-squares data term
# --------------------------------------------------------------------------------------------------


def huber_loss(r, delta: float) -> np.ndarray:
    """h_delta(r) = r^2 for |r| <= delta, 2 delta |r| - delta^2 beyond, elementwise (units of r squared).

    Twice the textbook Huber function, so that it *equals* the squared residual of the least-squares
    terms above (which carry no 1/2) wherever |r| <= delta. It is convex, continuously differentiable
    (h' = 2 clip(r, -delta, delta)), never above r^2, and grows linearly beyond delta: a residual of a
    gross outlier pulls with force at most 2 delta instead of 2 |r|. As delta -> infinity it is the
    squared loss; h_delta / (2 delta) -> |r| as delta -> 0 (within delta / 2 everywhere).
    """
    delta = check_positive(delta, "delta")
    a = np.abs(np.asarray(r, dtype=np.float64))
    return np.where(a <= delta, a * a, 2.0 * delta * a - delta * delta)


class Huber:
    """f(S) = sum_i h_delta(r_i(S)): the Huber loss (:func:`huber_loss`) on another data term's residuals.

    Wraps any :class:`DataTerm` with residuals r(S) and Jacobian J (e.g. :class:`MaskedLeastSquares`,
    or :class:`nldr.nrsfm.OrthographicReprojection` for robust NRSfM) and is itself a DataTerm, so
    :func:`nldr.regularizer.minimize_regularized` takes it unchanged. Residuals within ``delta`` count
    as in least squares, larger ones linearly; for every |r_i| <= delta, value and gradient equal the
    wrapped term's.

    Least-squares form (for Levenberg-Marquardt and the protocol): the residuals are
    ``rt_i = sign(r_i) sqrt(h_delta(r_i))``, so ``value = rt @ rt``; ``rt`` is continuously
    differentiable in r with drt/dr = 1 for |r| <= delta and ``delta / |rt|`` beyond, and the Jacobian
    is ``diag(drt/dr) J``. The gradient is ``J^T h'(r) = 2 J^T clip(r, -delta, delta)``.

    Parameters
    ----------
    term : DataTerm
        The least-squares data term whose residuals are made robust; kept as ``self.term`` (its own
        methods stay reachable there).
    delta : float > 0
        Threshold between quadratic and linear, in the units of the residuals (e.g. about 1.345 times
        a robust estimate of the residuals' standard deviation, Huber's 95 % efficiency rule).
    """

    def __init__(self, term, delta: float):
        if not isinstance(term, DataTerm):
            raise ValueError(
                "term must implement the nldr.data_terms.DataTerm protocol "
                f"(shape, residuals, jacobian, value, gradient); got {type(term).__name__}"
            )
        self.term = term
        self.delta = check_positive(delta, "delta")
        self.shape = tuple(term.shape)

    def residuals(self, S: np.ndarray) -> np.ndarray:
        r = self.term.residuals(S)
        return np.sign(r) * np.sqrt(huber_loss(r, self.delta))

    def jacobian(self, S: np.ndarray) -> sp.csr_matrix:
        r = self.term.residuals(S)
        a = np.abs(r)
        scale = np.ones_like(r)
        outside = a > self.delta
        scale[outside] = self.delta / np.sqrt(2.0 * self.delta * a[outside] - self.delta**2)
        return sp.csr_matrix(sp.diags(scale) @ self.term.jacobian(S))

    def value(self, S: np.ndarray) -> float:
        return float(np.sum(huber_loss(self.term.residuals(S), self.delta)))

    def gradient(self, S: np.ndarray) -> np.ndarray:
        psi = 2.0 * np.clip(self.term.residuals(S), -self.delta, self.delta)
        return np.asarray(self.term.jacobian(S).T @ psi).reshape(self.shape)


class MaskedHuber(Huber):
    """f(S) = sum over observed (i, j) of h_delta(W_ij - S_ij): matrix completion robust to outliers.

    :class:`Huber` around :class:`MaskedLeastSquares` (same ``W, mask`` checks), with the gradient
    ``-2 mask o clip(W - S, -delta, delta)`` formed directly. Equal to ``MaskedLeastSquares(W, mask)``
    when every observed residual is within ``delta``.

    Parameters
    ----------
    W : array, shape (n, d)
        Observed matrix; entries where ``mask`` is False are ignored (they may be NaN).
    mask : bool array, shape (n, d)
        True where W is observed.
    delta : float > 0
        Huber threshold, in the units of W.
    """

    def __init__(self, W, mask, delta: float):
        super().__init__(MaskedLeastSquares(W, mask), delta)
        self.W, self.mask = self.term.W, self.term.mask

    def gradient(self, S: np.ndarray) -> np.ndarray:
        return -2.0 * np.where(self.mask, np.clip(self.W - S, -self.delta, self.delta), 0.0)
