"""Inference with the non-linear dimensionality regularizer (the paper's Algorithm 1).

Problem. For a data term f (any :class:`~nldr.data_terms.DataTerm`), an RBF kernel
``K(S)_ij = exp(-gamma ||s_i - s_j||^2)`` (optionally double-centred) and tau > 0, the penalty method
minimises, for an increasing sequence of penalty weights rho,

    E_rho(S, C) = f(S) + rho/2 ||K(S) - C^T C||_F^2 + tau ||C||_*                          (1)

warm-starting every stage from the previous one. Two inner solvers are offered:

- ``method="reduced"`` (default): the C-step of Algorithm 1 has a closed form (Theorem 3.1), so C is
  eliminated and the reduced energy E_rho(S) = min_C E_rho(S, C) is minimised over S alone by
  L-BFGS, with the gradient given by the envelope theorem (maintenance note below).
- ``method="alternation"``: the literal Algorithm 1. C-step: closed form. S-step ("pre-image
  estimation"): Levenberg-Marquardt on the stacked residuals
  ``[r_f(S); sqrt(rho/2) w o vech(K(S) - C^T C)]`` with the analytic sparse Jacobian.

Maintenance note (the reduced energy and its gradient). Let K = U diag(lambda) U^T. By Theorem 3.1,

    E_rho(S) = min_C E_rho(S, C) = f(S) + sum_i phi(lambda_i(K(S))),
    phi(lambda) = min_{l >= 0} rho/2 (lambda - l^2)^2 + tau l,

attained at C*(S) = diag(l*) U^T. Envelope theorem: where the minimiser is unique, the derivative of
a minimum value with respect to a parameter is the partial derivative of the objective at the
minimiser, so phi'(lambda) = rho (lambda - l*^2) and, by the eigenvalue perturbation formula
d lambda_i = u_i^T dK u_i,

    dE_rho / dK = U diag(rho (lambda - l*^2)) U^T = rho (K - C*^T C*),

which is the K-gradient of (1) at fixed C = C*(S). The S-gradient then follows from the kernel's
vector-Jacobian product (:func:`nldr.kernels.rbf_kernel_vjp`); with centring, K = H K_rbf H and the
gradient with respect to K_rbf is H (dE/dK) H. So evaluating E_rho and its gradient costs one
symmetric eigendecomposition and O(n^2 d) work, the same as one C-step. phi is continuous but has a
kink where an eigenvalue crosses the threshold lambda_star and l* jumps from 0 to a positive root
(both candidates tie there). phi is the minimum of two smooth branches, so the kink is concave (the
slope drops from rho lambda to rho (lambda - l*^2)): it can never hold a minimiser, and L-BFGS steps
over it.

Maintenance note (the kernel-mismatch residuals and their Jacobian). ||K - B||_F^2 with K and B
symmetric equals sum_{i<=j} w_ij^2 (K_ij - B_ij)^2 with w_ii = 1 and w_ij = sqrt(2) for i < j, so the
residual vector holds only the upper triangle (n (n + 1) / 2 entries instead of n^2). For the
uncentred RBF kernel, K_ij depends only on s_i and s_j:

    dK_ij / ds_i = -2 gamma K_ij (s_i - s_j) = -dK_ij / ds_j,

so row (i, j) of the Jacobian has 2 d non-zeros, and the diagonal rows (K_ii = 1) are empty. With
centring every entry of H K H depends on every sample, so the Jacobian is dense; it is applied
matrix-free instead (``J v`` is the directional derivative of K, ``J^T u`` the kernel VJP), which is
also used for large uncentred problems whose sparse Jacobian would not fit in memory.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.optimize import least_squares, minimize
from scipy.sparse.linalg import LinearOperator, aslinearoperator

from ._spectral import check_eigensolver, cubic_threshold, leading_eigenpairs, shrink
from ._validation import as_float_matrix, check_count, check_positive
from .data_terms import DataTerm
from .kernels import center_kernel, rbf_kernel_vjp, squared_distances

__all__ = [
    "RegularizerResult",
    "minimize_regularized",
    "regularized_energy",
    "reduced_energy",
    "optimal_kernel_factor",
    "kernel_mismatch_residuals",
    "kernel_mismatch_jacobian",
    "pre_image_step",
]

_METHODS = ("reduced", "alternation")
_JACOBIANS = ("analytic", "finite-difference")
# Above this many non-zeros (about 240 MB as CSR) the kernel Jacobian is applied matrix-free.
_SPARSE_NNZ_LIMIT = 20_000_000


@dataclass
class RegularizerResult:
    """Outcome of :func:`minimize_regularized` (in the spirit of ``scipy.optimize.OptimizeResult``).

    Attributes
    ----------
    S : array, shape (n_samples, n_features)
        The estimate.
    C : array, shape (n_samples, n_samples)
        Kernel factor ``diag(l) U^T`` of the last stage (closed-form C-step at ``S``).
    energy_history : array, shape (n_inner,)
        Energy (1) after every inner iteration (an L-BFGS iteration, or a C-step + S-step sweep),
        at the rho of its stage; values of different stages are not comparable.
    stage_of_iteration : array of int, shape (n_inner,)
        Index of the rho stage each entry of ``energy_history`` belongs to.
    stage_energy : array, shape (n_outer,)
        Energy (1) at the end of each stage.
    rho_history : array, shape (n_outer,)
        Penalty weight of each stage.
    rank_history : array of int, shape (n_outer,)
        Rank of C at the end of each stage.
    converged : bool
        True when every stage met its tolerance before its iteration limit.
    message : str
        Why the solver stopped; names every stage that did not converge.
    n_outer : int
        Number of rho stages run.
    n_inner : int
        Total number of inner iterations over all stages.
    wall_time : float
        Seconds spent in the solver.
    method : str
        ``"reduced"`` or ``"alternation"``.
    """

    S: np.ndarray
    C: np.ndarray
    energy_history: np.ndarray
    stage_of_iteration: np.ndarray
    stage_energy: np.ndarray
    rho_history: np.ndarray
    rank_history: np.ndarray
    converged: bool
    message: str
    n_outer: int
    n_inner: int
    wall_time: float
    method: str

    # scipy.optimize.OptimizeResult-style aliases.
    @property
    def x(self) -> np.ndarray:
        """Alias of ``S``."""
        return self.S

    @property
    def success(self) -> bool:
        """Alias of ``converged``."""
        return self.converged

    @property
    def nit(self) -> int:
        """Alias of ``n_inner``."""
        return self.n_inner


# --------------------------------------------------------------------------------------------------
# Kernel, energies
# --------------------------------------------------------------------------------------------------


def _rbf(S: np.ndarray, gamma: float) -> np.ndarray:
    return np.exp(-gamma * squared_distances(S))


def _spectrum(K: np.ndarray, tau: float, rho: float, eigensolver: str = "full", expected=None):
    """(lam, U, l) in decreasing order: every eigenpair ("full") or only those above the threshold."""
    if eigensolver == "full":
        lam, U = np.linalg.eigh(K)
        lam, U = lam[::-1], U[:, ::-1]  # decreasing, as in nldr.robust_kpca
    else:
        lam, U = leading_eigenpairs(K, cubic_threshold(tau, rho), eigensolver, expected)
    return lam, U, shrink(lam, tau, rho)


class _RankHint:
    """The rank of the previous evaluation, so "auto" can skip a partial decomposition that won't pay."""

    def __init__(self):
        self.rank: int | None = None


