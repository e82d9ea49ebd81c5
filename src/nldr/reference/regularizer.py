"""Algorithm 1 as printed: alternate a closed-form C-step and a Levenberg-Marquardt S-step.

Reference implementation (see :mod:`nldr.reference`). The production solver,
:func:`nldr.regularizer.minimize_regularized`, minimises the same energy

    E_rho(S, C) = f(S) + rho/2 ||K(S) - C^T C||_F^2 + tau ||C||_*                          (1)

with C eliminated in closed form. Here, for each penalty weight rho of the schedule, the two steps
of the paper's Algorithm 1 are repeated until the energy stops decreasing:

- C-step: the closed form of Theorem 3.1 (:mod:`nldr._spectral`);
- S-step ("pre-image estimation"): Levenberg-Marquardt (``scipy.optimize.least_squares``,
  trust-region reflective with LSMR) on the stacked residuals ``[r_f(S); sqrt(rho/2) w o vech(K(S) -
  C^T C)]`` with the analytic Jacobian below.

Each step lowers (1), but block-coordinate descent on the strongly coupled S and C crawls: it stops
far from the minimum the reduced solver reaches (docs/REPRODUCTION.md#table-2-solver).

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

import numpy as np
import scipy.sparse as sp
from scipy.optimize import least_squares
from scipy.sparse.linalg import LinearOperator, aslinearoperator

from .._penalty import RegularizerResult, penalty_method
from .._reduced import optimal_kernel_factor
from .._schedule import penalty_schedule
from .._spectral import check_eigensolver, spectrum
from .._validation import as_float_matrix, check_count, check_positive
from ..data_terms import DataTerm, check_start
from ..kernels import center_kernel, rbf_kernel, rbf_kernel_vjp
from ..regularizer import reduced_energy

__all__ = [
    "minimize_regularized_alternation",
    "pre_image_step",
    "kernel_mismatch_residuals",
    "kernel_mismatch_jacobian",
    "finite_difference_pre_image_step",
]

# Above this many non-zeros (about 240 MB as CSR) the kernel Jacobian is applied matrix-free.
_SPARSE_NNZ_LIMIT = 20_000_000


# --------------------------------------------------------------------------------------------------
# Kernel-mismatch residuals and their Jacobian (for Levenberg-Marquardt)
# --------------------------------------------------------------------------------------------------


def _upper_weights(n: int, rho: float):
    iu = np.triu_indices(n)
    w = np.where(iu[0] == iu[1], 1.0, np.sqrt(2.0)) * np.sqrt(0.5 * rho)
    return iu, w


def _mismatch_residuals(S, B, gamma, rho, center, iu, w):
    K = rbf_kernel(S, gamma)
    if center:
        K = center_kernel(K)
    return w * (K - B)[iu]


def _mismatch_jacobian_sparse(S, gamma, rho, iu, w) -> sp.csr_matrix:
    n, d = S.shape
    K = rbf_kernel(S, gamma)
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
    K_rbf = rbf_kernel(S, gamma)
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


# --------------------------------------------------------------------------------------------------
# The S-step (pre-image estimation) by Levenberg-Marquardt
# --------------------------------------------------------------------------------------------------


def _lm_options(tol: float, max_iter: int) -> dict:
    """The S-step's least-squares settings (trust region, LSMR on the sparse Jacobian), shared by the
    analytic and the finite-difference pre-image step so that they differ only in the Jacobian."""
    return dict(method="trf", tr_solver="lsmr", x_scale=1.0, ftol=tol, xtol=tol, gtol=tol, max_nfev=max_iter)


def _pre_image(S, B, data_term, gamma, rho, center, *, max_iter, tol, iu, w):
    """LM on [r_f(S); kernel-mismatch residuals]; returns (S, scipy result). No validation."""
    shape = S.shape
    n, d = shape
    matrix_free = center or (n * (n - 1) * d > _SPARSE_NNZ_LIMIT)

    def fun(x):
        X = x.reshape(shape)
        return np.concatenate([data_term.residuals(X), _mismatch_residuals(X, B, gamma, rho, center, iu, w)])

    if matrix_free:

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

    else:

        def jac(x):
            X = x.reshape(shape)
            J_f = sp.csr_matrix(data_term.jacobian(X))
            return sp.vstack([J_f, _mismatch_jacobian_sparse(X, gamma, rho, iu, w)], format="csr")

    res = least_squares(
        fun,
        S.ravel(),
        jac=jac,
        **_lm_options(tol, max_iter),
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

    Returns
    -------
    S_new : array, shape (n_samples, n_features)
    """
    S = check_start(data_term, S, "S")
    gamma, rho = check_positive(gamma, "gamma"), check_positive(rho, "rho")
    C = as_float_matrix(C, "C")
    if C.shape[1] != S.shape[0]:
        raise ValueError(f"C must have {S.shape[0]} columns (one per sample); got shape {C.shape}")
    max_iter = check_count(max_iter, "max_iter")
    tol = check_positive(tol, "tol")
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
        iu=iu,
        w=w,
    )
    return S_new


