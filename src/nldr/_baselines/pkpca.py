"""Probabilistic kernel PCA with missing data (Sanguinetti & Lawrence 2006), the "PKPCA" of Table 2.

PPCA is fitted in the feature space of an (uncentred) RBF kernel, and the missing inputs are chosen
to maximise its likelihood. The likelihood is evaluated in the dual, where only the kernel matrix
K = Phi Phi^T (n x n) appears.

Maintenance note (the objective and its gradient). Restricted to the n-dimensional span of the
mapped data, the sample covariance Phi^T Phi / n has the non-zero eigenvalues lambda_i of K / n
(eigenvectors u_i of K). PPCA with q components, maximised over its loadings and noise variance
(Tipping & Bishop 1999), has log-likelihood

    L(X) = -(n/2) [ sum_{i<=q} log lambda_i + (n - q) log sigma^2 + n ] + const,
    sigma^2 = (tr K / n - sum_{i<=q} lambda_i) / (n - q)     (mean of the discarded eigenvalues).

Because the loadings and sigma^2 are at their optimum for the current X, the envelope theorem lets
us differentiate this profile likelihood through the spectrum alone: with d lambda_i / dK =
u_i u_i^T / n and d tr K / dK = I,

    dE/dK = (1/2) [ U_q diag(1 / lambda_q) U_q^T + (I - U_q U_q^T) / sigma^2 ],   E = -L,

i.e. half the inverse of the model covariance in the dual. ``rbf_kernel_vjp`` carries it to the
inputs. (The identity part contributes nothing: the RBF diagonal is constant.) Minimising E over the
missing entries with the model refitted at every evaluation *is* the alternation "refit PPCA, move
the missing inputs uphill" carried to its fixed point; the outer loop only re-chooses the number of
components q (those capturing ``variance_fraction`` of tr K, plus ``extra_components``), until q no
longer changes.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .._validation import check_count, check_positive
from ..kernels import rbf_kernel_vjp, squared_distances
from ..result import SolverResult
from ._lbfgs import outer_loop
from ._masked import check_masked_matrix, mean_fill

__all__ = ["PKPCAResult", "pkpca_impute"]


@dataclass(kw_only=True, repr=False)
class PKPCAResult(SolverResult):
    """Outcome of ``pkpca_impute``.

    Attributes
    ----------
    x : array, shape (n, d)
        Completed matrix in the units of W (observed entries of W kept).
    fun : float
        The objective minimised: the negative profile log-likelihood E (the module's maintenance note) at
        ``x`` with the last outer iteration's q (``objective_history[-1]``).
    status : int
        :data:`~nldr.result.CONVERGED` when the last inner solve converged and q did not change;
        otherwise ``max_iter`` outer iterations ran, and the status is
        :data:`~nldr.result.INACCURATE` if the last L-BFGS solve stopped because its line search
        could not make progress, :data:`~nldr.result.MAX_ITER` if not.
    message : str
        Why it stopped, with the message of the last inner solve.
    nit : int
        Outer iterations (choice of q followed by an inner L-BFGS solve).
    wall_time : float
    n_components : int
        Number of feature-space components q of the final model.
    n_components_history : tuple of int
        q used in every outer iteration.
    objective_history : array, shape (nit + 1,)
        E at the start and after every outer iteration (with that iteration's q).
    n_inner_iter : int
        Total L-BFGS iterations.
    """

    n_components: int
    n_components_history: tuple[int, ...]
    objective_history: np.ndarray
    n_inner_iter: int


def _objective(X: np.ndarray, gamma: float, q: int) -> tuple[float, np.ndarray]:
    """E = (n/2) [sum_{i<=q} log lambda_i + (n - q) log sigma^2 + n] (lambda: eigenvalues of K / n,
    sigma^2 the mean of the discarded ones; minus the log-likelihood up to a constant) and dE/dX (n, d)
    for complete X (n, d). No validation."""
    n = X.shape[0]
    K = np.exp(-gamma * squared_distances(X))
    mu, U = np.linalg.eigh(K)
    mu, U = mu[::-1], U[:, ::-1]
    lam = np.maximum(mu[:q], np.finfo(float).tiny) / n
    s2 = max((np.trace(K) / n - lam.sum()) / (n - q), np.finfo(float).tiny)
    value = 0.5 * n * (np.log(lam).sum() + (n - q) * np.log(s2) + n)
    Uq = U[:, :q]
    G = 0.5 * ((Uq / lam[None, :]) @ Uq.T + (np.eye(n) - Uq @ Uq.T) / s2)
    return float(value), rbf_kernel_vjp(X, K, G, gamma)


def _components_for_fraction(K: np.ndarray, fraction: float, extra: int) -> int:
    mu = np.linalg.eigvalsh(K)[::-1]
    cumulative = np.cumsum(mu) / mu.sum()
    q = int(np.searchsorted(cumulative, fraction - 1e-12) + 1) + extra
    return min(max(q, 1), K.shape[0] - 1)


def pkpca_impute(
    W,
    mask,
    gamma: float,
    *,
    n_components: int | None = None,
    variance_fraction: float = 0.95,
    extra_components: int = 1,
    max_iter: int = 20,
    inner_max_iter: int = 500,
    gtol: float = 1e-4,
) -> PKPCAResult:
    """Impute missing entries by maximising the likelihood of PPCA in an RBF feature space.

    Parameters
    ----------
    W : array, shape (n, d)
        Data, samples as rows; entries where ``mask`` is False are ignored (they may be NaN).
    mask : array of bool, shape (n, d)
        True where ``W`` is observed. Every column needs an observed entry.
    gamma : float > 0
        RBF inverse squared width (0.075 on oil flow in the paper).
    n_components : int, optional
        Fix the number q of feature-space components. By default q is re-chosen in every outer
        iteration as the fewest leading eigenvalues of K holding ``variance_fraction`` of its trace,
        plus ``extra_components`` (Sanguinetti & Lawrence's choice: 95% of the variance, plus one).
    variance_fraction : float in (0, 1]
    extra_components : int >= 0
    max_iter : int
        Maximum number of outer iterations (choose q, minimise over the missing entries).
    inner_max_iter : int
        Maximum L-BFGS iterations per outer iteration.
    gtol : float
        L-BFGS projected-gradient tolerance of each inner solve.

    Returns
    -------
    PKPCAResult
        Starting from mean imputation; ``success`` is False if ``max_iter`` outer iterations ran
        without q settling and the inner solve converging.
    """
    start = time.perf_counter()
    W, mask = check_masked_matrix(W, mask)
    gamma = check_positive(gamma, "gamma")
    n = W.shape[0]
    if n < 3:
        raise ValueError(f"W needs at least 3 rows for a feature-space PPCA; got {n}")
    if n_components is not None:
        if isinstance(n_components, bool) or not isinstance(n_components, int | np.integer):
            raise ValueError(f"n_components must be an integer or None; got {n_components!r}")
        if not 1 <= n_components < n:
            raise ValueError(f"n_components must satisfy 1 <= n_components < n = {n}; got {n_components}")
    if not (0.0 < float(variance_fraction) <= 1.0):
        raise ValueError(f"variance_fraction must be in (0, 1]; got {variance_fraction!r}")
    if isinstance(extra_components, bool) or not isinstance(extra_components, int | np.integer):
        raise ValueError(f"extra_components must be a non-negative integer; got {extra_components!r}")
    if extra_components < 0:
        raise ValueError(f"extra_components must be a non-negative integer; got {extra_components!r}")
    check_count(max_iter, "max_iter")
    check_count(inner_max_iter, "inner_max_iter")
    gtol = check_positive(gtol, "gtol")

    X = mean_fill(W, mask)
    missing = ~mask

    def choose_q() -> int:
        if n_components is not None:
            return int(n_components)
        K = np.exp(-gamma * squared_distances(X))
        return _components_for_fraction(K, float(variance_fraction), int(extra_components))

    loop = outer_loop(
        X,
        missing,
        lambda X, q: _objective(X, gamma, q),
        choose_q,
        done=not missing.any(),
        max_iter=max_iter,
        inner_max_iter=inner_max_iter,
        gtol=gtol,
    )
    return PKPCAResult(
        x=X,
        fun=float(loop.objective[-1]),
        status=loop.status,
        message=loop.message,
        nit=loop.nit,
        wall_time=time.perf_counter() - start,
        n_components=loop.n_components,
        n_components_history=loop.n_components_history,
        objective_history=loop.objective,
        n_inner_iter=loop.n_inner_iter,
    )
