"""Robust kernel PCA for missing data (Nguyen & De la Torre 2008), the "RKPCA" of Table 2.

Each sample y is scored by its energy

    E(y) = E_proj(y) + C ||m o (y - w)||^2,

where E_proj(y) = ||phi~(y) - U U^T phi~(y)||^2 is the squared feature-space distance of y from the
kernel principal subspace U (q components of centred KPCA), m the sample's observation mask and w
its observed values. Missing entries are found by minimising the summed energy with L-BFGS on the
analytic gradient, alternating with refitting KPCA to the completed matrix.

Maintenance note (E_proj and its gradient through the kernel). Fit KPCA on n samples X with kernel
K, centred kernel K~ = H K H (H = I - 11^T/n) with leading eigenpairs (nu_k, v_k), and
coefficients A = [v_k / sqrt(nu_k)], so that U = Phi~ A is orthonormal. The v_k are orthogonal to 1
(H 1 = 0), hence H A = A. For a query y with kernel vector k (k_i = k(y, x_i)) and m = K 1 / n,

    phi~(y)^T phi~(y) = k(y, y) - 2 1^T k / n + 1^T K 1 / n^2,    U^T phi~(y) = A^T H (k - m) = A^T (k - m),
    E_proj(y) = 1 - 2 1^T k / n + 1^T K 1 / n^2 - ||A^T (k - m)||^2        (k(y, y) = 1 for RBF),
    dE_proj/dk = -2 1 / n - 2 A A^T (k - m),
    dk_i/dy = -2 gamma k_i (y - x_i)   =>   dE_proj/dy = -2 gamma sum_i g_i k_i (y - x_i),  g = dE/dk.

Stacked over queries Y (rows), with Kyx the (m, n) cross kernel, G the rows g and M = G o Kyx:
dE/dY = -2 gamma (diag(M 1) Y - M X), two matrix products and no loop over points.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .._validation import check_count, check_positive
from ..kernels import center_kernel, squared_distances
from ..result import SolverResult
from ._lbfgs import outer_loop
from ._masked import check_masked_matrix, mean_fill

__all__ = ["KernelSubspace", "RKPCAResult", "rkpca_impute"]


@dataclass(frozen=True)
class KernelSubspace:
    """A fitted centred-KPCA principal subspace of an RBF kernel.

    Attributes
    ----------
    X_fit : array, shape (n, d)
        Training samples.
    gamma : float
        RBF inverse squared width.
    coefficients : array, shape (n, q)
        A = [v_k / sqrt(nu_k)]: the subspace basis is U = Phi~ A (orthonormal in feature space).
    kernel_column_means : array, shape (n,)
        m = K 1 / n of the training kernel.
    kernel_mean : float
        1^T K 1 / n^2, the squared norm of the feature-space mean.
    eigenvalues : array, shape (q,)
        Leading eigenvalues of the centred training kernel.
    """

    X_fit: np.ndarray
    gamma: float
    coefficients: np.ndarray
    kernel_column_means: np.ndarray
    kernel_mean: float
    eigenvalues: np.ndarray

    @property
    def n_components(self) -> int:
        return self.coefficients.shape[1]

    def reconstruction_error(self, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Squared feature-space distance of each row of Y to the subspace, and its gradient.

        Parameters
        ----------
        Y : array, shape (m, d)

        Returns
        -------
        error : array, shape (m,)
            E_proj(y_j) = ||phi~(y_j) - U U^T phi~(y_j)||^2.
        gradient : array, shape (m, d)
            d E_proj(y_j) / d y_j (row j depends on y_j only).
        """
        n = self.X_fit.shape[0]
        Kyx = np.exp(-self.gamma * squared_distances(Y, self.X_fit))
        coords = (Kyx - self.kernel_column_means[None, :]) @ self.coefficients  # U^T phi~(y), (m, q)
        error = 1.0 - 2.0 * Kyx.mean(axis=1) + self.kernel_mean - (coords * coords).sum(axis=1)
        G = -2.0 / n - 2.0 * coords @ self.coefficients.T  # dE/dk per query, (m, n)
        M = G * Kyx
        gradient = -2.0 * self.gamma * (M.sum(axis=1)[:, None] * Y - M @ self.X_fit)
        return error, gradient


