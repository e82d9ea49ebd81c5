"""The Bayesian GP-LVM with missing data as an imputer: :class:`GPLVMImputer` (needs GPy).

The Gaussian-process latent variable model (Lawrence 2005) explains each row x_i of X as a smooth
function of a low-dimensional latent point t_i, x_ij = f_j(t_i) + noise, with f_j ~ GP(0, k) under an
ARD RBF kernel k. The Bayesian variant (Titsias & Lawrence 2010) puts a Gaussian prior on the latent
points and integrates them out variationally with M inducing points; with ``missing_data=True`` each
column's likelihood uses only its observed entries. Oil flow is this model's classic data set.

This module wraps GPy's ``BayesianGPLVMMiniBatch`` (GPy is optional: ``pip install nldr[peers]``).
"""

from __future__ import annotations

import contextlib
import io
import logging
import warnings
from numbers import Integral

import numpy as np
from sklearn.utils._param_validation import Interval

from .._baselines._masked import observed_standardisation
from ._base import MaskedImputerBase

__all__ = ["GPLVMImputer", "GPY_MISSING"]

#: the message of the ImportError raised when GPy is not installed
GPY_MISSING = "GPLVMImputer needs GPy, which is not installed: pip install 'nldr[peers]' (or pip install GPy)"


def _gpy():
    try:
        with _quiet():
            import GPy
    except ImportError as exc:
        raise ImportError(GPY_MISSING) from exc
    return GPy


