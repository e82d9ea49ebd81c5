"""SoftImpute, nuclear-norm completion (Mazumder, Hastie & Tibshirani 2010), implemented in numpy: a
peer of the regularizer (not in the paper). Its knob is ``lam``, the weight of the nuclear norm (units
of W). scikit-learn's ``KNNImputer`` and ``IterativeImputer`` (and missForest as an
``IterativeImputer`` of extra trees) are used as they are: :func:`nldr.impute._grids.baseline_grid`
gives them with their hold-out grids.

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
from dataclasses import dataclass

import numpy as np

from .._spectral import shrink_singular_values
from .._validation import check_count, check_positive
from ..result import SolverResult, status_from
from ._masked import check_masked_matrix, observed_column_means

__all__ = [
    "SoftImputeResult",
    "soft_impute",
    "singular_value_threshold",
    "soft_impute_objective",
]


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
        :func:`nldr.impute._grids.baseline_grid` gives a grid relative to the largest singular
        value of the (centred) mean-filled matrix, above which Z = 0.
    center : bool, default True
        Complete ``W - 1 mu^T`` (mu: observed column means) and add mu back (module docstring).
    tol : float > 0, default 1e-7
        Stop when ``||Z_{k+1} - Z_k||_F^2 <= tol ||Z_k||_F^2`` (for Z_k = 0: ``<= tol ||Z_{k+1}||_F^2``,
        i.e. only at ``Z_{k+1} = 0``): dimensionless, the same iterates in any units of W.
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
        # relative to the iterate's size; from Z_k = 0 (the default start) to Z_{k+1}'s, so that the
        # test is unit-free and a step from zero stops only at the fixed point Z_{k+1} = 0
        size = float(np.sum(Z * Z)) or float(np.sum(Z_new * Z_new))
        Z, step = Z_new, float(np.sqrt(change))
        if change <= tol * size:
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
