"""The base class of every imputer in :mod:`nldr.impute`: NaN marks a missing entry.

One validation path (scikit-learn's ``validate_data`` with NaN allowed, then the library's one mask
check, :func:`nldr._validation.check_masked_matrix`, and the refusal of entries whose squares float64
cannot hold, :func:`nldr._validation.check_squares_representable`), one memory of the rows seen in
``fit``, and the scikit-learn plumbing (feature names, ``set_output``, tags). A subclass implements
two methods:

- ``_solve(W, mask)``: the method on the partially observed training matrix W (zero where missing,
  mask True where observed; every column observed when ``_require_observed_columns``). It stores
  what ``transform`` needs on ``self`` and returns ``(X_hat, result)``, the completed (n, d) matrix
  and the solver's result object (or None);
- ``_complete(W, mask)``: the completion of rows never seen, against what ``_solve`` learnt.

Parameters. Each class declares its parameters' types and ranges in ``_parameter_constraints``
(scikit-learn's declarative validation: ``fit`` raises ``InvalidParameterError``, a ValueError that
names the parameter, the accepted values and the value given); a class whose parameters have rules
that tie two of them together adds those to ``_validate_params`` in a few lines of code, so that
``fit`` checks them first and :class:`~nldr.model_selection.HoldoutSearch` checks every candidate
before any fit.

Observed entries. An imputer keeps them: ``fit_transform`` and ``transform`` return the observed
entries of X unchanged and estimate the missing ones, scikit-learn's convention, so that training
and test rows of a ``Pipeline`` are the same kind of thing. A method whose solve also moves the
observed entries (a denoiser: :class:`~nldr.impute.RobustPCAImputer`'s low-rank L, the
:class:`~nldr.impute.KernelRegularizerImputer`'s S) has a ``denoise`` parameter, default False;
with ``denoise=True`` both ``fit_transform`` and ``transform`` return the denoised estimate of every
entry. The base class applies the rule to what ``_solve`` returns (``_denoises`` says whether the
estimator's output is the denoised one).

Rows seen in ``fit``. A transductive method's answer for a row depends on every other row, so a
training row completed on its own would not be the row ``fit_transform`` returned. ``transform``
therefore returns the fitted estimate for any row identical to a training row (same values, same
missing entries), so that ``fit(X).transform(X)`` equals ``fit_transform(X)`` as scikit-learn's
contract says, and completes the other rows with ``_complete``. Identical training rows (same values,
same missing entries) are one row to the method: they share one estimate, the mean of the solve's
estimates of the copies (a solve may split copies apart within its tolerance), so ``fit_transform``
gives every copy the same row and ``transform`` returns that row for each of them.

Units. A subclass that sets ``_standardizes`` takes a ``standardize`` parameter (default True): the
base class then hands ``_solve`` and ``_complete`` the columns standardised by their observed
entries' mean and standard deviation (:func:`nldr._baselines._masked.observed_standardisation`),
and returns their estimates in the data's units, each observed entry the solve left in place given
back exactly. The completion is then unit-free per column: scaling a column scales its completion
(by a power of two, exactly; by any other factor, up to the rounding of the standardisation carried
through the solve).

A solve that ends at its start. Every iterative method here starts from the column means (mean
imputation). An estimate whose missing entries are all still the observed column means (to within
:data:`MEAN_FILL_RTOL` of the column's standard deviation) is a mean fill, not a converged solve:
``fit`` then sets ``result_``'s status to :data:`~nldr.result.INACCURATE` (``success`` False) and
warns (:class:`sklearn.exceptions.ConvergenceWarning`) naming the likely cause (the subclass's
``_mean_fill_cause``).

BLAS threads. ``fit`` and ``transform`` run on the library's thread choice for the training rows'
count (:func:`nldr._threads.blas_threads_for`), the estimator's own array arithmetic included.
"""

from __future__ import annotations

import warnings
from numbers import Real

import numpy as np
from sklearn.base import BaseEstimator, OneToOneFeatureMixin, TransformerMixin, _fit_context
from sklearn.exceptions import ConvergenceWarning
from sklearn.utils._param_validation import Interval
from sklearn.utils.validation import check_is_fitted, validate_data

from .._baselines._masked import observed_standardisation
from .._threads import blas_threads_for
from .._validation import check_masked_matrix, check_squares_representable
from ..result import INACCURATE

__all__ = ["MaskedImputerBase", "MEAN_FILL_RTOL", "canonical_row_order"]

