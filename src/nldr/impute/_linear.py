"""Linear low-rank imputers: :class:`PPCAImputer` (probabilistic PCA, Table 2's "PPCA"),
:class:`SoftImputer` (nuclear-norm completion) and :class:`RobustPCAImputer` (principal component
pursuit). New rows are completed from the fitted linear model (each class says how)."""

from __future__ import annotations

from numbers import Integral, Real

import numpy as np
from sklearn.utils._param_validation import Interval

from .._baselines import ppca_impute, soft_impute
from .._baselines._masked import mean_fill
from .._baselines.rpca import rpca_impute
from ._base import MaskedImputerBase

__all__ = ["PPCAImputer", "SoftImputer", "RobustPCAImputer", "SOFT_IMPUTE_DEFAULT_FRACTION"]

#: SoftImputer's default lam, as a fraction of the largest singular value of the centred mean-filled
#: matrix (the middle of the hold-out grid :data:`nldr._baselines.peers.SOFT_IMPUTE_FRACTIONS`)
SOFT_IMPUTE_DEFAULT_FRACTION = 0.03
#: iteratively reweighted least-squares sweeps of RobustPCAImputer.transform (least absolute deviations)
_IRLS_SWEEPS = 50


def _row_space(L: np.ndarray, residual: np.ndarray, rank: int) -> tuple[np.ndarray, float]:
    """The fitted rows' linear model for new rows: the basis B = V_r diag(s_r) / sqrt(n) of the row
    space of L (n, d), so that a row's coefficients have unit variance, and the noise variance, from
    the median squared residual on the observed entries (the chi-squared(1) median is 0.455, so a
    gross error among them does not set it)."""
    _, sv, Vt = np.linalg.svd(L, full_matrices=False)
    basis = Vt[:rank].T * (sv[:rank] / np.sqrt(L.shape[0]))[None, :]
    noise = float(np.median(residual**2)) / 0.455 if residual.size else 0.0
    return basis, max(noise, 1e-12 * float(np.mean(sv[:rank] ** 2) / L.shape[0]) if rank else 1e-12)


def _fit_on_basis(W, mask, centre, basis, noise, *, robust: bool, denoise: bool = False) -> np.ndarray:
    """Rows (m, d) completed on centre + span(basis (d, r)). A row's coefficients a are the
    posterior mean under a ~ N(0, I) and Gaussian noise of variance ``noise`` on its observed
    entries, (B_o^T B_o + noise I)^-1 B_o^T (w_o - centre_o); with ``robust`` the data term is
    reweighted to least absolute deviations, so a gross error among the observed entries does not
    drag the fit. Observed entries are kept; with ``denoise`` every entry is the fit's,
    centre + B a."""
    out = np.where(mask, W, centre)
    if denoise:
        out = np.broadcast_to(centre, W.shape).copy()
    r = basis.shape[1]
    if r == 0:
        return out
    for i in range(W.shape[0]):
        o = mask[i]
        if not o.any() or (o.all() and not denoise):
            continue
        A, b = basis[o], W[i, o] - centre[o]
        weights = np.ones(b.size)
        for _ in range(_IRLS_SWEEPS if robust else 1):
            Aw = A * weights[:, None]
            coef = np.linalg.solve(A.T @ Aw + noise * np.eye(r), Aw.T @ b)
            scale = np.sqrt(noise)
            weights = scale / np.maximum(np.abs(b - A @ coef), scale)  # Huber-like IRLS towards l1
        fitted = ~o if not denoise else slice(None)
        out[i, fitted] = centre[fitted] + basis[fitted] @ coef
    return out