# --------------------------------------------------------------------------------------------------
# The alternation
# --------------------------------------------------------------------------------------------------


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
    energies,
    eigensolver,
):
    n = S.shape[0]
    iu, w = _upper_weights(n, rho)
    previous = np.inf
    for sweep in range(1, max_inner + 1):
        K = rbf_kernel(S, gamma)
        if center:
            K = center_kernel(K)
        lam, U, l = spectrum(K, tau, rho, eigensolver)  # C-step
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
            iu=iu,
            w=w,
        )
        K = rbf_kernel(S, gamma)
        if center:
            K = center_kernel(K)
        energy = data_term.value(S) + 0.5 * rho * float(np.sum((K - B) ** 2)) + tau * float(l.sum())
        energies.append(energy)
        if sweep > 1 and previous - energy <= tol * max(abs(previous), abs(energy), 1.0):
            return S, sweep, True, "relative energy decrease below tol"
        previous = energy
    return S, max_inner, False, f"alternation reached max_inner={max_inner} sweeps"


def minimize_regularized_alternation(
    data_term: DataTerm,
    S0,
    *,
    gamma: float,
    tau: float,
    center: bool = False,
    rho0: float = 1.0,
    rho_growth: float = 10.0,
    rho_max: float = 1e4,
    max_inner: int = 100,
    tol: float = 1e-6,
    lm_max_iter: int = 50,
    lm_tol: float = 1e-8,
    eigensolver: str = "auto",
) -> RegularizerResult:
    """The paper's Algorithm 1 as printed: for each rho, alternate the C-step and the LM S-step.

    Minimises the same energy (1) as :func:`nldr.regularizer.minimize_regularized`, with the same
    penalty schedule, but by block-coordinate descent (see the module docstring); use that solver
    for results, this one to check it or to study the printed algorithm.

    Parameters
    ----------
    data_term : DataTerm
        The data term f(S) (e.g. :class:`~nldr.data_terms.MaskedLeastSquares`).
    S0 : array, shape data_term.shape = (n_samples, n_features)
        Initial estimate, samples as rows.
    gamma, tau : float > 0
        RBF inverse squared width and trace-norm weight.
    center : bool, default=False
        Double-centre the kernel (H K H).
    rho0, rho_growth, rho_max : float, defaults 1.0, 10.0, 1e4
        The penalty schedule (:func:`nldr._schedule.penalty_schedule`).
    max_inner : int, default=100
        Per-stage limit of sweeps (one C-step and one S-step each).
    tol : float > 0, default=1e-6
        A stage converges when a sweep lowers the energy by at most ``tol`` relative,
        ``(E_k - E_{k+1}) <= tol max(|E_k|, |E_{k+1}|, 1)``.
    lm_max_iter : int, default=50
        Residual evaluations per Levenberg-Marquardt S-step.
    lm_tol : float > 0, default=1e-8
        ``ftol``, ``xtol`` and ``gtol`` of each S-step.
    eigensolver : {"auto", "partial", "full"}, default="auto"
        The C-step's decomposition (as in :func:`~nldr.regularizer.minimize_regularized`).

    Returns
    -------
    RegularizerResult
        ``x`` (the estimate S, shape (n_samples, n_features)), ``fun`` (energy (1) at the last
        stage's rho and the closed-form C of ``x``), ``nit`` (sweeps over all stages), ``status``
        :data:`~nldr.result.CONVERGED` when every stage met ``tol``, else
        :data:`~nldr.result.MAX_ITER`; ``energy_history`` holds the energy after every sweep (at the
        C of that sweep's C-step).

    Raises
    ------
    ValueError
        If ``data_term`` is not a DataTerm, ``S0`` has the wrong shape or non-finite entries, or a
        parameter is out of range (the message names it).
    """
    start = time.perf_counter()
    S = check_start(data_term, S0, "S0").copy()
    gamma, tau = check_positive(gamma, "gamma"), check_positive(tau, "tau")
    rhos = penalty_schedule(rho0, rho_growth, rho_max)
    max_inner = check_count(max_inner, "max_inner")
    tol = check_positive(tol, "tol")
    lm_max_iter = check_count(lm_max_iter, "lm_max_iter")
    lm_tol = check_positive(lm_tol, "lm_tol")
    eigensolver = check_eigensolver(eigensolver)
    center = bool(center)

    def stage(S, rho, energies):
        return _stage_alternation(
            S, data_term, gamma, tau, rho, center, max_inner, tol, lm_max_iter, lm_tol, energies, eigensolver
        )

    def stage_end(S, rho):
        kw = dict(gamma=gamma, tau=tau, rho=rho, center=center, eigensolver=eigensolver)
        C = optimal_kernel_factor(S, **kw)
        value, _ = reduced_energy(S, data_term, **kw)
        return value, C, int(np.count_nonzero(np.any(C, axis=1)))

    return penalty_method(S, rhos, stage, stage_end, start=start)


def finite_difference_pre_image_step(S, C, data_term, *, gamma, rho, max_iter=100, tol=1e-8):
    """The S-step of :func:`pre_image_step` with a finite-difference Jacobian on the analytic pattern.

    The same least-squares problem and solver settings, but scipy's sparse 2-point differences
    instead of the analytic Jacobian: a check of the latter on whole LM solves.
    """
    shape = S.shape

    def fun(x):
        X = x.reshape(shape)
        return np.concatenate([data_term.residuals(X), kernel_mismatch_residuals(X, C, gamma=gamma, rho=rho)])

    J_f = sp.csr_matrix(data_term.jacobian(S))
    J_k = kernel_mismatch_jacobian(S, gamma=gamma, rho=rho).copy()
    J_k.data[:] = 1.0  # the structural non-zeros (2 d per off-diagonal pair)
    sparsity = sp.vstack([(J_f != 0).astype(float), J_k]).tocsr()
    res = least_squares(
        fun,
        S.ravel(),
        jac="2-point",
        jac_sparsity=sparsity,
        **_lm_options(tol, max_iter),
    )
    return res.x.reshape(shape)