@contextlib.contextmanager
def _quiet():
    """GPy's prints, warnings and log lines silenced (its optimiser and paramz talk on stdout)."""
    loggers = [logging.getLogger(name) for name in ("GPy", "paramz")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            with np.errstate(all="ignore"):
                yield
    finally:
        for lg, level in zip(loggers, levels, strict=True):
            lg.setLevel(level)


@contextlib.contextmanager
def _seeded(seed: int):
    """numpy's global generator (which GPy draws its initial latent variances and inducing points
    from) seeded for the block and restored after it."""
    state = np.random.get_state()  # noqa: NPY002 (GPy draws from the legacy global generator)
    np.random.seed(seed)  # noqa: NPY002
    try:
        yield
    finally:
        np.random.set_state(state)  # noqa: NPY002


class GPLVMImputer(MaskedImputerBase):
    """Missing entries predicted by a Bayesian GP-LVM fitted to the observed entries (GPy).

    ``fit`` standardises each column by its observed entries' mean and sd, builds
    ``GPy.models.bayesian_gplvm_minibatch.BayesianGPLVMMiniBatch(Y, n_latent,
    num_inducing=n_inducing, missing_data=True)`` (latent means initialised by PCA of the mean-filled
    matrix, GPy's default ARD RBF kernel and Gaussian noise), runs ``max_iter`` iterations of L-BFGS-B
    on the variational bound, and predicts every missing entry as the GP's posterior mean at its row's
    latent mean. Observed entries are returned as given. ``transform`` on new rows infers each new
    row's latent point as the training row's latent mean whose prediction best fits (least squares) the
    new row's observed entries, and predicts its missing entries there (GPy's own ``infer_newX`` fails on
    this model with missing data).

    Parameters
    ----------
    missing_values : np.nan or float, default np.nan
    n_latent : int >= 1, default 5
        Latent dimension Q (below n_features is the useful range; ARD switches off extra dimensions).
    n_inducing : int >= 1, default 30
        Inducing points M (at most n_samples are used).
    max_iter : int >= 1, default 300
        Optimiser iterations.
    random_state : int >= 0, default 0
        Seeds GPy's random initial latent variances and inducing points (numpy's global generator is
        restored afterwards).

    Attributes
    ----------
    model_ : the fitted GPy model
    mean_, scale_ : arrays, shape (n_features,), the columns' observed means and sds
    completed_ : array, shape (n_samples, n_features)
    n_features_in_ : int
    result_ : None

    See Also
    --------
    KernelRegularizerImputer : The paper's method, a non-linear manifold without a latent space.
    PPCAImputer : The linear model the GP-LVM generalises.

    Notes
    -----
    Needs GPy (``pip install 'nldr[peers]'``); without it ``fit`` raises an ImportError that says so.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[1.0, 2.0, 3.0], [2.0, np.nan, 5.9], [3.0, 6.1, 9.0],
    ...               [4.0, 7.9, np.nan], [5.0, 9.9, 15.1], [6.0, 12.0, 18.0]])
    >>> from nldr.impute._gplvm import GPLVMImputer
    >>> imputer = GPLVMImputer(n_latent=1, n_inducing=4, max_iter=20)
    >>> X_hat = imputer.fit_transform(X)
    >>> X_hat.shape, bool(np.isnan(X_hat).any())
    ((6, 3), False)
    >>> observed = ~np.isnan(X)
    >>> bool(np.array_equal(X_hat[observed], X[observed]))
    True
    """

    _min_samples = 3
    _min_features = 2

    def __init__(self, missing_values=np.nan, *, n_latent=5, n_inducing=30, max_iter=300, random_state=0):
        self.missing_values = missing_values
        self.n_latent = n_latent
        self.n_inducing = n_inducing
        self.max_iter = max_iter
        self.random_state = random_state

    _parameter_constraints: dict = {
        **MaskedImputerBase._parameter_constraints,
        "n_latent": [Interval(Integral, 1, None, closed="left")],
        "n_inducing": [Interval(Integral, 1, None, closed="left")],
        "max_iter": [Interval(Integral, 1, None, closed="left")],
        # an int only: numpy's legacy global generator is seeded with it (no RandomState, no None)
        "random_state": [Interval(Integral, 0, 2**32 - 1, closed="both")],
    }

    def _solve(self, W, mask):
        GPy = _gpy()
        self.mean_, self.scale_ = observed_standardisation(W, mask)
        Y = (np.where(mask, W, np.nan) - self.mean_) / self.scale_
        n, d = Y.shape
        q = min(int(self.n_latent), d)
        X0 = _pca_start(np.where(mask, Y, 0.0), q)
        with _quiet(), _seeded(int(self.random_state)):
            model = GPy.models.bayesian_gplvm_minibatch.BayesianGPLVMMiniBatch(
                Y, q, X=X0, num_inducing=min(int(self.n_inducing), n), missing_data=True
            )
            model.optimize(max_iters=int(self.max_iter), messages=False)
            pred = np.asarray(model.predict(np.asarray(model.X.mean))[0])
        self.model_ = model
        X_hat = np.where(mask, W, pred * self.scale_ + self.mean_)
        return X_hat, None

    def _complete(self, W, mask):
        Y = np.where(mask, (W - self.mean_) / self.scale_, 0.0)
        with _quiet():
            latent = np.asarray(self.model_.X.mean)
            fitted = np.asarray(self.model_.predict(latent)[0])  # (n_train, d), standardised
        # each new row: the training latent mean whose prediction best fits the row's observed entries
        err = (mask.astype(float) @ (fitted**2).T) - 2.0 * (Y * mask) @ fitted.T
        best = np.argmin(err, axis=1)
        return np.where(mask, W, fitted[best] * self.scale_ + self.mean_)


def _pca_start(Y0: np.ndarray, q: int) -> np.ndarray:
    """Latent means from PCA of the mean-filled standardised matrix Y0 (n, d): the first q principal
    scores, each scaled to unit variance (GPy's own PCA start does not accept NaN)."""
    Yc = Y0 - Y0.mean(axis=0)
    U, s, _ = np.linalg.svd(Yc, full_matrices=False)
    scores = U[:, :q] * s[:q]
    sd = scores.std(axis=0)
    return scores / np.where(sd > 0, sd, 1.0)
