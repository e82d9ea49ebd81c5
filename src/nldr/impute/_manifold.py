"""Completion and denoising of new rows against a manifold learnt from complete rows.

- :class:`RobustKernelPCAImputer`: the closed-form robust kernel PCA
  (:class:`nldr.robust_kpca.RobustKernelPCA`, the paper's Theorem 3.1 on the training kernel) learnt
  from the fully observed training rows; ``transform`` completes, and with a finite ``rho``
  denoises, rows against it (:meth:`~nldr.robust_kpca.RobustKernelPCA.complete`).
- :class:`DecompositionDenoiser`: any decomposition with ``inverse_transform`` (scikit-learn's ``PCA``,
  ``KernelPCA(fit_inverse_transform=True)``) as a denoiser, ``X -> inverse_transform(transform(X))``.

Unlike :class:`~nldr.impute.KernelRegularizerImputer`, neither is transductive: ``transform`` of a
row depends on the fitted model and that row only, so ``fit_transform(X)`` is ``fit(X).transform(X)``.
"""

from __future__ import annotations

import warnings
from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator, OneToOneFeatureMixin, TransformerMixin, _fit_context, clone
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

from .._preimage import LOSSES, average_solutions
from .._spectral import EIGENSOLVERS
from ..robust_kpca import RobustKernelPCA, rank_penalty_threshold
from ._base import MaskedImputerBase

__all__ = ["RobustKernelPCAImputer", "DecompositionDenoiser"]