class PPCAImputer(MaskedImputerBase):
    """Probabilistic PCA with missing values, fitted by exact EM (the "PPCA" of the paper's Table 2).

    ``fit`` runs :func:`nldr._baselines.ppca_impute` (from the complete-data solution on the
    mean-imputed matrix); missing entries are their posterior means E[x_m | x_o]. ``transform`` gives
    new rows the same posterior means under the fitted model (mean, loadings, noise variance).

    Parameters
    ----------
    missing_values : np.nan or float, default np.nan
    standardize : bool, default True
        Solve on the columns standardised by their observed entries' mean and standard deviation (a
        constant column is only centred) and return the estimate in the data's units, so that the
        completion is unit-free per column; the parameters in units of X are then in standardised
        units. False solves on X as given (the paper's Table 2 setting: PPCA's isotropic noise is in
        X's units).
    n_components : int or None, default None
        Latent dimension q, 1 <= q < n_features; None: min(10, n_features - 1) (on oil flow's 12
        columns q = 9-11 compare alike: docs/REPRODUCTION.md#table-2-baselines).
    max_iter : int >= 1, default 5000
        EM iterations at most.
    tol : float >= 0, default 1e-7
        EM stops when the log-likelihood changes by less than tol per observed entry (nats).
    accelerate : bool, default True
        Over-relaxed EM (the same fixed point, fewer iterations).

    Attributes
    ----------
    n_components_ : int
    mean_ : array, shape (n_features,)
    components_ : array, shape (n_features, n_components_), the loading matrix
    noise_variance_ : float
    shift_, scale_ : arrays, shape (n_features,)
        The standardisation (zeros and ones when ``standardize`` is False): the other fitted
        attributes and ``result_`` are in the solved units, ``(X - shift_) / scale_``.
    result_ : nldr._baselines.PPCAResult
    completed_ : array, shape (n_samples, n_features)
    n_features_in_ : int

    See Also
    --------
    PKPCAImputer : The same model in the feature space of an RBF kernel.
    SoftImputer : Nuclear-norm completion, another linear low-rank model.

    Notes
    -----
    Tipping & Bishop's model x = W z + mu + noise, z ~ N(0, I), fitted by EM on the observed entries
    (over-relaxed by default); the estimate of a missing entry is its posterior mean.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[1.0, 2.0, 3.0], [2.0, np.nan, 5.9], [3.0, 6.1, 9.0],
    ...               [4.0, 7.9, np.nan], [5.0, 9.9, 15.1], [6.0, 12.0, 18.0]])
    >>> from nldr.impute import PPCAImputer
    >>> X_hat = PPCAImputer(n_components=1).fit_transform(X)
    >>> np.round(X_hat[[1, 3], [1, 2]])  # the missing entries, near 4 and 12
    array([ 4., 12.])
    >>> observed = ~np.isnan(X)
    >>> bool(np.array_equal(X_hat[observed], X[observed]))
    True
    """

    _min_samples = 2
    _min_features = 2
    _standardizes = True

    _parameter_constraints: dict = {
        **MaskedImputerBase._parameter_constraints,
        "standardize": ["boolean"],
        "n_components": [Interval(Integral, 1, None, closed="left"), None],
        "max_iter": [Interval(Integral, 1, None, closed="left")],
        "tol": [Interval(Real, 0, np.inf, closed="left")],
        "accelerate": ["boolean"],
    }

    def __init__(
        self, missing_values=np.nan, *, standardize=True, n_components=None, max_iter=5000, tol=1e-7,
        accelerate=True,
    ):
        self.missing_values = missing_values
        self.standardize = standardize
        self.n_components = n_components
        self.max_iter = max_iter
        self.tol = tol
        self.accelerate = accelerate

    def _mean_fill_cause(self) -> str:
        return "the data's units with standardize=False (tol is per observed entry): rescale X or standardize"

    def _solve(self, W, mask):
        q = min(10, W.shape[1] - 1) if self.n_components is None else self.n_components
        solver = {"max_iter": self.max_iter, "tol": self.tol, "accelerate": self.accelerate}
        result = ppca_impute(np.where(mask, W, np.nan), mask, q, **solver)
        self.n_components_ = int(q)
        self.mean_, self.components_ = result.mean, result.components
        self.noise_variance_ = float(result.noise_variance)
        return result.x, result

    def _complete(self, W, mask):
        return self.result_.posterior_mean(W, mask)


