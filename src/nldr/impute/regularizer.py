"""The paper's method as a scikit-learn imputer: :class:`KernelRegularizerImputer`."""

from __future__ import annotations

import dataclasses

import numpy as np
from sklearn.utils import check_random_state

from .._options import ExactOptions, last_stage_only, solver_options
from .._threads import blas_threads_for
from .._validation import check_count, check_positive
from ..baselines._masked import mean_fill, observed_column_means
from ..data_terms import MaskedLeastSquares
from ..kernels import center_kernel, rbf_kernel, squared_distances
from ..preimage import Subspace, average_solutions, complete_from_starts, nearest_rows
from ..regularizer import minimize_regularized
from ._base import MaskedImputerBase

__all__ = ["KernelRegularizerImputer", "AUTO_EXACT_MAX_ROWS", "MEDIAN_RULE_MULTIPLE", "METHODS"]

#: solver paths of ``method``: "auto" and minimize_regularized's methods
METHODS = ("auto", "exact", "nystroem", "nystroem-warm")
#: keys of ``schedule``: minimize_regularized's penalty schedule
SCHEDULE_KEYS = ("rho0", "rho_growth", "rho_max")
#: ``method="auto"`` solves exactly up to this many rows and warm-starts from the Nystroem kernel above
#: (docs/PERFORMANCE.md, "The imputer's solver path").
AUTO_EXACT_MAX_ROWS = 150
#: options "exact" takes (method="auto" drops the others below AUTO_EXACT_MAX_ROWS rows)
_EXACT_OPTIONS = frozenset(f.name for f in dataclasses.fields(ExactOptions))
#: minimize_regularized's default penalty schedule
_DEFAULT_SCHEDULE = {"rho0": 1.0, "rho_max": 1e4}
#: the default width is this multiple of 1 / (median squared distance between rows), standardised units
#: (docs/REPRODUCTION.md, "The imputer's defaults")
MEDIAN_RULE_MULTIPLE = 0.25


def _median_rule_gamma(S: np.ndarray) -> float:
    """``MEDIAN_RULE_MULTIPLE / median ||s_i - s_j||^2`` over the pairs of rows of a complete S (units S^-2).

    The default width of :class:`KernelRegularizerImputer`: the median pair of rows gets kernel value
    exp(-1/4). Beyond 2000 rows an even subsample of 2000 sets the median.
    """
    n = S.shape[0]
    rows = S if n <= 2000 else S[np.linspace(0, n - 1, 2000).astype(int)]
    D = squared_distances(rows)
    med = float(np.median(D[np.triu_indices(rows.shape[0], 1)]))
    if not med > 0:
        raise ValueError(
            "the rows of X (after mean imputation) coincide: the median rule cannot set gamma; pass gamma"
        )
    return MEDIAN_RULE_MULTIPLE / med