def _reduced_value_grad(S, data_term, gamma, tau, rho, center, eigensolver="auto", hint=None):
    """E_rho(S), its gradient (n, d), and the spectrum (lam, U, l); no validation.

    ``eigensolver="full"`` is the reference: every eigenpair, ``dE/dK = U diag(rho gap) U^T`` (O(n^3)).
    Otherwise only the eigenpairs above the cubic's threshold are computed (see the maintenance note
    of :mod:`nldr._spectral`) and ``dE/dK = rho (K - C^T C)`` is formed from the kept ones, O(n^2 r)
    for rank r; the spectrum returned then holds only those eigenpairs.
    """
    K_rbf = _rbf(S, gamma)
    K = center_kernel(K_rbf) if center else K_rbf
    if eigensolver == "full":
        lam, U, l = _spectrum(K, tau, rho)
        gap = lam - l * l
        value = data_term.value(S) + 0.5 * rho * float(gap @ gap) + tau * float(l.sum())
        G = (U * (rho * gap)) @ U.T  # dE/dK = rho (K - C*^T C*), see the maintenance note
    else:
        lam, U, l = _spectrum(K, tau, rho, eigensolver, None if hint is None else hint.rank)
        if hint is not None:
            hint.rank = lam.size
        UL = U[:, l > 0] * l[l > 0]  # C*^T, shape (n, r)
        D = K - UL @ UL.T  # K - C*^T C*
        d = D.ravel()
        value = data_term.value(S) + 0.5 * rho * float(d @ d) + tau * float(l.sum())
        G = np.multiply(D, rho, out=D)
    if center:
        G = center_kernel(G)  # H G H (G symmetric)
    grad = data_term.gradient(S) + rbf_kernel_vjp(S, K_rbf, G, gamma)
    return value, grad, (lam, U, l)