#: An estimate's missing entries within this multiple of their column's standard deviation of the
#: column's observed mean are a mean fill. Rounding of the (un)standardisation is ~1e-16 relative; a
#: solve that moves an entry moves it by orders of magnitude more than this.
MEAN_FILL_RTOL = 1e-9


def _row_keys(X: np.ndarray) -> list[bytes]:
    """One hashable key per row; every NaN written the same way (a NaN's bits may vary)."""
    Y = np.array(X, dtype=np.float64, order="C")
    Y[np.isnan(Y)] = np.nan
    Y[Y == 0.0] = 0.0  # -0.0 and 0.0 are the same value
    return [row.tobytes() for row in Y]


class MaskedImputerBase(OneToOneFeatureMixin, TransformerMixin, BaseEstimator):
    """Shared machinery of the imputers (not used directly; see the module docstring).

    Attributes set by ``fit``
    -------------------------
    n_features_in_ : int
    feature_names_in_ : array of str, when X has string column names
    completed_ : float64 array, shape (n_samples, n_features)
        The method's estimate of the training matrix (what ``fit_transform`` returns), float64
        whatever X's dtype: the solvers run in float64.
    result_ : SolverResult or None
        The solver's result object, for the methods that have one.
    n_iter_ : int
        The solver's iteration count (``result_.nit``), where it has one.
    """

    #: ``missing_values``: np.nan or a finite number (not a bool); subclasses extend the dict
    _parameter_constraints: dict = {
        "missing_values": [Interval(Real, None, None, closed="neither"), "nan"],
    }

    #: the method needs an observed entry in every column
    _require_observed_columns = True
    #: fewest training rows and columns the method accepts
    _min_samples = 1
    _min_features = 1
    #: the class has a ``standardize`` parameter, and the base class standardises for it (module docstring)
    _standardizes = False

    def _mean_fill_cause(self) -> str:
        """The likely causes of a solve that ends at its start, for the warning (subclasses name theirs)."""
        return "the data's units (entries far from unit scale): rescale X"

    def _units(self, W, mask) -> None:
        """For a class that ``_standardizes``: set ``shift_`` and ``scale_`` (n_features,), the
        standardisation (zeros and ones when ``standardize`` is False)."""
        if not self._standardizes:
            return
        if self.standardize:
            self.shift_, self.scale_ = _standardisation(W, mask)
        else:
            self.shift_, self.scale_ = np.zeros(W.shape[1]), np.ones(W.shape[1])

    def _standardised(self, W, mask) -> np.ndarray:
        """W (m, d) in the solved units (zero at the missing entries)."""
        if not (self._standardizes and self.standardize):
            return W
        return np.where(mask, (W - self.shift_) / self.scale_, 0.0)

    def _in_data_units(self, Z_hat, Z, W, mask) -> np.ndarray:
        """An estimate in solved units back in the data's units; the observed entries the solve kept
        are W's, exactly."""
        if not (self._standardizes and self.standardize):
            return Z_hat
        kept = mask & (Z_hat == Z)
        return np.where(kept, W, Z_hat * self.scale_ + self.shift_)

    def _missing_mask(self, X: np.ndarray) -> np.ndarray:
        if _is_nan_marker(self.missing_values):
            return np.isnan(X)
        return (X == self.missing_values) | np.isnan(X)

    def _validated(self, X, *, reset: bool) -> tuple[np.ndarray, np.ndarray]:
        """X as float64 and its observation mask (True = observed); scikit-learn's checks first."""
        X = validate_data(
            self,
            X,
            reset=reset,
            dtype=np.float64,
            ensure_all_finite="allow-nan",
            ensure_min_samples=self._min_samples if reset else 1,
            ensure_min_features=self._min_features if reset else 1,
            copy=False,
        )
        missing = self._missing_mask(X)
        W, mask = check_masked_matrix(
            np.where(missing, np.nan, X),
            ~missing,
            require_observed_columns=reset and self._require_observed_columns,
            name="X",
        )
        check_squares_representable(W, mask, "X")
        return W, mask

    def _denoises(self) -> bool:
        """Whether the output is the denoised estimate of every entry (``denoise=True``), not the
        observed entries kept."""
        return bool(getattr(self, "denoise", False))

    def _fit(self, X):
        W, mask = self._validated(X, reset=True)
        self._units(W, mask)
        Z = self._standardised(W, mask)
        with blas_threads_for(W.shape[0]):
            Z_hat, result = self._solve(Z, mask)
        X_hat = np.asarray(self._in_data_units(np.asarray(Z_hat, dtype=np.float64), Z, W, mask))
        if not self._denoises():
            X_hat = np.where(mask, W, X_hat)
        keys = _row_keys(np.where(mask, W, np.nan))
        self.completed_ = _share_estimates(X_hat, keys)
        self.result_ = result
        self._check_moved(W, mask)
        if hasattr(result, "nit"):
            self.n_iter_ = int(result.nit)
        self._seen = {key: i for i, key in reversed(list(enumerate(keys)))}
        return self.completed_

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y=None):
        """Fit the method to X, shape (n_samples, n_features), NaN (or ``missing_values``) where missing.

        ``y`` is ignored. Returns self.
        """
        self._fit(X)
        return self

    @_fit_context(prefer_skip_nested_validation=True)
    def fit_transform(self, X, y=None):
        """Fit to X and return the method's estimate of X, a float64 array (n_samples, n_features)."""
        return self._fit(X).copy()

    def transform(self, X):
        """Complete X, shape (m, n_features): rows seen in ``fit`` get their fitted estimate, the
        others are completed against the fitted model (see the class docstring).

        Returns
        -------
        X_hat : float64 array, shape (m, n_features)
            float64 whatever X's dtype (the solvers run in float64).
        """
        check_is_fitted(self, "completed_")
        W, mask = self._validated(X, reset=False)
        out = np.empty(W.shape)
        seen = np.array([self._seen.get(key, -1) for key in _row_keys(np.where(mask, W, np.nan))], dtype=int)
        old = seen >= 0
        out[old] = self.completed_[seen[old]]
        new = ~old
        if new.any():
            Z = self._standardised(W[new], mask[new])
            with blas_threads_for(self.completed_.shape[0]):
                out[new] = self._in_data_units(self._complete(Z, mask[new]), Z, W[new], mask[new])
        return out

    def _check_moved(self, W, mask) -> None:
        """A fit whose estimate is the mean fill says so (module docstring): ``result_`` not successful
        and a ConvergenceWarning naming the likely cause."""
        missing = ~mask & mask.any(axis=0)  # an unobserved column has no mean to compare with
        if not missing.any():
            return
        mean, sd = _standardisation(W, mask)
        gap = np.abs(self.completed_ - mean[None, :])
        if np.any(gap[missing] > MEAN_FILL_RTOL * np.broadcast_to(sd, W.shape)[missing]):
            return
        result = self.result_
        if result is not None and hasattr(result, "status"):
            result.status = INACCURATE
            result.message = f"{result.message}; the estimate is the mean fill it started from"
        warnings.warn(
            f"{type(self).__name__} returned the column means' fill: the solve ended where it started "
            f"(its missing entries are the observed column means). Likely cause: {self._mean_fill_cause()}",
            ConvergenceWarning,
            stacklevel=4,
        )

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = True
        return tags


