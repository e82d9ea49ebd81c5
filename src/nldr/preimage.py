"""Pre-images against a learned kernel principal subspace: new samples on a fitted manifold.

The paper's sub-problem (E_inv) is "a generalized pre-image estimation problem": it finds the sample
whose feature vector lies on the principal subspace of the RKHS and best explains the observation, but
only for the samples the manifold was learned from (its Section 4.1 leaves new samples as future work).
This module is that extension for a fitted :class:`~nldr.robust_kpca.RobustKernelPCA`.

Notation. Training samples x_1..x_n (rows of ``X_fit``), RBF kernel k(x, y) = exp(-gamma ||x - y||^2),
feature mean mu = mean_j phi(x_j) when the model centres (else mu = 0), centred features
phi~(x) = phi(x) - mu, and the kept eigenpairs (lambda_i, u_i), i = 1..k, of the (centred) training
kernel. The unit principal axes are e_i = sum_j u_ji phi~(x_j) / sqrt(lambda_i), so the coordinates of
a sample on them are

    b(x) = k~_x V,   V = U diag(lambda)^(-1/2)   (shape (n, k)),

with k~_x the centred cross-kernel row (:func:`nldr.kernels.center_cross_kernel`). The squared
feature-space distance of phi~(x) to a point sum_i a_i e_i of the subspace is

    r_a(x) = k~(x, x) - 2 a . b(x) + ||a||^2,   k~(x, x) = 1 - 2 mean_j k(x, x_j) + mean(K)

(uncentred: k~(x, x) = 1), and the distance to its own projection is r(x) = k~(x, x) - ||b(x)||^2
(the choice a = b(x) minimises r_a over a). Both are functions of the kernel row k_x only, so with
G = dr/dk_x (shape (n,)) the chain rule through dk(x, x_j)/dx = -2 gamma k(x, x_j) (x - x_j) gives

    dr/dx = -2 gamma (sum_j G_j k_xj x - sum_j G_j k_xj x_j),

with dr/dk_x = -2/n 1 - 2 (V - 1 vbar^T) c, vbar = mean of V's rows, and c = b(x) for r or c = a for
r_a (uncentred: -2 V c). Rows are independent; every function here works on m rows at once.

Problems solved (L-BFGS over a block of rows; the objective is the sum of the rows' objectives, so its
minimiser is every row's minimiser):

- :func:`preimage`: min_x r_a(x), the pre-image of a subspace point (``inverse_transform``);
- :func:`complete_rows`: min over the free entries of

      ||m o (x - w)||^2 + rho r(x)

  (the paper's masked least-squares data term plus the weight rho on the distance to the learned
  manifold). ``rho=None`` is the hard limit: the observed entries stay fixed and the missing ones
  minimise r alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from .kernels import center_cross_kernel, rbf_kernel

__all__ = ["Subspace", "subspace_distance", "preimage", "complete_rows", "neighbour_start"]

#: rows per L-BFGS block: each block's kernel is (block, n); blocks keep the curvature pairs of
#: L-BFGS from mixing too many independent rows.
BLOCK = 64


@dataclass(frozen=True)
class Subspace:
    """The learned principal subspace, as arrays.

    Attributes
    ----------
    X_fit : (n, d) training samples
    gamma : RBF inverse squared width
    V : (n, k) eigenvectors divided by the square roots of their eigenvalues, ``U / sqrt(lambda)``
    column_means : (n,) column means of the uncentred training kernel, or None (uncentred model)
    """

    X_fit: np.ndarray
    gamma: float
    V: np.ndarray
    column_means: np.ndarray | None

    @property
    def centred(self) -> bool:
        return self.column_means is not None


def subspace_distance(space: Subspace, X: np.ndarray, A: np.ndarray | None = None):
    """Squared feature distances and their gradients, for m rows at once.

    Parameters
    ----------
    space : the learned subspace
    X : (m, d) samples
    A : (m, k) subspace points as coordinates on the unit axes, or None for each sample's own
        projection

    Returns
    -------
    r : (m,) ``r_A(x)`` (or ``r(x)``), squared feature-space distances (kernel units, in [0, 4])
    grad : (m, d) their gradients with respect to the rows of X
    """
    Kx = rbf_kernel(X, space.gamma, space.X_fit)
    n = Kx.shape[1]
    V = space.V
    if space.centred:
        mean_k = Kx.mean(axis=1)
        kxx = 1.0 - 2.0 * mean_k + space.column_means.mean()
        B = center_cross_kernel(Kx, space.column_means) @ V
    else:
        kxx = np.ones(X.shape[0])
        B = Kx @ V
    Cc = B if A is None else A
    r = (
        kxx - np.einsum("ij,ij->i", B, B)
        if A is None
        else kxx - 2 * np.einsum("ij,ij->i", A, B) + np.einsum("ij,ij->i", A, A)
    )
    G = -2.0 * (Cc @ V.T)
    if space.centred:
        G += 2.0 * (Cc @ V.mean(axis=0))[:, None] - 2.0 / n
    M = G * Kx
    grad = -2.0 * space.gamma * (M.sum(axis=1)[:, None] * X - M @ space.X_fit)
    return r, grad


def _lbfgs_rows(
    fun_grad, X0: np.ndarray, free: np.ndarray, max_iter: int, gtol: float
) -> tuple[np.ndarray, int]:
    """Minimise a sum of row objectives over the ``free`` entries of X0, block by block.

    ``fun_grad(X, rows)`` returns per-row values (len(rows),) and gradients (len(rows), d) for the
    block ``X`` of rows ``rows``. Returns the optimised X and the number of blocks that hit max_iter.
    """
    X = X0.copy()
    unconverged = 0
    for start in range(0, X.shape[0], BLOCK):
        rows = np.arange(start, min(start + BLOCK, X.shape[0]))
        Xb, Fb = X[rows], free[rows]
        if not Fb.any():
            continue

        def f(z, Xb=Xb, Fb=Fb, rows=rows):
            Y = Xb.copy()
            Y[Fb] = z
            val, grad = fun_grad(Y, rows)
            return float(val.sum()), grad[Fb]

        res = minimize(
            f,
            Xb[Fb],
            jac=True,
            method="L-BFGS-B",
            options={"maxiter": max_iter, "gtol": gtol, "ftol": 1e-15, "maxcor": 20},
        )
        unconverged += int(res.nit >= max_iter)
        Xb = Xb.copy()
        Xb[Fb] = res.x
        X[rows] = Xb
    return X, unconverged


def neighbour_start(
    X_fit: np.ndarray, W: np.ndarray, mask: np.ndarray, n_neighbors: int = 5, each: bool = False
) -> np.ndarray:
    """Starts for the missing entries from the nearest training rows on the observed entries.

    The distance is the mean squared difference over a row's observed entries. With ``each`` False,
    one start per row, at the mean of its ``n_neighbors`` nearest training rows (shape (m, d)); with
    ``each`` True, one start per neighbour (shape (m, n_neighbors, d)). A row with nothing observed
    starts at the training mean. Observed entries keep their values. Shapes: X_fit (n, d), W and mask
    (m, d).
    """
    Wz = np.where(mask, W, 0.0)
    m = mask.astype(np.float64)
    D = (m * Wz**2).sum(axis=1)[:, None] - 2.0 * Wz @ X_fit.T + m @ (X_fit**2).T
    D /= np.maximum(m.sum(axis=1), 1.0)[:, None]
    k = min(int(n_neighbors), X_fit.shape[0])
    nearest = np.argpartition(D, k - 1, axis=1)[:, :k]
    starts = X_fit[nearest]  # (m, k, d)
    starts[~mask.any(axis=1)] = X_fit.mean(axis=0)
    if not each:
        return np.where(mask, W, starts.mean(axis=1))
    return np.where(mask[:, None, :], Wz[:, None, :], starts)


def preimage(space: Subspace, A: np.ndarray, X0: np.ndarray, *, max_iter: int = 500, gtol: float = 1e-7):
    """Pre-images of subspace points: argmin_x r_a(x) for each row a of A, from the starts X0.

    Parameters
    ----------
    A : (m, k) coordinates on the unit principal axes
    X0 : (m, d) starting samples (a local method: the pre-image problem is not convex)

    Returns
    -------
    X : (m, d) pre-images
    unconverged : number of row blocks that reached max_iter
    """
    free = np.ones(X0.shape, dtype=bool)
    return _lbfgs_rows(lambda Y, rows: subspace_distance(space, Y, A[rows]), X0, free, max_iter, gtol)


def complete_rows(
    space: Subspace,
    W: np.ndarray,
    mask: np.ndarray,
    X0: np.ndarray,
    *,
    rho: float | None,
    max_iter: int = 500,
    gtol: float = 1e-7,
):
    """Minimise ``||m o (x - w)||^2 + rho r(x)`` per row (``rho=None``: r over the missing entries only).

    Parameters
    ----------
    W : (m, d) observations (anything where ``mask`` is False)
    mask : (m, d) bool, True = observed
    X0 : (m, d) start (observed entries equal to W when ``rho`` is None)
    rho : weight of the squared feature distance (kernel units) against the squared data residual
        (data units squared); None = infinite (the hard limit)

    Returns
    -------
    X : (m, d) completed (and, with finite rho, denoised) rows
    unconverged : number of row blocks that reached max_iter
    """
    Wz = np.where(mask, W, 0.0)
    if rho is None:
        return _lbfgs_rows(lambda Y, rows: subspace_distance(space, Y), X0, ~mask, max_iter, gtol)

    def fun_grad(Y, rows):
        r, g = subspace_distance(space, Y)
        res = mask[rows] * (Y - Wz[rows])
        return (res**2).sum(axis=1) + rho * r, 2.0 * res + rho * g

    return _lbfgs_rows(fun_grad, X0, np.ones(W.shape, dtype=bool), max_iter, gtol)