def _check_n_components(n_components, n: int) -> None:
    if isinstance(n_components, bool) or not isinstance(n_components, int | np.integer | float):
        raise ValueError(f"n_components must be an integer or a fraction in (0, 1); got {n_components!r}")
    if isinstance(n_components, float):
        if not 0.0 < n_components < 1.0:
            raise ValueError(f"n_components as a float is a trace fraction in (0, 1); got {n_components!r}")
    elif not 1 <= n_components < n:
        raise ValueError(f"n_components must satisfy 1 <= n_components < n = {n}; got {n_components}")


def _fit_subspace(X: np.ndarray, gamma: float, n_components: int | float) -> KernelSubspace:
    """The centred-KPCA subspace of complete X (n, d): q = n_components components, or the fewest
    holding a trace fraction n_components in (0, 1); capped at the numerical rank. No validation."""
    n = X.shape[0]
    K = np.exp(-gamma * squared_distances(X))
    nu, V = np.linalg.eigh(center_kernel(K))
    nu, V = nu[::-1], V[:, ::-1]
    if not nu[0] > 0:
        raise ValueError("all samples coincide in feature space; the KPCA subspace is undefined")
    positive = nu > nu[0] * 1e-12
    if isinstance(n_components, float):
        cumulative = np.cumsum(np.where(positive, nu, 0.0)) / nu[positive].sum()
        q = int(np.searchsorted(cumulative, n_components - 1e-12) + 1)
    else:
        q = int(n_components)
    q = max(1, min(q, int(positive.sum()), n - 1))
    A = V[:, :q] / np.sqrt(nu[:q])[None, :]
    m = K.mean(axis=0)
    return KernelSubspace(X.copy(), gamma, A, m, float(m.mean()), nu[:q].copy())


def _energy(
    Y: np.ndarray, W: np.ndarray, mask: np.ndarray, subspace: KernelSubspace, weight: float
) -> tuple[float, np.ndarray]:
    """Summed energy sum_j E_proj(y_j) + C ||mask o (Y - W)||^2 of the rows of Y (m, d) against a fixed
    subspace, and its gradient (m, d); ``weight`` C = inf leaves the data term out (a constraint the
    caller enforces). No validation."""
    error, grad = subspace.reconstruction_error(Y)
    value = float(error.sum())
    if weight > 0 and np.isfinite(weight):
        R = np.where(mask, Y - W, 0.0)
        value += weight * float(np.sum(R * R))
        grad = grad + 2.0 * weight * R
    return value, grad


def _check_weight(weight) -> float:
    try:
        w = float(weight)
    except (TypeError, ValueError):
        raise ValueError(f"weight must be a number >= 0 or inf; got {weight!r}") from None
    if np.isnan(w) or w < 0:
        raise ValueError(f"weight must be a number >= 0 or inf; got {weight!r}")
    return w


@dataclass(kw_only=True, repr=False)
class RKPCAResult(SolverResult):
    """Outcome of ``rkpca_impute``.

    Attributes
    ----------
    x : array, shape (n, d)
        Completed matrix in the units of W: observed entries of W, RKPCA estimates at the missing
        ones.
    fun : float
        The energy minimised (summed over samples, the subspace refitted to them) at the end of the
        last outer iteration (``energy_history[-1]``).
    status : int
        :data:`~nldr.result.CONVERGED` when the last inner solve converged and q (if chosen by trace
        fraction) did not change; otherwise ``max_iter`` outer iterations ran, and the status is
        :data:`~nldr.result.INACCURATE` if the last L-BFGS solve stopped because its line search
        could not make progress, :data:`~nldr.result.MAX_ITER` if not.
    message : str
        Why it stopped, with the message of the last inner solve.
    nit : int
        Outer iterations (choice of q followed by an inner L-BFGS solve); 1 when q is fixed.
    wall_time : float
    Y : array, shape (n, d)
        The energy minimiser itself; equals ``x`` when ``weight`` is inf, otherwise its observed
        entries are pulled towards the subspace (denoised) too.
    n_components : int
        q of the final KPCA subspace.
    n_components_history : tuple of int
        q used in every outer iteration.
    energy_history : array, shape (nit + 1,)
        Summed energy at the start and after every outer iteration, the subspace refitted to the
        current samples (so the projection part is the sum of the discarded centred eigenvalues).
    n_inner_iter : int
        Total L-BFGS iterations.
    """

    Y: np.ndarray
    n_components: int
    n_components_history: tuple[int, ...]
    energy_history: np.ndarray
    n_inner_iter: int