def _check_common(data_term, S, gamma, tau, rho, name_S="S"):
    if not isinstance(data_term, DataTerm):
        raise ValueError(
            "data_term must implement the nldr.data_terms.DataTerm protocol "
            f"(shape, residuals, jacobian, value, gradient); got {type(data_term).__name__}"
        )
    S = as_float_matrix(S, name_S)
    if S.shape != tuple(data_term.shape):
        raise ValueError(f"{name_S} must have the data term's shape {tuple(data_term.shape)}; got {S.shape}")
    return S, check_positive(gamma, "gamma"), check_positive(tau, "tau"), check_positive(rho, "rho")


def reduced_energy(
    S,
    data_term: DataTerm,
    *,
    gamma: float,
    tau: float,
    rho: float,
    center: bool = False,
    eigensolver: str = "auto",
):
    """Reduced energy E_rho(S) = min_C E_rho(S, C) and its gradient with respect to S.

    Parameters
    ----------
    S : array, shape (n_samples, n_features)
        Samples as rows; must match ``data_term.shape``.
    data_term : DataTerm
        The data term f.
    gamma : float > 0
        RBF inverse squared width.
    tau : float > 0
        Trace-norm weight.
    rho : float > 0
        Penalty weight.
    center : bool, default=False
        Use the double-centred kernel H K H.
    eigensolver : {"auto", "partial", "full"}, default="auto"
        "full": every eigenpair of K (the reference). "partial": only those above the cubic's
        threshold, the only ones C keeps. "auto": partial for n >= 300. Same value up to rounding.

    Returns
    -------
    value : float
        ``f(S) + sum_i min_l [rho/2 (lambda_i(K(S)) - l^2)^2 + tau l]``.
    gradient : array, shape (n_samples, n_features)
        Envelope-theorem gradient (see the module's maintenance note).
    """
    S, gamma, tau, rho = _check_common(data_term, S, gamma, tau, rho)
    eigensolver = check_eigensolver(eigensolver)
    value, grad, _ = _reduced_value_grad(S, data_term, gamma, tau, rho, bool(center), eigensolver)
    return float(value), grad


def optimal_kernel_factor(
    S, *, gamma: float, tau: float, rho: float, center: bool = False, eigensolver: str = "auto"
) -> np.ndarray:
    """The C-step: closed-form minimiser C of ``tau ||C||_* + rho/2 ||K(S) - C^T C||_F^2``.

    Parameters
    ----------
    S : array, shape (n_samples, n_features)
    gamma, tau, rho : float > 0
    center : bool, default=False
    eigensolver : {"auto", "partial", "full"}, default="auto"
        See :func:`nldr.robust_kpca.closed_form_rank_penalty`.

    Returns
    -------
    C : array, shape (n_samples, n_samples)
        ``diag(l) U^T``, rows in decreasing eigenvalue order; rows beyond the rank are zero.
    """
    S = as_float_matrix(S, "S")
    gamma, tau, rho = check_positive(gamma, "gamma"), check_positive(tau, "tau"), check_positive(rho, "rho")
    K = _rbf(S, gamma)
    if center:
        K = center_kernel(K)
    _, U, l = _spectrum(K, tau, rho, check_eigensolver(eigensolver))
    return _kernel_factor(l, U)


def _kernel_factor(l: np.ndarray, U: np.ndarray) -> np.ndarray:
    """C = diag(l) U^T zero-padded to (n, n) (U may hold only the leading eigenvectors)."""
    C = np.zeros((U.shape[0], U.shape[0]))
    C[: l.size] = l[:, None] * U.T
    return C