class KernelRegularizerImputer(MaskedImputerBase):
    """Matrix completion with the non-linear dimensionality regularizer (Garg, Eriksson, Reid 2016).

    ``fit_transform(X)`` solves the paper's joint problem on X: over the completed matrix S and a
    kernel factor C,

        min ||mask o (X - S)||_F^2 + rho/2 ||K(S) - C^T C||_F^2 + tau ||C||_*,

    by the penalty method on rho (:func:`nldr.regularizer.minimize_regularized` with
    :class:`~nldr.data_terms.MaskedLeastSquares`, from mean imputation), with the RBF kernel
    ``K_ij = exp(-gamma ||s_i - s_j||^2)``. ``fit`` does the same and keeps the learnt manifold: the
    rows S and the kernel factor C, whose non-zero rows span the principal subspace in feature space.
    ``transform`` completes rows never seen against that manifold: the observed entries stay, the
    missing ones minimise the feature-space distance to the subspace (the pre-image problem of
    :mod:`nldr.preimage`, started from the nearest training rows on the observed entries). Rows seen
    in ``fit`` get their fitted estimate.

    The estimate of a training row is the solve's S, whose observed entries also move slightly (the
    data term is a penalty, not a constraint); ``transform`` keeps the observed entries of new rows.

    With no arguments this is the recommended configuration: columns standardised on their observed
    entries, the width by the median rule in standardised units, tau 0.1 in standardised units, the
    exact solver up to :data:`AUTO_EXACT_MAX_ROWS` rows and the Nystroem warm start above (evidence:
    docs/REPRODUCTION.md, "The imputer's defaults"). The paper's Table 2 is
    ``KernelRegularizerImputer(standardize=False, gamma=0.075, tau=0.1, method="exact")``.

    Parameters
    ----------
    missing_values : np.nan or float, default np.nan
        The marker of a missing entry (NaN is always missing too).
    gamma : float > 0 or None, default None
        RBF inverse squared width, in 1 / (units of the solved matrix)^2: standardised units when
        ``standardize``, the data's units otherwise. None: the median rule on the
        mean-imputed (standardised) matrix: :data:`MEDIAN_RULE_MULTIPLE` / (median squared distance
        between its rows).
    tau : float > 0, default 0.1
        Weight of the trace norm of C (the feature-space data's nuclear norm), in the data term's
        units (squared units of the solved matrix). Larger tau: a lower-dimensional manifold.
    standardize : bool, default True
        Solve on columns centred and scaled by their observed entries' mean and standard deviation
        (a constant column is only centred), and return the estimate in the data's units. False
        solves on X as given, the paper's setting.
    center : bool, default False
        Double-centre the kernel (the paper's Table 2 does not).
    method : {"auto", "exact", "nystroem", "nystroem-warm"}, default "auto"
        :func:`~nldr.regularizer.minimize_regularized`'s solver path. "exact": every penalty stage
        with the exact kernel. "nystroem-warm": the stages before the last on a Nystroem kernel of
        100 landmark rows, then the last stage exactly from there (an exact stopping test, possibly
        another local minimum: docs/PERFORMANCE.md). "nystroem": every stage on the Nystroem kernel
        (not the exact minimiser). "auto": "exact" up to :data:`AUTO_EXACT_MAX_ROWS` rows,
        "nystroem-warm" above.
    options : dict or None, default None
        The method's options, as :func:`~nldr.regularizer.minimize_regularized` takes them
        (tolerances, ``max_inner``, ``eigensolver``, ``landmarks``, ...); an option the method does
        not take is a ValueError naming the method (raised by every fit, before any solve). "auto"
        takes the options of "nystroem-warm"; its Nystroem-only ones (``landmarks``,
        ``landmark_seed``, ``exact_stages``, ``exact_tol``, ``last_landmarks``) apply only above
        :data:`AUTO_EXACT_MAX_ROWS` rows. The Nystroem methods' ``landmark_seed`` defaults to a draw
        from ``random_state``.
    schedule : dict or None, default None
        The penalty schedule: ``rho0``, ``rho_growth``, ``rho_max`` of
        :func:`~nldr.regularizer.minimize_regularized` (None: its defaults 1, 10, 1e4, the paper's).
    verbose : bool, default False
        Print one line per penalty stage.
    n_neighbors : int >= 1, default 5
        ``transform``: the training rows nearest to a new row on its observed entries, which give
        its starts.
    starts : {"mean", "each"}, default "mean"
        ``transform``: one start at the neighbours' mean, or one per neighbour with the local minima
        averaged (:meth:`nldr.robust_kpca.RobustKernelPCA.complete`).
    weights : {"uniform", "distance"}, default "uniform"
        ``transform`` with ``starts="each"``: how the local minima are averaged.
    random_state : int, RandomState or None, default None
        Seeds the landmark draw of the Nystroem warm start (the exact path draws nothing).
    warm_start : bool, default False
        A fit after a previous fit on a matrix of the same shape starts from the previous solve's S
        (``result_.x``) and solves the last penalty stage only (rho0 = rho_max), its stopping tests in
        the units of the full schedule (``options["scale"]`` = sqrt(rho0 of ``schedule``) unless
        ``options`` sets it). This is how a path of taus or widths is solved cheaply, e.g. by
        :class:`nldr.model_selection.HoldoutSearch` with ``path="tau"``. The first fit, or one on
        another shape, solves the full schedule from mean imputation.

    Attributes
    ----------
    gamma_, tau_ : float
        The width and weight used (standardised units when ``standardize``).
    method_ : str
        The solver path used, "exact" or "nystroem-warm".
    mean_, scale_ : arrays, shape (n_features,)
        The standardisation (zeros and ones when ``standardize`` is False).
    result_ : nldr.regularizer.RegularizerResult
        The solve (its ``x`` in standardised units when ``standardize``).
    completed_ : array, shape (n_samples, n_features)
        The estimate of the training matrix, in the data's units.
    manifold_rows_ : array, shape (n_samples, n_features)
        S, the rows of the learnt manifold (standardised units when ``standardize``).
    kernel_factor_ : array, shape (n_components_, n_samples)
        The non-zero rows of C (``diag(l) U^T``).
    n_components_ : int
        Rank of C: the dimension of the learnt manifold's principal subspace.
    n_features_in_ : int
    feature_names_in_ : array of str (when X has string column names)

    Examples
    --------
    >>> import numpy as np
    >>> from nldr.impute import KernelRegularizerImputer
    >>> rng = np.random.default_rng(0)
    >>> t = rng.uniform(0, 2 * np.pi, 60)
    >>> X = np.c_[np.cos(t), np.sin(t), 0.5 * np.cos(2 * t)]
    >>> X_missing = np.where(rng.random(X.shape) < 0.2, np.nan, X)
    >>> X_hat = KernelRegularizerImputer().fit_transform(X_missing)
    >>> bool(np.isfinite(X_hat).all())
    True
    """

    def __init__(
        self,
        missing_values=np.nan,
        *,
        gamma=None,
        tau=0.1,
        standardize=True,
        center=False,
        method="auto",
        options=None,
        schedule=None,
        verbose=False,
        n_neighbors=5,
        starts="mean",
        weights="uniform",
        random_state=None,
        warm_start=False,
    ):
        self.missing_values = missing_values
        self.gamma = gamma
        self.tau = tau
        self.standardize = standardize
        self.center = center
        self.method = method
        self.options = options
        self.schedule = schedule
        self.verbose = verbose
        self.n_neighbors = n_neighbors
        self.starts = starts
        self.weights = weights
        self.random_state = random_state
        self.warm_start = warm_start

    _min_samples = 2

    def _check_params(self):
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}; got {self.method!r}")
        if self.starts not in ("mean", "each"):
            raise ValueError(f"starts must be 'mean' or 'each'; got {self.starts!r}")
        if self.weights not in ("uniform", "distance"):
            raise ValueError(f"weights must be 'uniform' or 'distance'; got {self.weights!r}")
        check_count(self.n_neighbors, "n_neighbors")
        tau = check_positive(self.tau, "tau")
        gamma = None if self.gamma is None else check_positive(self.gamma, "gamma")
        if self.options is not None and not isinstance(self.options, dict):
            raise ValueError(f"options must be a dict of the method's options or None; got {self.options!r}")
        schedule = {} if self.schedule is None else self.schedule
        if not isinstance(schedule, dict) or set(schedule) - set(SCHEDULE_KEYS):
            raise ValueError(
                f"schedule must be a dict with keys among {SCHEDULE_KEYS} or None; got {schedule!r}"
            )
        options = dict(self.options or {})
        if self.method != "exact":
            options.setdefault("landmark_seed", 0)  # drawn from random_state at fit
        solver_options("nystroem-warm" if self.method == "auto" else self.method, options)
        if not isinstance(self.warm_start, bool | np.bool_):
            raise ValueError(f"warm_start must be True or False; got {self.warm_start!r}")
        return gamma, tau

    def _standardisation(self, W, mask):
        d = W.shape[1]
        if not self.standardize:
            return np.zeros(d), np.ones(d)
        mean = observed_column_means(W, mask)
        var = np.where(mask, W - mean, 0.0) ** 2
        sd = np.sqrt(var.sum(axis=0) / mask.sum(axis=0))
        return mean, np.where(sd > 0, sd, 1.0)

    def _solver_arguments(self, n: int, warm: bool) -> tuple[str, dict]:
        """The solver path and minimize_regularized's keyword arguments (checked by _check_params).
        ``warm``: the last penalty stage only, in the stopping units of the full schedule."""
        method = self.method
        if method == "auto":
            method = "exact" if n <= AUTO_EXACT_MAX_ROWS else "nystroem-warm"
        schedule = dict(self.schedule or {})
        options = dict(self.options or {})
        if method == "exact":
            options = {k: v for k, v in options.items() if k in _EXACT_OPTIONS}
        elif "landmark_seed" not in options:
            options["landmark_seed"] = int(
                check_random_state(self.random_state).randint(np.iinfo(np.int32).max)
            )
        kwargs = {"method": method, "options": options, "verbose": bool(self.verbose), **schedule}
        return method, last_stage_only(kwargs, **_DEFAULT_SCHEDULE) if warm else kwargs

    def _solve(self, W, mask):
        gamma, tau = self._check_params()
        self.mean_, self.scale_ = self._standardisation(W, mask)
        Z = W if not self.standardize else np.where(mask, (W - self.mean_) / self.scale_, 0.0)
        S0 = mean_fill(Z, mask)
        previous = getattr(self, "completed_", None) if self.warm_start else None
        warm = previous is not None and previous.shape == W.shape
        if warm:  # the previous estimate, in this fit's (standardised) units
            S0 = previous if not self.standardize else (previous - self.mean_) / self.scale_
        self.gamma_ = _median_rule_gamma(mean_fill(Z, mask)) if gamma is None else gamma
        self.tau_ = tau
        self.method_, kwargs = self._solver_arguments(W.shape[0], warm)
        result = minimize_regularized(
            MaskedLeastSquares(Z, mask), S0, gamma=self.gamma_, tau=tau, center=bool(self.center), **kwargs
        )
        S = result.x
        self.manifold_rows_ = S
        keep = np.flatnonzero(np.any(result.C != 0.0, axis=1))
        self.kernel_factor_ = result.C[keep]
        self.n_components_ = int(keep.size)
        X_hat = S if not self.standardize else S * self.scale_ + self.mean_
        return X_hat, result

    def _subspace(self) -> Subspace:
        """The principal subspace spanned by C's rows, in the form :mod:`nldr.preimage` takes."""
        S = self.manifold_rows_
        K = rbf_kernel(S, self.gamma_)
        column_means = K.mean(axis=0) if self.center else None
        if self.center:
            K = center_kernel(K)
        C = self.kernel_factor_
        U = C / np.linalg.norm(C, axis=1, keepdims=True)  # rows u_i^T of C = diag(l) U^T
        lam = np.einsum("in,nm,im->i", U, K, U)  # u_i^T K u_i, the eigenvalues of the kept axes
        return Subspace(X_fit=S, gamma=self.gamma_, V=U.T / np.sqrt(lam)[None, :], column_means=column_means)

    def _complete(self, W, mask):
        if self.n_components_ == 0:
            raise ValueError(
                f"the fitted manifold has no component (tau = {self.tau_:g} removed them all): "
                "transform cannot complete new rows; lower tau"
            )
        Z = np.where(mask, (W - self.mean_) / self.scale_, 0.0)
        S = self.manifold_rows_
        nearest, distance = nearest_rows(S, Z, mask, self.n_neighbors)
        rows = S[nearest]
        rows[~mask.any(axis=1)] = S.mean(axis=0)
        if self.starts == "mean":
            rows = rows.mean(axis=1, keepdims=True)
        X0 = np.where(mask[:, None, :], Z[:, None, :], rows)
        with blas_threads_for(S.shape[0]):
            X_hat = complete_from_starts(self._subspace(), Z, mask, X0)
        X_hat = X_hat[:, 0] if self.starts == "mean" else average_solutions(X_hat, distance, self.weights)
        return np.where(mask, W, X_hat * self.scale_ + self.mean_)