class RobustKernelPCAImputer(MaskedImputerBase):
    """New rows completed (and optionally denoised) against the robust kernel PCA of complete rows.

    ``fit`` learns the manifold once from the training rows with every entry observed (rows with a
    missing entry do not enter it); ``transform`` completes each new row by the pre-image problem
    (Notes). This needs complete training rows (a clean reference set; learn once, complete new rows);
    to learn the manifold from incomplete rows, use :class:`~nldr.impute.KernelRegularizerImputer`.
    Not transductive: ``fit_transform(X)`` is ``fit(X).transform(X)`` (with ``rho=None`` the complete
    training rows come back unchanged).

    Parameters
    ----------
    missing_values : np.nan or float, default np.nan
    standardize : bool, default True
        Learn and complete on the columns standardised by the training matrix's observed entries'
        mean and standard deviation (a constant column is only centred) and return rows in the data's
        units, so that the completion is unit-free per column; ``gamma`` and ``delta`` are then in
        standardised units. False works on X as given.
    gamma : float > 0 or None, default None
        RBF inverse squared width, 1 / (units of the solved matrix)^2; None: 1 / n_features.
    tau : float > 0, default 1.0
        Trace-norm weight of the closed form (kernel units; larger tau, fewer components).
    center : bool, default True
        Centre the kernel in feature space (as kernel PCA does).
    eigensolver : {"auto", "partial", "krylov", "full"}, default "auto"
        How the training kernel is decomposed (:class:`~nldr.robust_kpca.RobustKernelPCA`).
    rho : float > 0 or None, default None
        ``transform``: weight of the squared feature distance (kernel units) against the data loss
        (units of X squared); None is the hard limit (completion only).
    loss : {"squared", "huber"}, default "squared"
        ``transform``'s data loss on the observed entries (with ``rho=None`` it only ranks the
        neighbours).
    delta : float > 0 or None, default None
        The Huber threshold (units of X); required with ``loss="huber"``.
    n_neighbors : int >= 1, default 5
        Training rows nearest on the observed entries, which give the starts.
    starts : {"mean", "each"}, default "mean"
    weights : {"uniform", "distance"}, default "uniform"
        How ``starts="each"`` averages its local minima (by inverse root-mean loss with "distance").
    warm_start : bool, default False
        Reuse work across fits and transforms that differ only in ``transform``'s knobs, as a search
        over ``n_neighbors``, ``starts`` and ``weights`` does (:class:`nldr.model_selection.HoldoutSearch`
        with ``path="n_neighbors"``, the neighbour counts in decreasing order):

        - a fit on the same complete rows with the same ``gamma``, ``tau``, ``center`` and
          ``eigensolver`` keeps the fitted manifold (the closed form would return it again);
        - a ``transform`` with ``starts="each"`` of the same rows as the previous one, with the same
          ``rho``, ``loss`` and ``delta`` and no more neighbours, averages the previous
          transform's local minima from its first ``n_neighbors`` neighbours instead of solving again
          (every ``starts="each"`` transform keeps its local minima for this).
          Those are the same starts; with ``rho=None`` each row is solved on its own, so the answer
          matches a cold transform up to rounding; with a finite ``rho`` the rows are solved in
          blocks that share L-BFGS's stopping test, so it matches to the solver's tolerance.

    Attributes
    ----------
    model_ : nldr.robust_kpca.RobustKernelPCA
        The manifold, fitted on the complete training rows (in the solved units).
    shift_, scale_ : arrays, shape (n_features,)
        The standardisation (zeros and ones when ``standardize`` is False): the solved units are
        ``(X - shift_) / scale_``.
    gamma_ : float
    n_components_ : int
        Components of the learnt principal subspace.
    n_features_in_ : int
    feature_names_in_ : array of str (when X has string column names)

    See Also
    --------
    nldr.robust_kpca.RobustKernelPCA : The closed-form manifold this completes against.
    KernelRegularizerImputer : Learns the manifold from incomplete rows.

    Notes
    -----
    The manifold is the RBF kernel's eigenvalues shrunk in closed form by tau
    (:class:`nldr.robust_kpca.RobustKernelPCA` with rho = 1; the number of components follows from
    tau). ``transform`` solves, per row w with observation mask m,

        min_x sum_j m_j l(x_j - w_j) + rho * dist(phi(x), principal subspace)^2

    (:meth:`~nldr.robust_kpca.RobustKernelPCA.complete`): ``rho=None`` keeps the observed entries
    and completes the missing ones; a finite rho lets every entry move (denoising), with the squared
    or the Huber loss ``l``. The problem is not convex: the starts come from the ``n_neighbors``
    training rows nearest on the observed entries, at their mean (``starts="mean"``) or one solve
    from each with the local minima averaged (``starts="each"``).

    Examples
    --------
    >>> import numpy as np
    >>> from nldr.impute import RobustKernelPCAImputer
    >>> X_train = np.array([[1.0, 2.0, 3.0], [3.0, 6.1, 9.0], [5.0, 9.9, 15.1], [6.0, 12.0, 18.0]])
    >>> X_new = np.array([[2.0, np.nan, 6.0], [4.0, 7.9, np.nan]])
    >>> imputer = RobustKernelPCAImputer(gamma=0.05, tau=0.01).fit(X_train)
    >>> X_hat = imputer.transform(X_new)
    >>> X_hat.shape, bool(np.isnan(X_hat).any())
    ((2, 3), False)
    >>> observed = ~np.isnan(X_new)
    >>> bool(np.array_equal(X_hat[observed], X_new[observed]))  # rho=None keeps the observed entries
    True
    """

    _require_observed_columns = False
    _min_samples = 2
    _standardizes = True

    def __init__(
        self,
        missing_values=np.nan,
        *,
        standardize=True,
        gamma=None,
        tau=1.0,
        center=True,
        eigensolver="auto",
        rho=None,
        loss="squared",
        delta=None,
        n_neighbors=5,
        starts="mean",
        weights="uniform",
        warm_start=False,
    ):
        self.missing_values = missing_values
        self.standardize = standardize
        self.gamma = gamma
        self.tau = tau
        self.center = center
        self.eigensolver = eigensolver
        self.rho = rho
        self.loss = loss
        self.delta = delta
        self.n_neighbors = n_neighbors
        self.starts = starts
        self.weights = weights
        self.warm_start = warm_start

    _parameter_constraints: dict = {
        **MaskedImputerBase._parameter_constraints,
        "standardize": ["boolean"],
        "gamma": [Interval(Real, 0, np.inf, closed="neither"), None],
        "tau": [Interval(Real, 0, np.inf, closed="neither")],
        "center": ["boolean"],
        "eigensolver": [StrOptions(set(EIGENSOLVERS))],
        "rho": [Interval(Real, 0, np.inf, closed="neither"), None],
        "loss": [StrOptions(set(LOSSES))],
        "delta": [Interval(Real, 0, np.inf, closed="neither"), None],
        "n_neighbors": [Interval(Integral, 1, None, closed="left")],
        "starts": [StrOptions({"mean", "each"})],
        "weights": [StrOptions({"uniform", "distance"})],
        "warm_start": ["boolean"],
    }

    def _validate_params(self) -> None:
        """Every parameter against its constraint, then the rule that ties two of them together."""
        super()._validate_params()
        if self.loss == "huber" and self.delta is None:
            raise ValueError("delta (the Huber threshold, units of X) is required with loss='huber'")

    def _manifold_key(self) -> tuple:
        return (self.gamma, self.tau, bool(self.center), self.eigensolver, bool(self.standardize))

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y=None):
        """Learn the manifold from the rows of X (n, n_features) with every entry observed; y is
        ignored. Returns self."""
        W, mask = self._validated(X, reset=True)
        self._units(W, mask)
        rows = self._standardised(W, mask)[mask.all(axis=1)]
        if rows.shape[0] < 2:
            raise ValueError(
                f"X has {rows.shape[0]} fully observed row(s): RobustKernelPCAImputer learns its manifold "
                "from complete rows and needs at least 2; use KernelRegularizerImputer to learn from "
                "incomplete rows"
            )
        previous = getattr(self, "model_", None)
        if not (
            self.warm_start
            and previous is not None
            and self._fitted_key == self._manifold_key()
            and np.array_equal(previous.X_fit_, rows)
        ):
            with warnings.catch_warnings():  # its warning speaks of its own transform's (n, 0) arrays
                warnings.filterwarnings("ignore", message=".*removes every component", category=UserWarning)
                self.model_ = RobustKernelPCA(
                    gamma=self.gamma, tau=self.tau, center=bool(self.center), eigensolver=self.eigensolver
                ).fit(rows)
            if self.model_.n_components_ == 0:
                warnings.warn(
                    f"tau = {self.tau:g} removes every component of the manifold (every eigenvalue of "
                    f"the complete rows' kernel is below the threshold "
                    f"{rank_penalty_threshold(self.tau, 1.0):.3g}): transform still returns "
                    f"(n, {rows.shape[1]}) arrays, but no principal subspace guides their missing "
                    "entries. Lower tau",
                    UserWarning,
                    stacklevel=2,
                )
            self._fitted_key = self._manifold_key()
            self._solutions = None
        self.gamma_ = float(self.model_.gamma_)
        self.n_components_ = int(self.model_.n_components_)
        return self

    @_fit_context(prefer_skip_nested_validation=True)
    def fit_transform(self, X, y=None):
        """``fit(X).transform(X)``: X (n, n_features) completed against the manifold learnt from
        its complete rows, a float64 array whatever X's dtype (the solvers run in float64)."""
        return self.fit(X).transform(X)

    def transform(self, X):
        """Complete (with finite ``rho``, denoise) the rows of X, shape (m, n_features), against the
        learnt manifold. Returns X_hat, a float64 array (m, n_features) whatever X's dtype (the
        solvers run in float64)."""
        check_is_fitted(self, "model_")
        self._validate_params()  # transform's knobs may have been set since fit
        W, mask = self._validated(X, reset=False)
        Z = self._standardised(W, mask)
        return self._in_data_units(self._complete(Z, mask), Z, W, mask)

    def _complete(self, W, mask):
        kw = {"rho": self.rho, "loss": self.loss, "delta": self.delta}
        k = int(self.n_neighbors)
        if self.starts == "mean":
            return self.model_.complete(W, mask, n_neighbors=k, starts="mean", **kw)
        memo = getattr(self, "_solutions", None) if self.warm_start else None
        if not (
            memo is not None
            and memo["kw"] == kw
            and memo["k"] >= k
            and np.array_equal(memo["W"], W)
            and np.array_equal(memo["mask"], mask)
        ):
            solutions, distance = self.model_.complete_each(W, mask, n_neighbors=k, **kw)
            memo = {"kw": kw, "k": k, "W": W, "mask": mask, "solutions": solutions, "distance": distance}
            self._solutions = memo  # kept for a warm transform that follows
        return average_solutions(memo["solutions"][:, :k], memo["distance"][:, :k], self.weights)


