"""The kernel baselines of the paper's Table 2 as scikit-learn imputers: :class:`PKPCAImputer`
(probabilistic kernel PCA, Sanguinetti & Lawrence 2006) and :class:`RKPCAImputer` (robust kernel
PCA, Nguyen & De la Torre 2008). Both solve with the outer loop of :mod:`nldr._baselines._lbfgs` and
complete new rows the same way: the missing entries minimise the feature-space distance to the
fitted principal subspace (:func:`nldr._preimage.complete_rows`), from the mean of the five training
rows nearest on the observed entries.
"""

from __future__ import annotations

from numbers import Integral, Real

import numpy as np
from sklearn.utils._param_validation import Interval

from .._baselines import pkpca_impute, rkpca_impute
from .._baselines._masked import mean_fill
from .._preimage import Subspace, complete_from_starts, nearest_rows
from ..kernels import center_kernel, rbf_kernel, squared_distances
from ._base import MaskedImputerBase

__all__ = ["PKPCAImputer", "RKPCAImputer"]

#: training rows whose mean starts a new row's completion
_START_NEIGHBOURS = 5


def _median_gamma(W: np.ndarray, mask: np.ndarray) -> float:
    """1 / median squared distance between the rows of the mean-filled W (units of W^-2)."""
    D = squared_distances(mean_fill(W, mask))
    med = float(np.median(D[np.triu_indices(D.shape[0], 1)]))
    if not med > 0:
        raise ValueError("the rows of X (after mean imputation) coincide: no median distance; pass gamma")
    return 1.0 / med


def _subspace(X: np.ndarray, gamma: float, q: int, centred: bool) -> Subspace:
    """The q leading axes of the (centred) RBF kernel of complete X, in :mod:`nldr._preimage`'s form."""
    K = rbf_kernel(X, gamma)
    column_means = K.mean(axis=0) if centred else None
    lam, U = np.linalg.eigh(center_kernel(K) if centred else K)
    lam, U = lam[::-1][:q], U[:, ::-1][:, :q]
    keep = lam > lam[0] * 1e-12
    return Subspace(X, gamma, U[:, keep] / np.sqrt(lam[keep])[None, :], column_means)


