"""The 1-NN baseline of the paper's Table 2 as a scikit-learn imputer: :class:`NearestNeighbourImputer`."""

from __future__ import annotations

import numpy as np

from .._baselines import nearest_neighbour_impute
from ._base import MaskedImputerBase

__all__ = ["NearestNeighbourImputer"]


class NearestNeighbourImputer(MaskedImputerBase):
    """Each row copies its missing entries from the nearest fully observed row (the paper's "1-NN").

    The distance is the squared Euclidean distance on the row's observed columns (standardised by
    default)
    (:func:`nldr._baselines.nearest_neighbour_impute`); ties go to the donor with the lowest index.
    ``transform`` draws new rows' donors from the fully observed rows seen in ``fit``. With no fully
    observed row there is no donor (the paper's "NA", oil flow at p = 0.5): ``fit`` raises a
    ValueError saying so.

    Parameters
    ----------
    missing_values : np.nan or float, default np.nan
        The marker of a missing entry (NaN is always missing too).
    standardize : bool, default True
        Solve on the columns standardised by their observed entries' mean and standard deviation (a
        constant column is only centred) and return the estimate in the data's units, so that the
        completion is unit-free per column; the parameters in units of X are then in standardised
        units. False solves on X as given (the paper's Table 2 setting: distances in X's units).

    Attributes
    ----------
    donors_ : array, shape (n_donors, n_features), the fully observed training rows (solved units)
    shift_, scale_ : arrays, shape (n_features,)
        The standardisation (zeros and ones when ``standardize`` is False): the other fitted
        attributes and ``result_`` are in the solved units, ``(X - shift_) / scale_``.
    result_ : nldr._baselines.NearestNeighbourResult
    completed_ : array, shape (n_samples, n_features)
    n_features_in_ : int

    See Also
    --------
    sklearn.impute.KNNImputer : k neighbours, any row a donor for the columns it observes.

    Notes
    -----
    Unlike ``KNNImputer(n_neighbors=1)``, the donor must be fully observed, as in the paper; that is
    why it has no answer once every row misses an entry.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[1.0, 2.0, 3.0], [2.0, np.nan, 5.9], [3.0, 6.1, 9.0],
    ...               [4.0, 7.9, np.nan], [5.0, 9.9, 15.1], [6.0, 12.0, 18.0]])
    >>> from nldr.impute import NearestNeighbourImputer
    >>> X_hat = NearestNeighbourImputer().fit_transform(X)
    >>> X_hat[1], X_hat[3]  # row 1 copies row 0's entry, row 3 row 2's
    (array([2. , 2. , 5.9]), array([4. , 7.9, 9. ]))
    """

    _require_observed_columns = False
    _standardizes = True

    _parameter_constraints: dict = {
        **MaskedImputerBase._parameter_constraints,
        "standardize": ["boolean"],
    }

    def __init__(self, missing_values=np.nan, *, standardize=True):
        self.missing_values = missing_values
        self.standardize = standardize

    def _solve(self, W, mask):
        result = nearest_neighbour_impute(np.where(mask, W, np.nan), mask)
        if not result.success:
            raise ValueError(
                "X has no fully observed row: 1-NN has no donor to copy from (the paper's NA); "
                "use another imputer, or fit on rows that include complete ones"
            )
        self.donors_ = W[mask.all(axis=1)]
        return result.x, result

    def _complete(self, W, mask):
        C = self.donors_
        # sum_j m_ij (w_ij - c_kj)^2 with W zero at the missing entries (as in the solver)
        D = (W * W).sum(axis=1)[:, None] - 2.0 * (W @ C.T) + mask.astype(np.float64) @ (C * C).T
        return np.where(mask, W, C[np.argmin(D, axis=1)])