class DecompositionDenoiser(OneToOneFeatureMixin, TransformerMixin, BaseEstimator):
    """A decomposition as a denoiser: ``transform(X) = estimator.inverse_transform(estimator.transform(X))``.

    The estimator (cloned) is fitted on the training rows; each row is replaced by its
    reconstruction from the fitted components, e.g. ``DecompositionDenoiser(PCA(8))`` or
    ``DecompositionDenoiser(KernelPCA(16, kernel="rbf", fit_inverse_transform=True))``. It needs complete
    rows: put a ``SimpleImputer`` before it in a ``Pipeline`` to fill missing entries first.

    Parameters
    ----------
    estimator : estimator with ``fit``, ``transform`` and ``inverse_transform``

    Attributes
    ----------
    estimator_ : the fitted clone
    n_features_in_ : int

    See Also
    --------
    RobustKernelPCAImputer : Denoises against the closed-form robust kernel PCA (with finite ``rho``).

    Notes
    -----
    The reconstruction lies in the span of the fitted components: PCA's projection, or KernelPCA's
    learnt pre-image map.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.decomposition import PCA
    >>> from nldr.impute import DecompositionDenoiser
    >>> X = np.array([[1.0, 2.0, 3.0], [2.0, 4.1, 5.9], [3.0, 6.1, 9.0], [4.0, 7.9, 12.1]])
    >>> X_denoised = DecompositionDenoiser(PCA(1)).fit_transform(X)
    >>> X_denoised.shape, int(np.linalg.matrix_rank(X_denoised - X_denoised.mean(axis=0)))
    ((4, 3), 1)
    """

    def __init__(self, estimator=None):
        self.estimator = estimator

    #: a decomposition such as PCA: the three methods the reconstruction calls
    _parameter_constraints: dict = {"estimator": [HasMethods(["fit", "transform", "inverse_transform"])]}

    # the estimator is the user's, not validated here: its own fit validates it
    @_fit_context(prefer_skip_nested_validation=False)
    def fit(self, X, y=None):
        """Fit the estimator on X, shape (n, n_features). Returns self."""
        X = validate_data(self, X, dtype=np.float64)
        self.estimator_ = clone(self.estimator).fit(X)
        return self

    def transform(self, X):
        """The reconstruction of X, shape (m, n_features)."""
        check_is_fitted(self, "estimator_")
        X = validate_data(self, X, reset=False, dtype=np.float64)
        return np.asarray(self.estimator_.inverse_transform(self.estimator_.transform(X)), dtype=np.float64)