def _standardisation(W: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~nldr._baselines._masked.observed_standardisation`, a column with no observed entry
    left as it is (shift 0, scale 1)."""
    seen = mask.any(axis=0)
    shift, scale = np.zeros(W.shape[1]), np.ones(W.shape[1])
    if seen.any():
        shift[seen], scale[seen] = observed_standardisation(W[:, seen], mask[:, seen])
    return shift, scale


def canonical_row_order(W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The permutation (n,) that sorts the rows of W (n, d) by their content: lexicographically by
    their observed values, a missing entry after every value. Rows in any order sort to the same
    matrix (identical rows are interchangeable), so what is computed on ``W[order]`` does not depend
    on the order the rows came in."""
    Y = np.where(mask, W, 0.0)
    Y[Y == 0.0] = 0.0  # -0.0 and 0.0 are the same value
    keys = [Y[:, j] for j in range(W.shape[1])] + [~mask[:, j] for j in range(W.shape[1])]
    columns = [k for pair in zip(keys[W.shape[1] :], keys[: W.shape[1]], strict=True) for k in pair]
    return np.lexsort(columns[::-1])


def _share_estimates(X_hat: np.ndarray, keys: list[bytes]) -> np.ndarray:
    """X_hat (n, d) with every group of identical rows (equal ``keys``) given the mean of the group's
    estimates, summed in row order; X_hat itself (not a copy) when no two rows are identical."""
    groups: dict[bytes, list[int]] = {}
    for i, key in enumerate(keys):
        groups.setdefault(key, []).append(i)
    copies = [rows for rows in groups.values() if len(rows) > 1]
    if not copies:
        return X_hat
    out = X_hat.copy()
    for rows in copies:
        out[rows] = X_hat[rows].mean(axis=0)
    return out


def _is_nan_marker(value) -> bool:
    return isinstance(value, float) and np.isnan(value)