def rkpca_impute(
    W,
    mask,
    gamma: float,
    *,
    n_components: int | float = 7,
    weight: float = np.inf,
    max_iter: int = 20,
    inner_max_iter: int = 2000,
    gtol: float = 1e-6,
) -> RKPCAResult:
    """Impute missing entries with robust kernel PCA (feature-space subspace distance + data term).

    Parameters
    ----------
    W : array, shape (n, d)
        Data, samples as rows; entries where ``mask`` is False are ignored (they may be NaN).
    mask : array of bool, shape (n, d)
        True where ``W`` is observed. Every column needs an observed entry.
    gamma : float > 0
        RBF inverse squared width (0.075 on oil flow in the paper).
    n_components : int or float
        Components q of the centred KPCA subspace, or a trace fraction in (0, 1) from which q is
        re-chosen in every outer iteration (capped at the numerical rank).
    weight : float >= 0 or inf
        C, the weight of the data term on observed entries. ``inf`` (default) keeps observed entries
        fixed and optimises only the missing ones; a finite C lets observed entries move too
        (denoising), the completed ``X`` still keeping W at observed entries.
    max_iter : int
        Maximum outer iterations (only a trace-fraction ``n_components`` needs more than one).
    inner_max_iter : int
        Maximum L-BFGS iterations per outer iteration.
    gtol : float
        L-BFGS projected-gradient tolerance.

    Returns
    -------
    RKPCAResult

    Notes
    -----
    The method alternates "fit KPCA to the current samples" and "minimise the energy over the free
    entries with that subspace fixed". We run this alternation to its fixed point directly: L-BFGS
    minimises the profile energy F(Y) = sum_j E_proj(y_j; subspace fitted to Y) + data term, whose
    gradient equals the fixed-subspace gradient because the fitted subspace and feature-space mean
    minimise the summed projection error (envelope theorem). So the fixed points of the alternation
    are exactly the stationary points of F, reached in one quasi-Newton solve instead of many slow
    outer sweeps; F is also the sum of the discarded eigenvalues of the centred kernel.
    """
    start = time.perf_counter()
    W, mask = check_masked_matrix(W, mask)
    gamma = check_positive(gamma, "gamma")
    n = W.shape[0]
    if n < 3:
        raise ValueError(f"W needs at least 3 rows for KPCA; got {n}")
    _check_n_components(n_components, n)
    weight = _check_weight(weight)
    check_count(max_iter, "max_iter")
    check_count(inner_max_iter, "inner_max_iter")
    gtol = check_positive(gtol, "gtol")

    Y = mean_fill(W, mask)
    missing = ~mask
    free = missing if not np.isfinite(weight) else np.ones_like(mask)
    loop = outer_loop(
        Y,
        free,
        lambda Y, q: _energy(Y, W, mask, _fit_subspace(Y, gamma, q), weight),
        lambda: _fit_subspace(Y, gamma, n_components).n_components,
        done=not missing.any() and np.isinf(weight),
        max_iter=max_iter,
        inner_max_iter=inner_max_iter,
        gtol=gtol,
    )
    return RKPCAResult(
        x=np.where(mask, W, Y),
        fun=float(loop.objective[-1]),
        status=loop.status,
        message=loop.message,
        nit=loop.nit,
        wall_time=time.perf_counter() - start,
        Y=Y,
        n_components=loop.n_components,
        n_components_history=loop.n_components_history,
        energy_history=loop.objective,
        n_inner_iter=loop.n_inner_iter,
    )
