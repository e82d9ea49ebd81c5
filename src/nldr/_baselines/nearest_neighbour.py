"""1-nearest-neighbour imputation (the "1-NN" row of the paper's Table 2).

Each incomplete row copies its missing entries from the nearest *fully observed* row, the distance
being measured on the incomplete row's observed columns only. With no fully observed row there is
no donor: the paper prints "NA" (p = 0.5 on oil flow, where a row of 12 entries is complete with
probability 0.5^12). We report that as a result with ``success=False`` and ``x=None`` rather than
an exception, so that a sweep over masks records "not available" as data.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..result import CONVERGED, INACCURATE, SolverResult
from ._masked import check_masked_matrix

__all__ = ["NearestNeighbourResult", "nearest_neighbour_impute"]


@dataclass(kw_only=True, repr=False)
class NearestNeighbourResult(SolverResult):
    """Outcome of ``nearest_neighbour_impute``.

    Attributes
    ----------
    x : array, shape (n, d), or None
        The completed matrix in the units of W; None when 1-NN is not available.
    fun : float
        What 1-NN minimises, row by row: the summed squared distance of every row to its donor over
        the row's observed columns (0 for fully observed rows). NaN when not available.
    status : int
        :data:`~nldr.result.CONVERGED` (the method is exact, there is no tolerance), or
        :data:`~nldr.result.INACCURATE` when ``W`` has no fully observed row, so 1-NN is undefined
        (the paper's "NA"); ``success`` is False exactly then.
    message : str
    nit : int
        Always 0 (no iterations).
    wall_time : float
    neighbour : int array, shape (n,), or None
        Index of the donor row of each row (a fully observed row is its own donor); None when not
        available.
    n_complete_rows : int
        Number of fully observed rows (candidate donors).
    """

    neighbour: np.ndarray | None
    n_complete_rows: int


def nearest_neighbour_impute(W, mask) -> NearestNeighbourResult:
    """Fill each row's missing entries from its nearest fully observed row.

    Parameters
    ----------
    W : array, shape (n, d)
        Data, samples as rows; entries where ``mask`` is False are ignored (they may be NaN).
    mask : array of bool, shape (n, d)
        True where ``W`` is observed.

    Returns
    -------
    NearestNeighbourResult
        ``success=False`` (and ``x=None``) when no row of ``W`` is fully observed.

    Notes
    -----
    The distance from row i to a complete row c is ``sum_j mask_ij (W_ij - W_cj)^2`` (squared
    Euclidean on row i's observed columns). Ties, including every distance of a row with no
    observed entry, go to the complete row with the lowest index.

    Raises
    ------
    ValueError
        If the shapes disagree or an observed entry is not finite.
    """
    start = time.perf_counter()
    W, mask = check_masked_matrix(W, mask, require_observed_columns=False)
    complete = np.flatnonzero(mask.all(axis=1))
    if complete.size == 0:
        return NearestNeighbourResult(
            x=None,
            fun=float("nan"),
            status=INACCURATE,
            message="no fully observed row: 1-NN has no donor (the paper's NA)",
            nit=0,
            wall_time=time.perf_counter() - start,
            neighbour=None,
            n_complete_rows=0,
        )
    C = W[complete]  # (c, d), fully observed donors
    M = mask.astype(np.float64)
    # sum_j m_ij (w_ij - c_kj)^2 = sum_j m_ij w_ij^2 - 2 (m o w)_i . c_k + m_i . (c_k o c_k);
    # W is already zero where mask is False, so m o w = W.
    D = (W * W).sum(axis=1)[:, None] - 2.0 * (W @ C.T) + M @ (C * C).T
    neighbour = complete[np.argmin(D, axis=1)]
    neighbour[complete] = complete
    X = np.where(mask, W, W[neighbour])
    return NearestNeighbourResult(
        x=X,
        fun=float(np.sum(np.where(mask, W - W[neighbour], 0.0) ** 2)),
        status=CONVERGED,
        message=f"every row filled from the nearest of {complete.size} fully observed rows",
        nit=0,
        wall_time=time.perf_counter() - start,
        neighbour=neighbour,
        n_complete_rows=complete.size,
    )