class SoftImputer(MaskedImputerBase):
    """Nuclear-norm matrix completion, SoftImpute (Mazumder, Hastie & Tibshirani 2010).

    ``fit`` runs :func:`nldr._baselines.soft_impute`: min 1/2 ||P_O(Z - X_c)||_F^2 + lam ||Z||_* with
    X_c the columns centred on their observed means (``center``); missing entries come from Z.
    ``transform`` fits each new row's observed entries on the row space of the fitted Z (plus the
    means; coefficients by their posterior mean with the fitted rows as the prior and the residual
    variance as noise) and fills the missing ones from that fit.

    Parameters
    ----------
    missing_values : np.nan or float, default np.nan
    standardize : bool, default True
        Solve on the columns standardised by their observed entries' mean and standard deviation (a
        constant column is only centred) and return the estimate in the data's units, so that the
        completion is unit-free per column; the parameters in units of X are then in standardised
        units. False solves on X as given.
    lam : float >= 0 or None, default None
        Weight of the nuclear norm, in the units of X. None: :data:`SOFT_IMPUTE_DEFAULT_FRACTION`
        times the largest singular value of the (centred) mean-imputed X, above which Z = 0.
    center : bool, default True
        Complete the columns centred on their observed means, and add the means back.
    tol : float > 0, default 1e-7
        Stop when ||Z_{k+1} - Z_k||_F^2 <= tol ||Z_k||_F^2 (dimensionless).
    max_iter : int >= 1, default 5000
        Iterations at most.

    Attributes
    ----------
    lam_ : float
    rank_ : int, rank of the fitted Z
    column_means_ : array, shape (n_features,)
    basis_ : array, shape (n_features, rank_), Z's row space scaled by its singular values / sqrt(n)
    noise_variance_ : float, of the observed entries about the fit (robust estimate)
    shift_, scale_ : arrays, shape (n_features,)
        The standardisation (zeros and ones when ``standardize`` is False): the other fitted
        attributes and ``result_`` are in the solved units, ``(X - shift_) / scale_``.
    result_ : nldr._baselines.SoftImputeResult
    completed_ : array, shape (n_samples, n_features)
    n_features_in_ : int

    See Also
    --------
    PPCAImputer : A probabilistic linear low-rank model.
    RobustPCAImputer : Linear low rank with gross errors among the observed entries.

    Notes
    -----
    The iteration fills the missing entries from the current Z and soft-thresholds the singular
    values by ``lam`` (singular value thresholding); the rank follows from lam.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[1.0, 2.0, 3.0], [2.0, np.nan, 5.9], [3.0, 6.1, 9.0],
    ...               [4.0, 7.9, np.nan], [5.0, 9.9, 15.1], [6.0, 12.0, 18.0]])
    >>> from nldr.impute import SoftImputer
    >>> imputer = SoftImputer().fit(X)
    >>> X_hat = imputer.transform(X)
    >>> X_hat.shape, bool(np.isnan(X_hat).any()), imputer.rank_ >= 1
    ((6, 3), False, True)
    """

    _standardizes = True

    _parameter_constraints: dict = {
        **MaskedImputerBase._parameter_constraints,
        "standardize": ["boolean"],
        "lam": [Interval(Real, 0, np.inf, closed="left"), None],
        "center": ["boolean"],
        "tol": [Interval(Real, 0, np.inf, closed="neither")],
        "max_iter": [Interval(Integral, 1, None, closed="left")],
    }

    def __init__(
        self, missing_values=np.nan, *, standardize=True, lam=None, center=True, tol=1e-7, max_iter=5000
    ):
        self.missing_values = missing_values
        self.standardize = standardize
        self.lam = lam
        self.center = center
        self.tol = tol
        self.max_iter = max_iter

    def _mean_fill_cause(self) -> str:
        return (
            "lam at or above the largest singular value of the centred matrix (Z = 0): lower lam, or "
            "leave it None; with standardize=False, lam is in the units of X"
        )

    def _solve(self, W, mask):
        lam = self.lam
        if lam is None:
            filled = mean_fill(W, mask)
            if self.center:
                filled = filled - filled.mean(axis=0)
            lam = SOFT_IMPUTE_DEFAULT_FRACTION * float(np.linalg.svd(filled, compute_uv=False)[0])
        result = soft_impute(
            np.where(mask, W, np.nan), mask, lam=lam, center=self.center, tol=self.tol, max_iter=self.max_iter
        )
        self.lam_ = float(lam)
        self.rank_ = int(result.rank)
        self.column_means_ = result.column_means
        residual = (result.Z + self.column_means_ - W)[mask]
        self.basis_, self.noise_variance_ = _row_space(result.Z, residual, self.rank_)
        return result.x, result

    def _complete(self, W, mask):
        return _fit_on_basis(W, mask, self.column_means_, self.basis_, self.noise_variance_, robust=False)