def regularized_energy(
    S, C, data_term: DataTerm, *, gamma: float, tau: float, rho: float, center: bool = False
) -> float:
    """The full energy ``f(S) + rho/2 ||K(S) - C^T C||_F^2 + tau ||C||_*`` at a given (S, C).

    Parameters
    ----------
    S : array, shape (n_samples, n_features)
    C : array, shape (r, n_samples)
        Any kernel factor (``C^T C`` is n x n).
    data_term : DataTerm
    gamma, tau, rho : float > 0
    center : bool, default=False

    Returns
    -------
    energy : float
    """
    S, gamma, tau, rho = _check_common(data_term, S, gamma, tau, rho)
    C = as_float_matrix(C, "C")
    if C.shape[1] != S.shape[0]:
        raise ValueError(f"C must have {S.shape[0]} columns (one per sample); got shape {C.shape}")
    K = _rbf(S, gamma)
    if center:
        K = center_kernel(K)
    nuclear = float(np.linalg.svd(C, compute_uv=False).sum())
    return float(data_term.value(S) + 0.5 * rho * np.sum((K - C.T @ C) ** 2) + tau * nuclear)


# --------------------------------------------------------------------------------------------------
# Kernel-mismatch residuals and their Jacobian (for Levenberg-Marquardt)
# --------------------------------------------------------------------------------------------------


def _upper_weights(n: int, rho: float):
    iu = np.triu_indices(n)
    w = np.where(iu[0] == iu[1], 1.0, np.sqrt(2.0)) * np.sqrt(0.5 * rho)
    return iu, w


def _mismatch_residuals(S, B, gamma, rho, center, iu, w):
    K = _rbf(S, gamma)
    if center:
        K = center_kernel(K)
    return w * (K - B)[iu]


def _mismatch_jacobian_sparse(S, gamma, rho, iu, w) -> sp.csr_matrix:
    n, d = S.shape
    K = _rbf(S, gamma)
    rows_i, rows_j = iu
    off = rows_i != rows_j
    i, j = rows_i[off], rows_j[off]
    coef = w[off] * (-2.0 * gamma) * K[i, j]
    block = coef[:, None] * (S[i] - S[j])  # d r / d s_i; d r / d s_j is its negative
    data = np.concatenate([block, -block], axis=1).ravel()
    cols = np.concatenate([i[:, None] * d + np.arange(d), j[:, None] * d + np.arange(d)], axis=1).ravel()
    counts = np.where(off, 2 * d, 0)  # diagonal rows: K_ii = 1 is constant
    indptr = np.concatenate([[0], np.cumsum(counts)])
    return sp.csr_matrix((data, cols, indptr), shape=(iu[0].size, n * d))


def _mismatch_jacobian_operator(S, gamma, rho, center, iu, w) -> LinearOperator:
    n, d = S.shape
    K_rbf = _rbf(S, gamma)
    m = iu[0].size

    def matvec(v):
        V = np.asarray(v, dtype=np.float64).reshape(n, d)
        a = np.einsum("ij,ij->i", S, V)
        SV = S @ V.T
        dK = -2.0 * gamma * K_rbf * (a[:, None] + a[None, :] - SV - SV.T)
        if center:
            dK = center_kernel(dK)
        return w * dK[iu]

    def rmatvec(u):
        G = np.zeros((n, n))
        G[iu] = w * np.asarray(u, dtype=np.float64).ravel()
        G = 0.5 * (G + G.T)  # <G, K> is unchanged for symmetric K; centring needs symmetric G
        if center:
            G = center_kernel(G)
        return rbf_kernel_vjp(S, K_rbf, G, gamma).ravel()

    return LinearOperator((m, n * d), matvec=matvec, rmatvec=rmatvec, dtype=np.float64)


def kernel_mismatch_residuals(S, C, *, gamma: float, rho: float, center: bool = False) -> np.ndarray:
    """Residuals r with ``||r||^2 = rho/2 ||K(S) - C^T C||_F^2``, upper triangle only.

    Parameters
    ----------
    S : array, shape (n_samples, n_features)
    C : array, shape (r, n_samples)
    gamma, rho : float > 0
    center : bool, default=False

    Returns
    -------
    r : array, shape (n_samples (n_samples + 1) / 2,)
        ``sqrt(rho/2) w_ij (K_ij - (C^T C)_ij)`` for i <= j in ``numpy.triu_indices`` order, with
        ``w_ii = 1`` and ``w_ij = sqrt(2)`` off the diagonal.
    """
    S = as_float_matrix(S, "S")
    C = as_float_matrix(C, "C")
    if C.shape[1] != S.shape[0]:
        raise ValueError(f"C must have {S.shape[0]} columns (one per sample); got shape {C.shape}")
    gamma, rho = check_positive(gamma, "gamma"), check_positive(rho, "rho")
    iu, w = _upper_weights(S.shape[0], rho)
    return _mismatch_residuals(S, C.T @ C, gamma, rho, bool(center), iu, w)


