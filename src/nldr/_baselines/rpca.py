"""Linear Robust PCA: principal component pursuit (PCP) by ADMM, with missing entries (not in the paper).

Problem (Candes, Li, Ma & Wright 2011; with missing entries as in their section 1.6). For data W
(n, d) observed on the set O (``mask``),

    minimise ||L||_* + lam sum_{(i,j) in O} |S_ij|   subject to  L_ij + S_ij = W_ij for (i,j) in O.   (1)

L is the low-rank part (it is also the completion of the missing entries), S the sparse gross errors.
The default ``lam = 1 / sqrt(max(n, d) * share observed)`` is theirs; :func:`rpca_impute` takes it as
a multiple (``lam_factor``) so that hold-out CV can scale it.

ADMM. Let W~ be W on O and 0 elsewhere and let S be free (unpenalised) off O, so that the constraint
reads L + S = W~ on every entry. With multiplier Y and penalty mu, one sweep is

    L <- SVT_{1/mu}(W~ - S + Y/mu)          (singular value thresholding, the prox of ||.||_*)
    T <- W~ - L + Y/mu;  S <- shrink_{lam/mu}(T) on O,  S <- T off O
    Y <- Y + mu (W~ - L - S),

two-block ADMM on a convex problem, so it converges for any fixed mu > 0 (Boyd et al. 2011, 3.2).
After a sweep Y is *exactly* in lam d||P_O S||_1 (|Y_ij| <= lam on O, = lam sign(S_ij) where S_ij != 0,
and Y = 0 off O), and ``Y + mu (S_new - S_old)`` is exactly in d||L||_*; so the dual residual
``mu ||S_new - S_old||_F`` and the primal residual ``||W~ - L - S||_F`` measure the distance to the
optimality conditions. The loop stops when both are below ``tol * ||W~||_F``.

Certificate. Every Y with ``||Y||_2 <= 1``, ``|Y_ij| <= lam`` on O and Y = 0 off O gives the lower bound
``<Y, W~>`` on the optimum of (1) (Lagrangian duality), and (L, W - L on O) is feasible; so the result's
``gap = objective(L) - <Y_hat, W~>``, with Y_hat = Y scaled into that set, bounds the suboptimality of
its ``fun`` (tests/test_rpca.py checks cvxpy's optimum lies in that bracket).

Centring. By default (``center=True``) the observed column medians are subtracted first and added
back (the nuclear norm would otherwise shrink the column levels; medians because means are not robust
to the very outliers PCP removes); (1) and its certificate then hold for the centred matrix.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .._spectral import shrink_singular_values
from .._validation import check_count, check_positive
from ..result import SolverResult, status_from
from ._masked import check_masked_matrix

__all__ = ["RPCAResult", "rpca_pcp", "rpca_impute", "pcp_objective", "default_pcp_lambda"]


@dataclass(kw_only=True, repr=False)
class RPCAResult(SolverResult):
    """Outcome of :func:`rpca_pcp`.

    Attributes
    ----------
    x : array, shape (n, d)
        The low-rank estimate L plus the column centre: the denoised and completed matrix (units of W).
    fun : float
        Objective (1) at (L, W - L on O), centred units.
    L, S : arrays, shape (n, d)
        Low-rank and sparse parts of the centred matrix (S is 0 off the mask).
    Y : array, shape (n, d)
        The multiplier (0 off the mask).
    rank : int
        Rank of L.
    lam, mu : float
        The l1 weight and the ADMM penalty used.
    gap : float >= 0
        ``fun`` minus the dual bound of the scaled multiplier: ``fun - gap`` <= optimum <= ``fun``.
    primal_residual, dual_residual : float
        ``||P_O(W - L - S)||_F`` and ``mu ||S_k - S_(k-1)||_F`` at the last sweep.
    column_centre : array, shape (d,)
        The medians subtracted (zeros when not centred).
    """

    L: np.ndarray
    S: np.ndarray
    Y: np.ndarray
    rank: int
    lam: float
    mu: float
    gap: float
    primal_residual: float
    dual_residual: float
    column_centre: np.ndarray


def default_pcp_lambda(mask) -> float:
    """Candes et al.'s weight ``1 / sqrt(max(n, d) * share of observed entries)`` for a mask (n, d)."""
    mask = np.asarray(mask, dtype=bool)
    return 1.0 / np.sqrt(max(mask.shape) * mask.mean())


def pcp_objective(L, W, mask, lam: float) -> float:
    """``||L||_* + lam sum_O |W - L|`` (the objective of (1) at its feasible point with this L)."""
    R = np.where(mask, np.asarray(W) - L, 0.0)
    return float(np.linalg.svd(L, compute_uv=False).sum() + lam * np.abs(R).sum())


def _observed_medians(W: np.ndarray, mask: np.ndarray) -> np.ndarray:
    return np.array([np.median(W[mask[:, j], j]) for j in range(W.shape[1])])


