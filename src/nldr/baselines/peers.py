"""The imputers people already use, as peers of the regularizer (not in the paper; issue 16).

Every function has the baselines' signature ``impute(W, mask, **params)`` and the same input check
(:func:`nldr.baselines._masked.check_masked_matrix`), so :func:`nldr.model_selection.select_imputer`
can choose its knob on the same hold-out folds as everything else.

- :func:`knn_impute`: scikit-learn's ``KNNImputer`` (k nearest rows under the NaN-aware Euclidean
  distance, their mean or inverse-distance-weighted mean). Knobs: ``n_neighbors``, ``weights``.
- :func:`iterative_impute`: scikit-learn's ``IterativeImputer`` with ``BayesianRidge`` (chained
  equations: each column regressed on the others in turn, from the column means). Its ridge penalty is
  learnt by evidence maximisation, so it has no knob here; the fixed setting is scikit-learn's
  ``max_iter=10``, ``tol=1e-3``, ascending imputation order (25 sweeps change the oil-flow SSE by < 1 %).
- :func:`missforest_impute`: the missForest recipe (Stekhoven & Buehlmann 2012) as scikit-learn
  writes it, ``IterativeImputer`` with an ``ExtraTreesRegressor`` per column. Knob: ``max_features``
  (share of the other columns tried at each split); ``n_estimators`` defaults to a small 10 so it stays
  affordable. Seeded by ``random_state``.
- :func:`soft_impute`: nuclear-norm completion, SoftImpute (Mazumder, Hastie & Tibshirani 2010),
  implemented here in numpy. Knob: ``lam``, the weight of the nuclear norm (units of W).

SoftImpute. It minimises ``f(Z) = 1/2 ||P_O(Z - W)||_F^2 + lam ||Z||_*`` over Z (n, d), where P_O keeps
the observed entries. The iteration ``Z <- S_lam(P_O(W) + P_O^perp(Z))``, with ``S_lam`` the singular
value thresholding ``U diag(max(s - lam, 0)) V^T``, is proximal gradient with step 1 (the data term's
gradient is 1-Lipschitz), so f never increases and Z converges to a minimiser. With ``Y_k = Z_k +
P_O(W - Z_k)`` and ``Z_{k+1} = S_lam(Y_k)``, ``Y_k - Z_{k+1}`` is in ``lam * d||Z_{k+1}||_*`` exactly, so

    G = P_O(W - Z_{k+1})  is within  ||P_O^perp(Z_{k+1} - Z_k)||_F <= ||Z_{k+1} - Z_k||_F  of a subgradient,

i.e. the optimality condition ``P_O(W - Z) in lam (U V^T + N)``, ``U^T N = 0, N V = 0, ||N||_2 <= 1``,
holds up to the last step's size, which the result reports as ``step`` (and the tests check). The
iteration stops when ``||Z_{k+1} - Z_k||_F^2 <= tol * ||Z_k||_F^2`` (Mazumder et al.'s rule).

By default (``center=True``) SoftImpute completes ``W - 1 mu^T``, mu the observed column means, and
adds mu back: otherwise the nuclear norm also shrinks the column means, which a low-rank model of the
deviations has no reason to do. The optimality statement above then holds for the centred matrix.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np
from sklearn.ensemble import ExtraTreesRegressor
from sklearn.exceptions import ConvergenceWarning

# IterativeImputer is still "experimental" in scikit-learn (1.6-1.9): it is importable only after this
# import, which registers it in sklearn.impute. The import has that side effect only.
from sklearn.experimental import enable_iterative_imputer  # noqa: F401
from sklearn.impute import IterativeImputer, KNNImputer
from sklearn.linear_model import BayesianRidge

from .._spectral import shrink_singular_values
from .._validation import check_count, check_positive
from ..result import SolverResult, status_from
from ._masked import check_masked_matrix, observed_column_means

__all__ = [
    "KNN_WEIGHTS",
    "SOFT_IMPUTE_FRACTIONS",
    "knn_impute",
    "iterative_impute",
    "missforest_impute",
    "SoftImputeResult",
    "soft_impute",
    "singular_value_threshold",
    "soft_impute_objective",
]

#: ``weights`` of :func:`knn_impute` (scikit-learn's KNNImputer).
KNN_WEIGHTS = ("uniform", "distance")
#: SoftImpute's lam grid in :func:`nldr.model_selection.baseline_grid`, as fractions of the largest singular
#: value of the centred mean-filled matrix (the lam at which Z = 0): two and a half decades below it.
SOFT_IMPUTE_FRACTIONS = (0.003, 0.01, 0.03, 0.1, 0.3)


def _nan_matrix(W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """W with NaN at the missing entries: what scikit-learn's imputers take."""
    return np.where(mask, W, np.nan)