def kernel_mismatch_jacobian(
    S, *, gamma: float, rho: float, center: bool = False, matrix_free: bool = False
) -> sp.csr_matrix | LinearOperator:
    """Analytic Jacobian of :func:`kernel_mismatch_residuals` with respect to vec(S) (C order).

    Parameters
    ----------
    S : array, shape (n, d)
    gamma, rho : float > 0
    center : bool, default=False
        With centring the Jacobian is dense, so it is always returned matrix-free.
    matrix_free : bool, default=False
        Return a ``LinearOperator`` (O(n^2) memory) instead of the sparse matrix.

    Returns
    -------
    J : scipy.sparse.csr_matrix or LinearOperator, shape (n (n + 1) / 2, n d)
        Sparse: row (i, j), i < j, has 2 d non-zeros (the blocks of s_i and s_j); diagonal rows are
        empty because K_ii = 1.
    """
    S = as_float_matrix(S, "S")
    gamma, rho = check_positive(gamma, "gamma"), check_positive(rho, "rho")
    iu, w = _upper_weights(S.shape[0], rho)
    if center or matrix_free:
        return _mismatch_jacobian_operator(S, gamma, rho, bool(center), iu, w)
    return _mismatch_jacobian_sparse(S, gamma, rho, iu, w)


def _mismatch_sparsity(n: int, d: int) -> sp.csr_matrix:
    """Structural non-zeros of the uncentred kernel Jacobian (for finite differences)."""
    iu, w = _upper_weights(n, 1.0)
    S = np.ones((n, d)) + np.arange(n)[:, None]  # distinct rows: every structural entry non-zero
    J = _mismatch_jacobian_sparse(S, 1e-6, 1.0, iu, w)
    J.data[:] = 1.0
    return J


# --------------------------------------------------------------------------------------------------
# The S-step (pre-image estimation) by Levenberg-Marquardt
# --------------------------------------------------------------------------------------------------


def _pre_image(S, B, data_term, gamma, rho, center, *, max_iter, tol, jacobian, iu, w):
    """LM on [r_f(S); kernel-mismatch residuals]; returns (S, scipy result). No validation."""
    shape = S.shape
    n, d = shape
    matrix_free = center or (n * (n - 1) * d > _SPARSE_NNZ_LIMIT)

    def fun(x):
        X = x.reshape(shape)
        return np.concatenate([data_term.residuals(X), _mismatch_residuals(X, B, gamma, rho, center, iu, w)])

    if jacobian == "finite-difference":
        if matrix_free:
            raise ValueError("jacobian='finite-difference' needs the sparse (uncentred, small) formulation")
        J_f = sp.csr_matrix(data_term.jacobian(S))
        sparsity = sp.vstack([(J_f != 0).astype(float), _mismatch_sparsity(n, d)]).tocsr()
        jac, extra = "2-point", {"jac_sparsity": sparsity}
    elif matrix_free:

        def jac(x):
            X = x.reshape(shape)
            J_k = _mismatch_jacobian_operator(X, gamma, rho, center, iu, w)
            J_f = aslinearoperator(data_term.jacobian(X))
            m_f = J_f.shape[0]
            return LinearOperator(
                (m_f + J_k.shape[0], n * d),
                matvec=lambda v: np.concatenate([J_f.matvec(v), J_k.matvec(v)]),
                rmatvec=lambda u: J_f.rmatvec(u[:m_f]) + J_k.rmatvec(u[m_f:]),
                dtype=np.float64,
            )

        extra = {}
    else:

        def jac(x):
            X = x.reshape(shape)
            J_f = sp.csr_matrix(data_term.jacobian(X))
            return sp.vstack([J_f, _mismatch_jacobian_sparse(X, gamma, rho, iu, w)], format="csr")

        extra = {}
    res = least_squares(
        fun,
        S.ravel(),
        jac=jac,
        method="trf",
        tr_solver="lsmr",
        x_scale=1.0,
        ftol=tol,
        xtol=tol,
        gtol=tol,
        max_nfev=max_iter,
        **extra,
    )
    return res.x.reshape(shape), res


