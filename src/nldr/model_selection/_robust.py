"""The Huber threshold of a robust fit by a robust-scale rule (:class:`RobustScaleDelta`), a
``derive`` hook of :class:`~nldr.model_selection.HoldoutSearch`.

The Huber threshold delta and tau trade off against each other (an outlier pulls with force 2 delta
against the regularizer's tau), so delta is not a free third grid axis but follows a robust-scale
rule for every candidate (tau, gamma), the one-step M-estimate recipe:

1. the least-squares fit at (tau, gamma) on the fit's own training entries;
2. sigma = 1.4826 x the median absolute deviation of its residuals on those entries (a consistent
   estimate of a Gaussian standard deviation that up to half the residuals being gross errors cannot
   break);
3. delta = ``factor`` x sigma (Huber's 1.345: 95 % efficiency under Gaussian noise);
4. the Huber fit at (tau, gamma, delta), scored on the fold's hidden entries.

Score such a search by the absolute error per hidden entry (``scoring="absolute"``): the hidden
entries are corrupted too, and a squared score would be dominated by the outliers among them, which no
method can predict.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from sklearn.base import clone

from .._validation import check_positive

__all__ = ["HUBER_EFFICIENCY", "robust_scale", "RobustScaleDelta"]

#: Huber's threshold for 95 % efficiency at the Gaussian, in standard deviations.
HUBER_EFFICIENCY = 1.345


def robust_scale(residuals) -> float:
    """1.4826 x the median absolute deviation from the median of ``residuals`` (1-d, units kept).

    Raises a ValueError if the residuals are empty or the scale is 0 (more than half of them equal).
    """
    r = np.asarray(residuals, dtype=np.float64).ravel()
    if r.size == 0:
        raise ValueError("residuals must not be empty")
    scale = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    if not scale > 0:
        raise ValueError("residuals have zero median absolute deviation: no scale to set delta from")
    return scale


class RobustScaleDelta:
    """``derive`` hook: the Huber threshold of a fit from the least-squares fit's residuals.

    Called as ``hook(estimator, X_train)`` (the estimator at a candidate's parameters, X_train with
    NaN where the fit may not look), it fits a clone with ``least_squares`` set on X_train and returns
    ``{delta_param: factor * robust_scale(residuals on the observed entries of X_train)}``.

    Parameters
    ----------
    factor : float > 0, default 1.345
    least_squares : dict, default ``{"loss": "squared"}``
        The parameters that turn the estimator into its least-squares version.
    delta_param : str, default "delta"
    """

    def __init__(
        self,
        factor: float = HUBER_EFFICIENCY,
        least_squares: Mapping | None = None,
        delta_param: str = "delta",
    ):
        self.factor = check_positive(factor, "factor")
        self.least_squares = dict({"loss": "squared"} if least_squares is None else least_squares)
        self.delta_param = delta_param

    def __call__(self, estimator, X_train) -> dict:
        fit = clone(estimator).set_params(**self.least_squares)
        S = np.asarray(fit.fit_transform(X_train), dtype=np.float64)
        observed = ~np.isnan(X_train)
        return {self.delta_param: self.factor * robust_scale((X_train - S)[observed])}

    def __repr__(self) -> str:
        return f"RobustScaleDelta(factor={self.factor}, least_squares={self.least_squares})"
