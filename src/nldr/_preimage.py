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

Problems solved (L-BFGS over a block of rows, whose objective is the sum of the rows' objectives, so
its minimiser is every row's minimiser; the hard limit of :func:`complete_rows` by Newton's method on
each row's free entries, with the exact Hessian of r, see :func:`_newton_rows`):

- :func:`preimage`: min_x r_a(x), the pre-image of a subspace point (``inverse_transform``);
- :func:`complete_rows`: min over the free entries of

      sum_j m_j l(x_j - w_j) + rho r(x),   l(t) = t^2 (squared) or h_delta(t) (Huber),

  (the paper's masked least-squares data term, or its Huber form :func:`nldr.data_terms.huber_loss`,
  plus the weight rho on the distance to the learned manifold). ``rho=None`` is the hard limit: the
  observed entries stay fixed and the missing ones minimise r alone.

Starts and averaging. The problem is not convex. :func:`nearest_rows` finds the training rows nearest
to a new row on its observed entries (mean loss l over them); :func:`average_solutions` combines the
local minima reached from each of them (uniformly or by inverse distance). When many entries are
missing, several branches of the manifold agree with the observed ones: a single local minimum
commits to one branch, their average approximates the conditional mean, which has the lower expected
squared error (oil flow at p = 0.5: REPRODUCTION.md, "New rows on a learned manifold").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from .data_terms import huber_loss
from .kernels import center_cross_kernel, rbf_kernel

__all__ = [
    "Subspace",
    "subspace_distance",
    "preimage",
    "complete_rows",
    "completion_objective",
    "complete_from_starts",
    "nearest_rows",
    "average_solutions",
    "LOSSES",
]

#: data losses of :func:`complete_rows` and :func:`nearest_rows`
LOSSES = ("squared", "huber")

#: rows per L-BFGS block: each block's kernel is (block, n); blocks keep the curvature pairs of
#: L-BFGS from mixing too many independent rows.
BLOCK = 64
#: the hard limit's Newton steps are at most this many kernel widths 1 / sqrt(2 gamma) long
NEWTON_MAX_STEP = 1.0


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


def _projection(space: Subspace, X: np.ndarray):
    """For m rows X (m, d): the kernel rows Kx (m, n), r(x) (m,), the distance to each row's own
    projection, and G = dr/dk_x (m, n) (the module docstring's formulas with c = b(x))."""
    Kx = rbf_kernel(X, space.gamma, space.X_fit)
    V = space.V
    if space.centred:
        kxx = 1.0 - 2.0 * Kx.mean(axis=1) + space.column_means.mean()
        B = center_cross_kernel(Kx, space.column_means) @ V
    else:
        kxx = np.ones(X.shape[0])
        B = Kx @ V
    r = kxx - np.einsum("ij,ij->i", B, B)
    G = -2.0 * (B @ V.T)
    if space.centred:
        G += 2.0 * (B @ V.mean(axis=0))[:, None] - 2.0 / Kx.shape[1]
    return Kx, r, G


#: X_fit^T diag(M) X_fit of every row from the training rows' outer products (one matrix product) while
#: they hold at most this many numbers; one product per row above (memory O(m n d) instead)
OUTER_PRODUCTS_MAX = 2**22


def _distance_hessian(space: Subspace, X: np.ndarray, Vt: np.ndarray):
    """r(x) (m,), its gradient (m, d) and Hessian (m, d, d) for the rows X (m, d) (formulas: see
    :func:`_newton_rows`); ``Vt`` is V less its mean row when centred (else V)."""
    Xf = space.X_fit
    n, d = Xf.shape
    g2 = 2.0 * space.gamma
    Kx, r, G = _projection(space, X)
    M = G * Kx
    S, u = M.sum(axis=1), M @ Xf
    grad = -g2 * (S[:, None] * X - u)
    xu = X[:, :, None] * u[:, None, :]
    second = S[:, None, None] * X[:, :, None] * X[:, None, :] - xu - xu.transpose(0, 2, 1)
    if n * d * d <= OUTER_PRODUCTS_MAX:  # X_fit^T diag(M) X_fit
        second += (M @ (Xf[:, :, None] * Xf[:, None, :]).reshape(n, d * d)).reshape(-1, d, d)
    else:
        second += np.matmul((M[:, :, None] * Xf).transpose(0, 2, 1), Xf)
    J = -g2 * ((Kx @ Vt)[:, :, None] * X[:, None, :] - np.matmul(Vt.T, Kx[:, :, None] * Xf))
    H = g2**2 * second - 2.0 * np.matmul(J.transpose(0, 2, 1), J)
    H[:, np.arange(d), np.arange(d)] -= g2 * S[:, None]
    return r, grad, H


def _newton_rows(space: Subspace, X0: np.ndarray, free: np.ndarray, max_iter: int, gtol: float):
    """min r(x) over the ``free`` entries of each row of X0 (m, d): Newton's method per row.

    Maintenance note. r depends on x through the kernel row k (k_j = k(x, x_j)): r = kxx(k) - ||b||^2
    with kxx affine in k and b = k V~ + const, V~ = V less its mean row when centred (else V). With
    Delta_j = x - x_j, dk_j/dx = -2 gamma k_j Delta_j and d2k_j/dx2 = k_j (4 gamma^2 Delta_j Delta_j^T
    - 2 gamma I), so with G = dr/dk and M_j = G_j k_j the gradient is g = -2 gamma sum_j M_j Delta_j
    and the Hessian

        H = 4 gamma^2 sum_j M_j Delta_j Delta_j^T - 2 gamma (sum_j M_j) I - 2 J^T J,
        J = V~^T dk/dx = -2 gamma (a x^T - Q),  a = V~^T k,  Q = V~^T diag(k) X_fit   (k x d),

    where sum_j M_j Delta_j Delta_j^T = S x x^T - x u^T - u x^T + X_fit^T diag(M) X_fit (S = sum M,
    u = X_fit^T M). Each row's step solves H_FF s = -g_F on its free entries F with H's eigenvalues
    replaced by their absolute values (floored at 1e-10 of the largest), so it is a descent direction
    even where H is indefinite; it is at most one kernel width 1 / sqrt(2 gamma) long, and halved
    until r decreases by the Armijo rule. A row stops when max |g_F| <= gtol (the test L-BFGS-B's
    ``gtol`` applies to a block) or when no halving decreases r (r is then flat to rounding).
    Rows never interact, so a row's answer does not depend on the others. Returns the rows and the
    number of rows that reached ``max_iter``.
    """
    X = X0.copy()
    n, d = space.X_fit.shape
    g2 = 2.0 * space.gamma
    Vt = space.V - space.V.mean(axis=0) if space.centred else space.V
    cap = NEWTON_MAX_STEP / np.sqrt(g2)
    chunk = max(1, int(2**22 // (n * max(d, Vt.shape[1]))))
    active = free.any(axis=1)
    for _ in range(max_iter):
        rows = np.flatnonzero(active)
        if rows.size == 0:
            return X, 0
        for start in range(0, rows.size, chunk):
            idx = rows[start : start + chunk]
            x, F = X[idx], free[idx]
            r, grad, H = _distance_hessian(space, x, Vt)
            grad = np.where(F, grad, 0.0)
            moving = np.abs(grad).max(axis=1) > gtol
            active[idx[~moving]] = False
            if not moving.any():
                continue
            idx, x, F, r, grad, H = (v[moving] for v in (idx, x, F, r, grad, H))
            FF = F[:, :, None] & F[:, None, :]
            scale = np.abs(np.where(FF, H, 0.0)).max(axis=(1, 2))
            H = np.where(FF, H, 0.0)
            H[:, np.arange(d), np.arange(d)] += np.where(F, 0.0, scale[:, None] + 1.0)
            lam, U = np.linalg.eigh(H)
            lam = np.maximum(np.abs(lam), 1e-10 * np.abs(lam).max(axis=1, keepdims=True) + 1e-300)
            step = -np.einsum("mij,mj->mi", U, np.einsum("mji,mj->mi", U, grad) / lam)
            step = np.where(F, step, 0.0)
            length = np.linalg.norm(step, axis=1)
            step *= np.minimum(1.0, cap / np.maximum(length, 1e-300))[:, None]
            slope = np.einsum("ij,ij->i", grad, step)
            alpha = np.ones(idx.size)
            pending = np.ones(idx.size, dtype=bool)
            for _halving in range(40):
                trial = x[pending] + alpha[pending, None] * step[pending]
                r_trial = _projection(space, trial)[1]
                ok = r_trial <= r[pending] + 1e-4 * alpha[pending] * slope[pending]
                where = np.flatnonzero(pending)
                X[idx[where[ok]]] = trial[ok]
                pending[where[ok]] = False
                alpha[where[~ok]] *= 0.5
                if not pending.any():
                    break
            active[idx[pending]] = False  # no decrease: flat to rounding
    return X, int(active.sum())


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


def _loss(T: np.ndarray, loss: str, delta: float | None) -> np.ndarray:
    return T * T if loss == "squared" else huber_loss(T, delta)


def nearest_rows(
    X_fit: np.ndarray,
    W: np.ndarray,
    mask: np.ndarray,
    n_neighbors: int,
    *,
    loss: str = "squared",
    delta: float | None = None,
    chunk: int = 128,
) -> tuple[np.ndarray, np.ndarray]:
    """The training rows nearest to each new row on its observed entries, nearest first.

    The distance of a new row w (mask m) to a training row x is the mean loss over the observed
    entries, ``sum_j m_j l(w_j - x_j) / sum_j m_j`` (l squared: the mean squared difference; l Huber:
    the same with each entry's pull bounded, so a gross error in one observed entry does not decide
    the neighbours). A row with nothing observed has distance 0 to every training row.

    Parameters
    ----------
    X_fit : (n, d) training rows
    W, mask : (m, d) new rows and their observation masks (True = observed)
    n_neighbors : number of neighbours k (at most n)
    loss, delta : "squared", or "huber" with threshold delta > 0 (units of W)
    chunk : new rows per block of the (chunk, n, d) Huber differences

    Returns
    -------
    index : (m, k) int, rows of X_fit, nearest first
    distance : (m, k) their distances (units of W squared)
    """
    Wz = np.where(mask, W, 0.0)
    m = mask.astype(np.float64)
    if loss == "squared":
        D = (m * Wz**2).sum(axis=1)[:, None] - 2.0 * Wz @ X_fit.T + m @ (X_fit**2).T
    else:
        D = np.empty((W.shape[0], X_fit.shape[0]))
        for start in range(0, W.shape[0], chunk):
            rows = slice(start, start + chunk)
            L = _loss(Wz[rows, None, :] - X_fit[None, :, :], loss, delta)
            D[rows] = np.einsum("mnd,md->mn", L, m[rows])
    D = np.maximum(D, 0.0) / np.maximum(m.sum(axis=1), 1.0)[:, None]
    k = min(int(n_neighbors), X_fit.shape[0])
    nearest = np.argpartition(D, k - 1, axis=1)[:, :k]
    dist = np.take_along_axis(D, nearest, axis=1)
    order = np.argsort(dist, axis=1, kind="stable")
    return np.take_along_axis(nearest, order, axis=1), np.take_along_axis(dist, order, axis=1)


def average_solutions(X: np.ndarray, distance: np.ndarray, weights: str = "uniform") -> np.ndarray:
    """Combine per-neighbour solutions (m, k, d) into one row each (m, d).

    ``weights="uniform"``: their mean; ``"distance"``: weights proportional to 1 / sqrt(distance)
    (the inverse root-mean loss of :func:`nearest_rows`, as scikit-learn's ``KNNImputer`` weights by
    inverse distance); a row with zero distances uses those neighbours alone, equally weighted.
    """
    if weights == "uniform":
        return X.mean(axis=1)
    root = np.sqrt(np.maximum(distance, 0.0))
    zero = root <= 1e-300
    w = np.where(zero.any(axis=1, keepdims=True), zero.astype(np.float64), 1.0 / np.where(zero, 1.0, root))
    w /= w.sum(axis=1, keepdims=True)
    return np.einsum("mk,mkd->md", w, X)


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
    loss: str = "squared",
    delta: float | None = None,
    max_iter: int = 500,
    gtol: float = 1e-7,
):
    """Minimise ``sum_j m_j l(x_j - w_j) + rho r(x)`` per row (``rho=None``: r over the missing entries).

    Parameters
    ----------
    W : (m, d) observations (anything where ``mask`` is False)
    mask : (m, d) bool, True = observed
    X0 : (m, d) start (observed entries equal to W when ``rho`` is None)
    rho : weight of the squared feature distance (kernel units) against the data loss (data units
        squared); None = infinite (the hard limit, where the loss plays no part)
    loss : "squared" (l(t) = t^2) or "huber" (l = h_delta of :func:`nldr.data_terms.huber_loss`: t^2
        within delta, linear beyond, so an observed entry far from the manifold pulls with force at
        most 2 delta)
    delta : Huber threshold (units of W); required with loss "huber"

    Returns
    -------
    X : (m, d) completed (and, with finite rho, denoised) rows
    unconverged : number of row blocks (with ``rho=None``: rows) that reached max_iter
    """
    if rho is None:
        return _newton_rows(space, X0, ~mask, max_iter, gtol)
    Wz = np.where(mask, W, 0.0)

    def fun_grad(Y, rows):
        return completion_objective(space, Wz[rows], mask[rows], Y, rho=rho, loss=loss, delta=delta)

    return _lbfgs_rows(fun_grad, X0, np.ones(W.shape, dtype=bool), max_iter, gtol)


def complete_from_starts(
    space: Subspace,
    W: np.ndarray,
    mask: np.ndarray,
    X0: np.ndarray,
    *,
    rho: float | None = None,
    loss: str = "squared",
    delta: float | None = None,
    max_iter: int = 500,
) -> np.ndarray:
    """:func:`complete_rows` for every row of W (m, d) from each of its k starts X0 (m, k, d);
    returns the k local minima per row, shape (m, k, d)."""
    m, k, d = X0.shape
    X_hat, _ = complete_rows(
        space,
        np.repeat(W, k, axis=0),
        np.repeat(mask, k, axis=0),
        X0.reshape(m * k, d),
        rho=rho,
        loss=loss,
        delta=delta,
        max_iter=max_iter,
    )
    return X_hat.reshape(m, k, d)


def completion_objective(
    space: Subspace,
    W: np.ndarray,
    mask: np.ndarray,
    X: np.ndarray,
    *,
    rho: float,
    loss: str = "squared",
    delta: float | None = None,
):
    """Per-row objective of :func:`complete_rows` with finite rho, and its gradient.

    Returns ``f`` (m,), ``f_i = sum_j mask_ij l(X_ij - W_ij) + rho r(X_i)``, and ``df/dX`` (m, d),
    with l' = 2 t (squared) or 2 clip(t, -delta, delta) (Huber). W, mask, X: (m, d).
    """
    r, g = subspace_distance(space, X)
    res = mask * (X - np.where(mask, W, 0.0))
    psi = res if loss == "squared" else np.clip(res, -delta, delta)
    return _loss(res, loss, delta).sum(axis=1) + rho * r, 2.0 * psi + rho * g