def pre_image_step(
    S,
    C,
    data_term: DataTerm,
    *,
    gamma: float,
    rho: float,
    center: bool = False,
    max_iter: int = 100,
    tol: float = 1e-8,
    jacobian: str = "analytic",
) -> np.ndarray:
    """The S-step of Algorithm 1: minimise ``f(S) + rho/2 ||K(S) - C^T C||_F^2`` over S at fixed C.

    Levenberg-Marquardt (``scipy.optimize.least_squares``, trust-region reflective with LSMR) from
    ``S``; it accepts only steps that lower the objective, so the result never scores worse than ``S``.

    Parameters
    ----------
    S : array, shape (n_samples, n_features)
        Starting point; must match ``data_term.shape``.
    C : array, shape (r, n_samples)
        Fixed kernel factor.
    data_term : DataTerm
    gamma, rho : float > 0
    center : bool, default=False
    max_iter : int, default=100
        Maximum number of residual evaluations.
    tol : float, default=1e-8
        ``ftol``, ``xtol`` and ``gtol`` of ``least_squares``.
    jacobian : {"analytic", "finite-difference"}, default="analytic"
        The sparse analytic Jacobian, or sparse finite differences on the same pattern (slow; for
        checks and timing comparisons).

    Returns
    -------
    S_new : array, shape (n_samples, n_features)
    """
    S, gamma, _, rho = _check_common(data_term, S, gamma, 1.0, rho)
    C = as_float_matrix(C, "C")
    if C.shape[1] != S.shape[0]:
        raise ValueError(f"C must have {S.shape[0]} columns (one per sample); got shape {C.shape}")
    max_iter = check_count(max_iter, "max_iter")
    tol = check_positive(tol, "tol")
    if jacobian not in _JACOBIANS:
        raise ValueError(f"jacobian must be one of {_JACOBIANS}; got {jacobian!r}")
    iu, w = _upper_weights(S.shape[0], rho)
    S_new, _ = _pre_image(
        S,
        C.T @ C,
        data_term,
        gamma,
        rho,
        bool(center),
        max_iter=max_iter,
        tol=tol,
        jacobian=jacobian,
        iu=iu,
        w=w,
    )
    return S_new


# --------------------------------------------------------------------------------------------------
# The penalty method
# --------------------------------------------------------------------------------------------------


def _rho_schedule(rho0: float, growth: float, rho_max: float) -> list[float]:
    rhos, rho = [], rho0
    while rho <= rho_max * (1.0 + 1e-12):
        rhos.append(rho)
        rho *= growth
    return rhos


def _stage_reduced(S, data_term, gamma, tau, rho, center, max_inner, tol, gtol, energies, eigensolver, hint):
    shape = S.shape

    def fun(x):
        value, grad, _ = _reduced_value_grad(
            x.reshape(shape), data_term, gamma, tau, rho, center, eigensolver, hint
        )
        return value, grad.ravel()

    def record(intermediate_result):
        energies.append(float(intermediate_result.fun))

    res = minimize(
        fun,
        S.ravel(),
        jac=True,
        method="L-BFGS-B",
        callback=record,
        options={"maxiter": max_inner, "maxfun": 20 * max_inner, "ftol": tol, "gtol": gtol, "maxcor": 20},
    )
    # status 0: tolerance met; 1: iteration or evaluation limit; 2: line search could not make
    # progress, which at these tolerances means rounding noise at the minimum.
    converged = res.status != 1
    return res.x.reshape(shape), int(res.nit), converged, str(res.message)