class RobustPCAImputer(MaskedImputerBase):
    """Linear Robust PCA by principal component pursuit, with missing entries (Candes et al. 2011).

    ``fit`` runs :func:`nldr._baselines.rpca.rpca_impute`: min ||L||_* + lam ||S||_1 with L + S = X on
    the observed entries, ``lam = lam_factor / sqrt(max(n, d) * share observed)``; the missing
    entries of a training row are its low-rank L (plus the column medians). ``transform`` fits each
    new row's observed entries on the row space of L (as :class:`SoftImputer`, the data term
    reweighted towards least absolute deviations, robust to a gross error among them) and fills the
    missing ones from that fit. Both keep the observed entries, as an imputer does; with
    ``denoise=True`` both return the low-rank estimate of every entry instead (training rows: L plus
    the medians; new rows: their fit on L's row space), so observed entries with gross errors are
    corrected too.

    Parameters
    ----------
    missing_values : np.nan or float, default np.nan
    standardize : bool, default True
        Solve on the columns standardised by their observed entries' mean and standard deviation (a
        constant column is only centred) and return the estimate in the data's units, so that the
        completion is unit-free per column; the parameters in units of X are then in standardised
        units. False solves on X as given.
    lam_factor : float > 0, default 1.0
        Multiple of Candes et al.'s weight of the l1 norm (dimensionless).
    center : bool, default True
        Subtract the observed column medians first and add them back.
    mu : float > 0 or None, default None
        The ADMM penalty of :func:`~nldr._baselines.rpca.rpca_pcp`, in 1 / units of X; None:
        n d / (4 sum |X_c|) on the observed entries.
    tol : float > 0, default 1e-7
        ADMM stops when the primal and dual residuals are both <= tol ||X_c||_F on the observed
        entries (dimensionless).
    max_iter : int >= 1, default 10000
        ADMM iterations at most.
    denoise : bool, default False
        Return the low-rank estimate of the observed entries too (a denoiser), from ``fit_transform``
        and ``transform`` alike; False keeps them (an imputer).

    Attributes
    ----------
    rank_ : int, rank of L
    column_centre_ : array, shape (n_features,)
    basis_ : array, shape (n_features, rank_), L's row space scaled by its singular values / sqrt(n)
    noise_variance_ : float, of the observed entries about L (robust estimate)
    shift_, scale_ : arrays, shape (n_features,)
        The standardisation (zeros and ones when ``standardize`` is False): the other fitted
        attributes and ``result_`` are in the solved units, ``(X - shift_) / scale_``.
    result_ : nldr._baselines.rpca.RPCAResult
    completed_ : array, shape (n_samples, n_features)
    n_features_in_ : int

    See Also
    --------
    SoftImputer : Nuclear-norm completion without the sparse error term.
    KernelRegularizerImputer : With ``loss="huber"``, the non-linear method robust to gross errors.

    Notes
    -----
    Principal component pursuit splits the observed entries into a low-rank L and a sparse S of gross
    errors, solved by ADMM (:func:`nldr._baselines.rpca.rpca_pcp`).

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[1.0, 2.0, 3.0], [2.0, np.nan, 5.9], [3.0, 6.1, 9.0],
    ...               [4.0, 7.9, np.nan], [5.0, 9.9, 15.1], [6.0, 12.0, 18.0]])
    >>> from nldr.impute import RobustPCAImputer
    >>> X_hat = RobustPCAImputer().fit_transform(X)
    >>> X_hat.shape, bool(np.isnan(X_hat).any())
    ((6, 3), False)
    >>> observed = ~np.isnan(X)
    >>> bool(np.array_equal(X_hat[observed], X[observed]))  # an imputer keeps them
    True
    >>> L = RobustPCAImputer(denoise=True).fit_transform(X)  # the low-rank estimate of every entry
    >>> bool(np.array_equal(L[observed], X[observed]))
    False
    """

    _standardizes = True

    _parameter_constraints: dict = {
        **MaskedImputerBase._parameter_constraints,
        "standardize": ["boolean"],
        "lam_factor": [Interval(Real, 0, np.inf, closed="neither")],
        "center": ["boolean"],
        "mu": [Interval(Real, 0, np.inf, closed="neither"), None],
        "tol": [Interval(Real, 0, np.inf, closed="neither")],
        "max_iter": [Interval(Integral, 1, None, closed="left")],
        "denoise": ["boolean"],
    }

    def __init__(
        self,
        missing_values=np.nan,
        *,
        standardize=True,
        lam_factor=1.0,
        center=True,
        mu=None,
        tol=1e-7,
        max_iter=10000,
        denoise=False,
    ):
        self.missing_values = missing_values
        self.standardize = standardize
        self.lam_factor = lam_factor
        self.center = center
        self.mu = mu
        self.tol = tol
        self.max_iter = max_iter
        self.denoise = denoise

    def _solve(self, W, mask):
        solver = {"mu": self.mu, "tol": self.tol, "max_iter": self.max_iter}
        result = rpca_impute(
            np.where(mask, W, np.nan), mask, lam_factor=self.lam_factor, center=self.center, **solver
        )
        self.rank_ = int(result.rank)
        self.column_centre_ = result.column_centre
        residual = (result.x - W)[mask]
        self.basis_, self.noise_variance_ = _row_space(result.L, residual, self.rank_)
        return result.x, result

    def _complete(self, W, mask):
        return _fit_on_basis(
            W, mask, self.column_centre_, self.basis_, self.noise_variance_, robust=True, denoise=self.denoise
        )