def _complete_on(space: Subspace, W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """New rows (m, d): observed entries kept, missing ones at the subspace's pre-image."""
    nearest, _ = nearest_rows(space.X_fit, W, mask, _START_NEIGHBOURS)
    start = space.X_fit[nearest].mean(axis=1)
    start[~mask.any(axis=1)] = space.X_fit.mean(axis=0)
    X0 = np.where(mask, W, start)
    X_hat = complete_from_starts(space, W, mask, X0[:, None, :])[:, 0]
    return np.where(mask, W, X_hat)


class _KernelBaseline(MaskedImputerBase):
    _min_samples = 3
    _standardizes = True
    _parameter_constraints: dict = {
        **MaskedImputerBase._parameter_constraints,
        "standardize": ["boolean"],
        "gamma": [Interval(Real, 0, np.inf, closed="neither"), None],
        "max_iter": [Interval(Integral, 1, None, closed="left")],
        "inner_max_iter": [Interval(Integral, 1, None, closed="left")],
        "gtol": [Interval(Real, 0, np.inf, closed="neither")],
    }
    #: the solver function and whether its subspace is centred
    _solver = None
    _centred = False

    def _mean_fill_cause(self) -> str:
        return (
            "the data's units with standardize=False: gtol is absolute (per unit of X), so on large "
            "entries the start already meets it, and gamma is in 1 / (units of X)^2; rescale X, "
            "scale gtol and gamma with it, or standardize"
        )

    def _solve(self, W, mask):
        self.gamma_ = _median_gamma(W, mask) if self.gamma is None else float(self.gamma)
        solver = {"max_iter": self.max_iter, "inner_max_iter": self.inner_max_iter, "gtol": self.gtol}
        result = type(self)._solver(np.where(mask, W, np.nan), mask, self.gamma_, **self._knobs(), **solver)
        self.n_components_ = int(result.n_components)
        rows = getattr(result, "Y", result.x)  # RKPCA's energy minimiser (x keeps the observed entries)
        self.subspace_ = _subspace(rows, self.gamma_, self.n_components_, centred=self._centred)
        return result.x, result

    def _complete(self, W, mask):
        return _complete_on(self.subspace_, W, mask)


class PKPCAImputer(_KernelBaseline):
    """Probabilistic kernel PCA with missing data (the "PKPCA" of the paper's Table 2).

    PPCA in the feature space of an uncentred RBF kernel; the missing entries maximise its profile
    likelihood (:func:`nldr._baselines.pkpca_impute`, from mean imputation). ``transform`` completes
    new rows against the fitted feature-space principal subspace (module docstring).

    Parameters
    ----------
    missing_values : np.nan or float, default np.nan
    standardize : bool, default True
        Solve on the columns standardised by their observed entries' mean and standard deviation (a
        constant column is only centred) and return the estimate in the data's units, so that the
        completion is unit-free per column; the parameters in units of X are then in standardised
        units. False solves on X as given (the paper's Table 2 setting, with its gamma in X's units).
    gamma : float > 0 or None, default None
        RBF inverse squared width, ``K_ij = exp(-gamma ||x_i - x_j||^2)``, in 1 / (units of X)^2 (the
        paper: 0.075 on oil flow). None: 1 / (median squared distance between the rows of the
        mean-imputed X).
    n_components : int or None, default None
        The number q of feature-space components (1 <= q < n_samples); None re-chooses q in every
        outer iteration as the fewest leading kernel eigenvalues holding ``variance_fraction`` of the
        trace, plus ``extra_components`` (Sanguinetti & Lawrence's rule).
    variance_fraction : float in (0, 1], default 0.95
    extra_components : int >= 0, default 1
    max_iter : int >= 1, default 20
        Outer iterations (component refits) at most.
    inner_max_iter : int >= 1, default 500
        L-BFGS iterations per outer iteration at most.
    gtol : float > 0, default 1e-4
        L-BFGS stops when the largest projected-gradient entry is below gtol (units of the profile
        likelihood per unit of X).

    Attributes
    ----------
    gamma_ : float
    n_components_ : int, q of the final model
    shift_, scale_ : arrays, shape (n_features,)
        The standardisation (zeros and ones when ``standardize`` is False): the other fitted
        attributes and ``result_`` are in the solved units, ``(X - shift_) / scale_``.
    result_ : nldr._baselines.PKPCAResult
    completed_ : array, shape (n_samples, n_features)
    subspace_ : nldr._preimage.Subspace, the fitted principal subspace (uncentred)
    n_features_in_ : int

    See Also
    --------
    PPCAImputer : The same model in the data space.
    RKPCAImputer : The paper's other kernel baseline.
    KernelRegularizerImputer : The paper's method.

    Notes
    -----
    The profile likelihood's gradient with respect to the missing entries follows from the envelope
    theorem (the maintenance note of :mod:`nldr._baselines.pkpca`); the outer loop refits the
    components and the inner one moves the missing entries by L-BFGS.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[1.0, 2.0, 3.0], [2.0, np.nan, 5.9], [3.0, 6.1, 9.0],
    ...               [4.0, 7.9, np.nan], [5.0, 9.9, 15.1], [6.0, 12.0, 18.0]])
    >>> from nldr.impute import PKPCAImputer
    >>> X_hat = PKPCAImputer().fit_transform(X)
    >>> X_hat.shape, bool(np.isnan(X_hat).any())
    ((6, 3), False)
    >>> observed = ~np.isnan(X)
    >>> bool(np.array_equal(X_hat[observed], X[observed]))
    True
    """

    def __init__(
        self,
        missing_values=np.nan,
        *,
        standardize=True,
        gamma=None,
        n_components=None,
        variance_fraction=0.95,
        extra_components=1,
        max_iter=20,
        inner_max_iter=500,
        gtol=1e-4,
    ):
        self.missing_values = missing_values
        self.standardize = standardize
        self.gamma = gamma
        self.n_components = n_components
        self.variance_fraction = variance_fraction
        self.extra_components = extra_components
        self.max_iter = max_iter
        self.inner_max_iter = inner_max_iter
        self.gtol = gtol

    _parameter_constraints: dict = {
        **_KernelBaseline._parameter_constraints,
        "n_components": [Interval(Integral, 1, None, closed="left"), None],
        "variance_fraction": [Interval(Real, 0, 1, closed="right")],
        "extra_components": [Interval(Integral, 0, None, closed="left")],
    }

    _solver = staticmethod(pkpca_impute)

    def _knobs(self):
        return {
            "n_components": self.n_components,
            "variance_fraction": self.variance_fraction,
            "extra_components": self.extra_components,
        }


class RKPCAImputer(_KernelBaseline):
    """Robust kernel PCA for missing data (the "RKPCA" of the paper's Table 2).

    Each row's energy is its squared feature-space distance to the centred KPCA subspace of q
    components plus ``weight`` times its squared error on the observed entries; the missing entries
    minimise the summed energy with the subspace refitted (:func:`nldr._baselines.rkpca_impute`, from
    mean imputation). ``transform`` completes new rows against the fitted subspace.

    Parameters
    ----------
    missing_values : np.nan or float, default np.nan
    standardize : bool, default True
        Solve on the columns standardised by their observed entries' mean and standard deviation (a
        constant column is only centred) and return the estimate in the data's units, so that the
        completion is unit-free per column; the parameters in units of X are then in standardised
        units. False solves on X as given (the paper's Table 2 setting, with its gamma in X's units).
    gamma : float > 0 or None, default None
        RBF inverse squared width in 1 / (units of X)^2 (the paper: 0.075 on oil flow). None:
        1 / (median squared distance between the rows of the mean-imputed X).
    n_components : int or float, default 7
        Components q of the centred KPCA subspace (1 <= q < n_samples), or a trace fraction in
        (0, 1) from which q is re-chosen every outer iteration.
    weight : float >= 0 or inf, default inf
        Weight of the data term on observed entries (units of X^-2); inf keeps them fixed.
    max_iter : int >= 1, default 20
        Outer iterations (subspace refits) at most.
    inner_max_iter : int >= 1, default 2000
        L-BFGS iterations per outer iteration at most.
    gtol : float > 0, default 1e-6
        L-BFGS stops when the largest projected-gradient entry is below gtol (energy units per unit
        of X).

    Attributes
    ----------
    gamma_ : float
    n_components_ : int, q of the final subspace
    shift_, scale_ : arrays, shape (n_features,)
        The standardisation (zeros and ones when ``standardize`` is False): the other fitted
        attributes and ``result_`` are in the solved units, ``(X - shift_) / scale_``.
    result_ : nldr._baselines.RKPCAResult
    completed_ : array, shape (n_samples, n_features)
    subspace_ : nldr._preimage.Subspace, the fitted principal subspace (centred)
    n_features_in_ : int

    See Also
    --------
    PKPCAImputer : The paper's other kernel baseline.
    KernelRegularizerImputer : The paper's method.

    Notes
    -----
    With ``weight=inf`` the observed entries stay fixed and only the missing ones move; the
    subspace is refitted between L-BFGS runs on the profile energy until it stops changing.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[1.0, 2.0, 3.0], [2.0, np.nan, 5.9], [3.0, 6.1, 9.0],
    ...               [4.0, 7.9, np.nan], [5.0, 9.9, 15.1], [6.0, 12.0, 18.0]])
    >>> from nldr.impute import RKPCAImputer
    >>> X_hat = RKPCAImputer(n_components=2).fit_transform(X)  # q < n_samples
    >>> X_hat.shape, bool(np.isnan(X_hat).any())
    ((6, 3), False)
    >>> observed = ~np.isnan(X)
    >>> bool(np.array_equal(X_hat[observed], X[observed]))
    True
    """

    def __init__(
        self,
        missing_values=np.nan,
        *,
        standardize=True,
        gamma=None,
        n_components=7,
        weight=np.inf,
        max_iter=20,
        inner_max_iter=2000,
        gtol=1e-6,
    ):
        self.missing_values = missing_values
        self.standardize = standardize
        self.gamma = gamma
        self.n_components = n_components
        self.weight = weight
        self.max_iter = max_iter
        self.inner_max_iter = inner_max_iter
        self.gtol = gtol

    _parameter_constraints: dict = {
        **_KernelBaseline._parameter_constraints,
        "n_components": [Interval(Integral, 1, None, closed="left"), Interval(Real, 0, 1, closed="neither")],
        "weight": [Interval(Real, 0, np.inf, closed="both")],
    }

    _solver = staticmethod(rkpca_impute)
    _centred = True

    def _knobs(self):
        return {"n_components": self.n_components, "weight": self.weight}