def _stage_alternation(
    S,
    data_term,
    gamma,
    tau,
    rho,
    center,
    max_inner,
    tol,
    lm_max_iter,
    lm_tol,
    jacobian,
    energies,
    eigensolver,
):
    n = S.shape[0]
    iu, w = _upper_weights(n, rho)
    previous = np.inf
    for sweep in range(1, max_inner + 1):
        K = _rbf(S, gamma)
        if center:
            K = center_kernel(K)
        lam, U, l = _spectrum(K, tau, rho, eigensolver)  # C-step
        B = (U * l**2) @ U.T
        S, _ = _pre_image(
            S,
            B,
            data_term,
            gamma,
            rho,
            center,
            max_iter=lm_max_iter,
            tol=lm_tol,
            jacobian=jacobian,
            iu=iu,
            w=w,
        )
        K = _rbf(S, gamma)
        if center:
            K = center_kernel(K)
        energy = data_term.value(S) + 0.5 * rho * float(np.sum((K - B) ** 2)) + tau * float(l.sum())
        energies.append(energy)
        if sweep > 1 and previous - energy <= tol * max(abs(previous), abs(energy), 1.0):
            return S, sweep, True, "relative energy decrease below tol"
        previous = energy
    return S, max_inner, False, f"alternation reached max_inner={max_inner} sweeps"


