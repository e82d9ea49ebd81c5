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

import inspect
from collections.abc import Mapping

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin, clone

from .._options import merge_solver_kwargs, solver_options
from .._validation import check_positive
from ..baselines._masked import mean_fill
from ..data_terms import MaskedHuber, MaskedLeastSquares
from ..regularizer import minimize_regularized

__all__ = ["HUBER_EFFICIENCY", "robust_scale", "RobustScaleDelta", "HuberRegularizer"]

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


#: keywords of minimize_regularized a HuberRegularizer's ``solver`` may set (the others it sets itself)
_SOLVER_KEYWORDS = frozenset(inspect.signature(minimize_regularized).parameters) - {
    "data_term", "S0", "gamma", "tau", "center"
}


class HuberRegularizer(TransformerMixin, BaseEstimator):
    """The regularizer with the Huber data term (:class:`~nldr.data_terms.MaskedHuber`), transductive.

    ``fit_transform(X)`` (NaN where missing) runs :func:`~nldr.regularizer.minimize_regularized` from
    mean imputation on X's observed entries in X's units, with the isolation guard, and returns the
    solve's S (n, d); ``loss="squared"`` uses :class:`~nldr.data_terms.MaskedLeastSquares` instead (the
    least-squares fit of :class:`RobustScaleDelta`). It completes the matrix it is fitted on only.

    Parameters
    ----------
    gamma : float > 0
        RBF inverse squared width (1 / units of X squared).
    tau : float > 0
        Trace-norm weight.
    delta : float > 0, default 1.0
        Huber threshold (units of X); :class:`RobustScaleDelta` sets it per fit in a search.
    loss : {"huber", "squared"}, default "huber"
    center : bool, default False
    solver : dict, optional
        Further keyword arguments of ``minimize_regularized`` (``rho0``, ``rho_growth``, ``rho_max``,
        ``method``, ``options``).

    Attributes
    ----------
    result_ : nldr.regularizer.RegularizerResult
    """

    def __init__(self, gamma=1.0, tau=0.1, delta=1.0, loss="huber", center=False, solver=None):
        self.gamma = gamma
        self.tau = tau
        self.delta = delta
        self.loss = loss
        self.center = center
        self.solver = solver

    def _check_params(self):
        if self.loss not in ("huber", "squared"):
            raise ValueError(f"loss must be 'huber' or 'squared'; got {self.loss!r}")
        check_positive(self.delta, "delta")
        if self.solver is not None and not isinstance(self.solver, Mapping):
            raise ValueError(f"solver must be a dict of minimize_regularized's keywords; got {self.solver!r}")
        solver = dict(self.solver or {})
        unknown = sorted(set(solver) - _SOLVER_KEYWORDS)
        if unknown:
            raise ValueError(
                f"solver: minimize_regularized takes no keyword {', '.join(map(repr, unknown))}; "
                f"these are set here or unknown (its others: {', '.join(sorted(_SOLVER_KEYWORDS))})"
            )
        solver_options(solver.get("method", "exact"), solver.get("options"))  # the method's own options

    def fit_transform(self, X, y=None):
        """Solve on X, shape (n, d), NaN where missing; return the solve's S, shape (n, d)."""
        self._check_params()
        X = np.asarray(X, dtype=np.float64)
        mask = ~np.isnan(X)
        W = np.where(mask, X, 0.0)
        term = MaskedHuber(W, mask, self.delta) if self.loss == "huber" else MaskedLeastSquares(W, mask)
        kwargs = merge_solver_kwargs(self.solver, {"options": {"isolation_guard": True}})
        self.result_ = minimize_regularized(
            term, mean_fill(W, mask), gamma=self.gamma, tau=self.tau, center=bool(self.center), **kwargs
        )
        return self.result_.x

    def fit(self, X, y=None):
        """:meth:`fit_transform` on X; returns self."""
        self.fit_transform(X)
        return self