def rpca_pcp(
    W,
    mask=None,
    *,
    lam: float | None = None,
    mu: float | None = None,
    center: bool = True,
    tol: float = 1e-7,
    max_iter: int = 10000,
) -> RPCAResult:
    """Principal component pursuit (1) by ADMM (module docstring), with missing entries.

    Parameters
    ----------
    W : array, shape (n, d)
        Data, samples as rows; entries where ``mask`` is False are ignored (they may be NaN).
    mask : bool array, shape (n, d), optional
        True where W is observed; default all observed. Every column needs an observed entry.
    lam : float > 0, optional
        Weight of the l1 norm (dimensionless: L and S have the same units); default
        :func:`default_pcp_lambda`.
    mu : float > 0, optional
        ADMM penalty (1 / units of W); default ``n d / (4 sum_O |W~|)`` (Candes et al.).
    center : bool, default True
        Subtract the observed column medians first and add them back.
    tol : float > 0, default 1e-7
        Stop when the primal and dual residuals are both <= tol ||W~||_F.
    max_iter : int >= 1, default 10000

    Returns
    -------
    RPCAResult
        ``x`` the completed low-rank estimate; an iteration limit is reported in ``status``.

    Raises
    ------
    ValueError
        Bad shapes or mask, non-finite observed entries, an unobserved column, or a non-positive
        ``lam``, ``mu``, ``tol`` (the message names it).
    """
    start = time.perf_counter()
    if mask is None:
        mask = np.isfinite(np.asarray(W, dtype=np.float64))
    W, mask = check_masked_matrix(W, mask)
    lam = default_pcp_lambda(mask) if lam is None else check_positive(lam, "lam")
    tol, max_iter = check_positive(tol, "tol"), check_count(max_iter, "max_iter")
    centre = _observed_medians(W, mask) if center else np.zeros(W.shape[1])
    Wt = np.where(mask, W - centre, 0.0)
    scale = float(np.linalg.norm(Wt))
    if scale == 0.0:
        scale = 1.0
    if mu is None:
        total = float(np.abs(Wt).sum())
        mu = W.size / (4.0 * total) if total > 0 else 1.0
    mu = check_positive(mu, "mu")
    L, S, Y = np.zeros_like(Wt), np.zeros_like(Wt), np.zeros_like(Wt)
    converged, nit, primal, dual, rank = False, 0, np.inf, np.inf, 0
    while nit < max_iter:
        nit += 1
        L, kept = shrink_singular_values(Wt - S + Y / mu, 1.0 / mu)
        rank = kept.size
        T = Wt - L + Y / mu
        S_new = np.where(mask, np.sign(T) * np.maximum(np.abs(T) - lam / mu, 0.0), T)
        dual = mu * float(np.linalg.norm(S_new - S))
        S = S_new
        R = Wt - L - S
        Y = Y + mu * R
        primal = float(np.linalg.norm(R))
        if primal <= tol * scale and dual <= tol * scale:
            converged = True
            break
    fun = pcp_objective(L, Wt, mask, lam)
    Y = np.where(mask, Y, 0.0)
    spectral = float(np.linalg.norm(Y, 2))
    bound = float(np.sum(Y * Wt)) / max(1.0, spectral, float(np.abs(Y).max()) / lam)
    message = (
        f"primal and dual residuals below tol={tol:g} after {nit} sweeps (rank {rank})"
        if converged
        else f"max_iter={max_iter} sweeps ran; residuals {primal:.3g}, {dual:.3g} (rank {rank})"
    )
    return RPCAResult(
        x=L + centre,
        fun=fun,
        status=status_from(converged),
        message=message,
        nit=nit,
        wall_time=time.perf_counter() - start,
        L=L,
        S=np.where(mask, S, 0.0),
        Y=Y,
        rank=rank,
        lam=lam,
        mu=mu,
        gap=max(fun - bound, 0.0),
        primal_residual=primal,
        dual_residual=dual,
        column_centre=centre,
    )


def rpca_impute(W, mask, *, lam_factor: float = 1.0, **options) -> RPCAResult:
    """:func:`rpca_pcp` with ``lam = lam_factor * default_pcp_lambda(mask)``: the baselines' signature
    ``impute(W, mask, **params)``; :class:`nldr.impute.RobustPCAImputer` is its estimator form.

    Parameters
    ----------
    W, mask : as in :func:`rpca_pcp` (mask required).
    lam_factor : float > 0, default 1
        Multiple of Candes et al.'s weight.
    **options
        ``mu, center, tol, max_iter`` of :func:`rpca_pcp`.
    """
    lam_factor = check_positive(lam_factor, "lam_factor")
    W, mask = check_masked_matrix(W, mask)
    return rpca_pcp(W, mask, lam=lam_factor * default_pcp_lambda(mask), **options)