def minimize_regularized(
    data_term: DataTerm,
    S0,
    *,
    gamma: float,
    tau: float,
    center: bool = False,
    method: str = "reduced",
    rho0: float = 1.0,
    rho_growth: float = 10.0,
    rho_max: float = 1e4,
    max_inner: int | None = None,
    tol: float | None = None,
    gtol: float = 1e-6,
    lm_max_iter: int = 50,
    lm_tol: float = 1e-8,
    jacobian: str = "analytic",
    eigensolver: str = "auto",
) -> RegularizerResult:
    """Minimise ``f(S) + rho/2 ||K(S) - C^T C||_F^2 + tau ||C||_*`` by the penalty method.

    For rho = rho0, rho0 * rho_growth, ... up to rho_max, minimise the energy at that rho starting
    from the previous stage's S (Algorithm 1 of Garg, Eriksson and Reid, 2016).

    Parameters
    ----------
    data_term : DataTerm
        The data term f(S) (e.g. :class:`~nldr.data_terms.MaskedLeastSquares`).
    S0 : array, shape data_term.shape = (n_samples, n_features)
        Initial estimate, samples as rows (e.g. mean imputation for matrix completion).
    gamma : float > 0
        RBF inverse squared width, ``K_ij = exp(-gamma ||s_i - s_j||^2)``.
    tau : float > 0
        Trace-norm weight (the paper uses 0.1 for matrix completion on oil flow).
    center : bool, default=False
        Double-centre the kernel (H K H). The uncentred kernel reproduces the paper's Table 2.
    method : {"reduced", "alternation"}, default="reduced"
        ``"reduced"``: L-BFGS on the reduced energy min_C E (C eliminated in closed form).
        ``"alternation"``: the literal Algorithm 1, closed-form C-step then Levenberg-Marquardt
        S-step, repeated. Block-coordinate descent on the strongly coupled S and C crawls: on oil
        flow (benchmarks/bench_regularizer.py) 100 sweeps per stage take 30-100 s and stop far from
        where the reduced method gets in about 1 s (error 37 against 21 at p = 0.25).
    rho0 : float > 0, default=1.0
        First penalty weight.
    rho_growth : float > 1, default=10.0
        Factor between consecutive penalty weights.
    rho_max : float >= rho0, default=1e4
        Last penalty weight (stages run while rho <= rho_max).
    max_inner : int, optional
        Per-stage limit of inner iterations: L-BFGS iterations (default 3000) for ``"reduced"``,
        C-step + S-step sweeps (default 100) for ``"alternation"``.
    tol : float > 0, optional
        Stage convergence: relative energy decrease per inner iteration, ``(E_k - E_{k+1}) /
        max(|E_k|, |E_{k+1}|, 1) <= tol``. Default 1e-10 for ``"reduced"`` (the L-BFGS ``ftol``) and
        1e-6 for ``"alternation"`` (whose sweeps crawl: a tighter value only spends time).
    gtol : float > 0, default=1e-6
        ``"reduced"`` only: L-BFGS also stops when the largest gradient entry is below gtol.
    lm_max_iter : int, default=50
        ``"alternation"`` only: residual evaluations per Levenberg-Marquardt S-step (it typically
        needs 5-10 on oil flow).
    lm_tol : float > 0, default=1e-8
        ``"alternation"`` only: ``ftol``, ``xtol`` and ``gtol`` of each S-step.
    jacobian : {"analytic", "finite-difference"}, default="analytic"
        ``"alternation"`` only: the Jacobian used by Levenberg-Marquardt.
    eigensolver : {"auto", "partial", "full"}, default="auto"
        The C-step's decomposition. Only eigenpairs above the cubic's threshold survive, so
        "partial" computes just those (LAPACK MRRR) and forms dE/dK = rho (K - C^T C) from them;
        "full" decomposes the whole kernel (the original implementation, kept as the reference);
        "auto" uses "partial" for n >= 300 unless the previous evaluation kept more than a quarter
        of the spectrum. The three agree to rounding (tests/test_regularizer.py).

    Returns
    -------
    RegularizerResult
        ``S``, ``C``, histories, ``converged`` and ``message`` (an iteration limit is reported,
        never silent), counts and wall time.

    Raises
    ------
    ValueError
        If ``data_term`` is not a DataTerm, ``S0`` has the wrong shape or non-finite entries, or a
        parameter is out of range (the message names it).
    """
    start = time.perf_counter()
    S, gamma, tau, rho0 = _check_common(data_term, S0, gamma, tau, rho0, name_S="S0")
    if method not in _METHODS:
        raise ValueError(f"method must be one of {_METHODS}; got {method!r}")
    if jacobian not in _JACOBIANS:
        raise ValueError(f"jacobian must be one of {_JACOBIANS}; got {jacobian!r}")
    rho_growth = check_positive(rho_growth, "rho_growth")
    if rho_growth <= 1.0:
        raise ValueError(f"rho_growth must be > 1 so that the penalty increases; got {rho_growth!r}")
    rho_max = check_positive(rho_max, "rho_max")
    if rho_max < rho0:
        raise ValueError(f"rho_max must be >= rho0 = {rho0!r}; got {rho_max!r}")
    if max_inner is None:
        max_inner = 3000 if method == "reduced" else 100
    max_inner = check_count(max_inner, "max_inner")
    if tol is None:
        tol = 1e-10 if method == "reduced" else 1e-6
    tol = check_positive(tol, "tol")
    gtol = check_positive(gtol, "gtol")
    lm_max_iter = check_count(lm_max_iter, "lm_max_iter")
    lm_tol = check_positive(lm_tol, "lm_tol")
    eigensolver = check_eigensolver(eigensolver)
    center = bool(center)
    hint = _RankHint()

    S = S.copy()
    energies: list[float] = []
    stage_index: list[int] = []
    rhos = _rho_schedule(rho0, rho_growth, rho_max)
    stage_energy, ranks, failures = [], [], []
    n_inner = 0
    C = np.zeros((S.shape[0], S.shape[0]))
    for k, rho in enumerate(rhos):
        before = len(energies)
        if method == "reduced":
            S, nit, ok, why = _stage_reduced(
                S, data_term, gamma, tau, rho, center, max_inner, tol, gtol, energies, eigensolver, hint
            )
        else:
            S, nit, ok, why = _stage_alternation(
                S,
                data_term,
                gamma,
                tau,
                rho,
                center,
                max_inner,
                tol,
                lm_max_iter,
                lm_tol,
                jacobian,
                energies,
                eigensolver,
            )
        stage_index.extend([k] * (len(energies) - before))
        n_inner += nit
        value, _, (lam, U, l) = _reduced_value_grad(S, data_term, gamma, tau, rho, center, eigensolver, hint)
        C = _kernel_factor(l, U)
        stage_energy.append(value)
        ranks.append(int(np.count_nonzero(l)))
        if not ok:
            failures.append(f"stage {k} (rho={rho:g}): {why}")

    converged = not failures
    if converged:
        message = f"all {len(rhos)} penalty stages converged (rho {rhos[0]:g} to {rhos[-1]:g})"
    else:
        message = "iteration limit reached in " + "; ".join(failures)
    return RegularizerResult(
        S=S,
        C=C,
        energy_history=np.asarray(energies, dtype=np.float64),
        stage_of_iteration=np.asarray(stage_index, dtype=np.int64),
        stage_energy=np.asarray(stage_energy, dtype=np.float64),
        rho_history=np.asarray(rhos, dtype=np.float64),
        rank_history=np.asarray(ranks, dtype=np.int64),
        converged=converged,
        message=message,
        n_outer=len(rhos),
        n_inner=n_inner,
        wall_time=time.perf_counter() - start,
        method=method,
    )