def _keep_observed(X_hat: np.ndarray, W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The imputer's output, with the observed entries exactly those of W (shape (n, d))."""
    if X_hat.shape != W.shape:  # scikit-learn drops all-missing columns; check_masked_matrix forbids them
        raise RuntimeError(f"imputer returned shape {X_hat.shape}, expected {W.shape}")
    return np.where(mask, W, X_hat)


# --------------------------------------------------------------------------------------------------
# scikit-learn's imputers
# --------------------------------------------------------------------------------------------------


def knn_impute(W, mask, *, n_neighbors: int = 5, weights: str = "uniform") -> np.ndarray:
    """Fill each missing entry from the row's nearest rows (scikit-learn's ``KNNImputer``).

    Parameters
    ----------
    W : array, shape (n, d)
        Data, samples as rows; entries where ``mask`` is False are ignored (they may be NaN).
    mask : array of bool, shape (n, d)
        True where ``W`` is observed. Every column needs an observed entry.
    n_neighbors : int >= 1, default 5
        Rows averaged per missing entry: the nearest rows that observe that column, under scikit-learn's
        ``nan_euclidean`` distance (Euclidean on the columns both rows observe, rescaled to all d).
    weights : {"uniform", "distance"}, default "uniform"
        Plain mean of the neighbours, or weighted by inverse distance.

    Returns
    -------
    X : array, shape (n, d)
        ``W`` at the observed entries, the neighbours' (weighted) mean elsewhere; scikit-learn falls
        back to the column mean where a row shares no observed column with any candidate.

    Raises
    ------
    ValueError
        Bad shapes or mask, non-finite observed entries, an unobserved column, ``n_neighbors`` not a
        positive integer, or ``weights`` not one of the two.
    """
    W, mask = check_masked_matrix(W, mask)
    n_neighbors = check_count(n_neighbors, "n_neighbors")
    if weights not in KNN_WEIGHTS:
        raise ValueError(f"weights must be one of {KNN_WEIGHTS}; got {weights!r}")
    imputer = KNNImputer(n_neighbors=n_neighbors, weights=weights)
    return _keep_observed(imputer.fit_transform(_nan_matrix(W, mask)), W, mask)


def _chained(W, mask, estimator, *, max_iter, tol, random_state) -> np.ndarray:
    """scikit-learn's IterativeImputer from the column means, every column in ascending order."""
    imputer = IterativeImputer(
        estimator=estimator,
        initial_strategy="mean",
        imputation_order="ascending",
        max_iter=max_iter,
        tol=tol,
        random_state=random_state,
        keep_empty_features=False,
    )
    with warnings.catch_warnings():
        # "[IterativeImputer] Early stopping criterion not reached": the last iterate is still the
        # imputation scikit-learn returns; the tables judge it by its error like every other method.
        warnings.simplefilter("ignore", ConvergenceWarning)
        X_hat = imputer.fit_transform(_nan_matrix(W, mask))
    return _keep_observed(X_hat, W, mask)


def iterative_impute(W, mask, *, max_iter: int = 10, tol: float = 1e-3, random_state: int = 0) -> np.ndarray:
    """Chained-equation imputation with Bayesian ridge regression (scikit-learn's ``IterativeImputer``).

    Starting from the column means, each column with missing entries is regressed (``BayesianRidge``,
    its two precisions learnt from the data) on all the other columns, and its missing entries are
    replaced by the prediction; one sweep over the columns is one iteration.

    Parameters
    ----------
    W : array, shape (n, d); entries where ``mask`` is False are ignored.
    mask : bool array, shape (n, d), True where observed; every column needs an observed entry.
    max_iter : int >= 1, default 10
        Sweeps over the columns at most (scikit-learn's default).
    tol : float > 0, default 1e-3
        scikit-learn's rule: stop when the largest change of an imputed value is below ``tol`` times
        the largest absolute observed value.
    random_state : int, default 0
        Passed to scikit-learn (it only orders ties here; the result is deterministic).

    Returns
    -------
    X : array, shape (n, d)
        ``W`` at the observed entries, the last sweep's predictions elsewhere.
    """
    W, mask = check_masked_matrix(W, mask)
    max_iter = check_count(max_iter, "max_iter")
    tol = check_positive(tol, "tol")
    return _chained(W, mask, BayesianRidge(), max_iter=max_iter, tol=tol, random_state=random_state)


def missforest_impute(
    W,
    mask,
    *,
    max_features: float = 1.0,
    n_estimators: int = 10,
    min_samples_leaf: int = 1,
    max_iter: int = 5,
    tol: float = 1e-3,
    random_state: int = 0,
) -> np.ndarray:
    """missForest: chained-equation imputation with a forest of extremely randomised trees per column.

    The recipe of Stekhoven & Buehlmann (2012) in scikit-learn's form: ``IterativeImputer`` with an
    ``ExtraTreesRegressor`` (as scikit-learn's own missForest example), from the column means.

    Parameters
    ----------
    W : array, shape (n, d); entries where ``mask`` is False are ignored.
    mask : bool array, shape (n, d), True where observed; every column needs an observed entry.
    max_features : float in (0, 1], default 1.0
        Share of the d - 1 predictor columns drawn at each split (1.0: all, scikit-learn's default for
        regression; missForest's sqrt rule is about 0.3 at d = 12).
    n_estimators : int >= 1, default 10
        Trees per column and sweep (missForest uses 100; 10 keeps 200 jobs affordable).
    min_samples_leaf : int >= 1, default 1
    max_iter : int >= 1, default 5
        Sweeps over the columns (random trees never meet scikit-learn's ``tol``, so all of them run;
        missForest's own rule, stop when the imputation first changes more than before, typically
        stops after 4-6, and on oil flow 5 sweeps are as good as 10 at half the cost).
    tol : float > 0, default 1e-3
        As :func:`iterative_impute`.
    random_state : int, default 0
        Seeds the trees: the same seed gives the same imputation.

    Returns
    -------
    X : array, shape (n, d)
        ``W`` at the observed entries, the last sweep's forest predictions elsewhere.
    """
    W, mask = check_masked_matrix(W, mask)
    max_features = check_positive(max_features, "max_features")
    if max_features > 1.0:
        raise ValueError(f"max_features must lie in (0, 1] (a share of the columns); got {max_features}")
    forest = ExtraTreesRegressor(
        n_estimators=check_count(n_estimators, "n_estimators"),
        max_features=max_features,
        min_samples_leaf=check_count(min_samples_leaf, "min_samples_leaf"),
        random_state=random_state,
        n_jobs=1,
    )
    max_iter, tol = check_count(max_iter, "max_iter"), check_positive(tol, "tol")
    return _chained(W, mask, forest, max_iter=max_iter, tol=tol, random_state=random_state)


# --------------------------------------------------------------------------------------------------
# SoftImpute
# --------------------------------------------------------------------------------------------------


@dataclass(kw_only=True, repr=False)
class SoftImputeResult(SolverResult):
    """Outcome of :func:`soft_impute`.

    Attributes
    ----------
    x : array, shape (n, d)
        The completed matrix in the units of W: ``W`` at the observed entries, ``Z`` (plus the column
        means when centred) at the missing ones.
    fun : float
        ``1/2 ||P_O(Z - W_c)||_F^2 + lam ||Z||_*`` at the returned Z (W_c: W centred or not).
    status : int
        :data:`~nldr.result.CONVERGED` when the relative step fell below ``tol``,
        :data:`~nldr.result.MAX_ITER` when ``max_iter`` iterations ran first.
    message : str
    nit : int
        Singular value thresholdings run.
    wall_time : float
    Z : array, shape (n, d)
        The minimiser (of the centred problem when ``center``); ``x`` differs from it (plus the means)
        at the observed entries, which ``x`` takes from W.
    rank : int
        Rank of Z (singular values above ``lam``).
    step : float
        ``||Z_nit - Z_(nit-1)||_F``: the optimality condition holds to this (module docstring).
    column_means : array, shape (d,)
        The means subtracted (zeros when not centred).
    """

    Z: np.ndarray
    rank: int
    step: float
    column_means: np.ndarray


def singular_value_threshold(Y: np.ndarray, lam: float) -> tuple[np.ndarray, int]:
    """``S_lam(Y) = U diag(max(s - lam, 0)) V^T``, the proximal map of ``lam ||.||_*``; returns (Z, rank).

    Parameters
    ----------
    Y : array, shape (n, d)
    lam : float >= 0

    Returns
    -------
    Z : array, shape (n, d)
    rank : int, number of singular values of Y above lam
    """
    Z, kept = shrink_singular_values(Y, lam)
    return Z, kept.size


def soft_impute_objective(Z, W, mask, lam: float) -> float:
    """``1/2 ||P_O(Z - W)||_F^2 + lam ||Z||_*`` for arrays of shape (n, d) (W ignored where not observed)."""
    R = np.where(mask, Z - np.where(mask, W, 0.0), 0.0)
    return 0.5 * float(np.sum(R * R)) + lam * float(np.linalg.svd(Z, compute_uv=False).sum())


def soft_impute(
    W,
    mask,
    *,
    lam: float,
    center: bool = True,
    tol: float = 1e-7,
    max_iter: int = 5000,
    Z0=None,
) -> SoftImputeResult:
    """Nuclear-norm completion by singular value thresholding (SoftImpute, Mazumder et al. 2010).

    Parameters
    ----------
    W : array, shape (n, d)
        Data, samples as rows; entries where ``mask`` is False are ignored (they may be NaN).
    mask : array of bool, shape (n, d)
        True where ``W`` is observed; every column needs an observed entry.
    lam : float >= 0
        Weight of the nuclear norm, in the units of W (a singular value is shrunk by lam).
        :func:`nldr.model_selection.baseline_grid` gives a grid relative to the largest singular
        value of the (centred) mean-filled matrix, above which Z = 0.
    center : bool, default True
        Complete ``W - 1 mu^T`` (mu: observed column means) and add mu back (module docstring).
    tol : float > 0, default 1e-7
        Stop when ``||Z_{k+1} - Z_k||_F^2 <= tol ||Z_k||_F^2`` (for Z_k = 0: ``<= tol``).
    max_iter : int >= 1, default 5000
    Z0 : array, shape (n, d), optional
        Starting point (a warm start along a lam path), in centred units when ``center``; default the
        zero matrix, i.e. the first iterate thresholds the (centred) zero-filled W.

    Returns
    -------
    SoftImputeResult

    Raises
    ------
    ValueError
        Bad shapes or mask, non-finite observed entries, an unobserved column, negative ``lam``, or a
        ``Z0`` of another shape.
    """
    start = time.perf_counter()
    W, mask = check_masked_matrix(W, mask)
    lam = check_positive(lam, "lam", allow_zero=True)
    tol = check_positive(tol, "tol")
    max_iter = check_count(max_iter, "max_iter")
    mu = observed_column_means(W, mask) if center else np.zeros(W.shape[1])
    Wc = np.where(mask, W - mu, 0.0)
    if Z0 is None:
        Z = np.zeros_like(Wc)
    else:
        Z = np.asarray(Z0, dtype=np.float64)
        if Z.shape != Wc.shape or not np.all(np.isfinite(Z)):
            raise ValueError(f"Z0 must be a finite array of W's shape {Wc.shape}; got shape {Z.shape}")
    converged, step, rank, nit = False, np.inf, 0, 0
    while nit < max_iter:
        nit += 1
        Z_new, rank = singular_value_threshold(np.where(mask, Wc, Z), lam)
        change = float(np.sum((Z_new - Z) ** 2))
        size = float(np.sum(Z * Z))
        Z, step = Z_new, float(np.sqrt(change))
        if change <= tol * (size if size > 0 else 1.0):
            converged = True
            break
    X = np.where(mask, W, Z + mu)
    message = (
        f"relative step below tol={tol:g} after {nit} iterations (rank {rank})"
        if converged
        else f"max_iter={max_iter} iterations ran; last step {step:.3g} (rank {rank})"
    )
    return SoftImputeResult(
        x=X,
        fun=soft_impute_objective(Z, Wc, mask, lam),
        status=status_from(converged),
        message=message,
        nit=nit,
        wall_time=time.perf_counter() - start,
        Z=Z,
        rank=rank,
        step=step,
        column_means=mu,
    )
