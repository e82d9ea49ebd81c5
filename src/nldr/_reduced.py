"""The reduced energy of the regularizer and one L-BFGS stage on it (inner functions of
:mod:`nldr.regularizer`; they trust their input).

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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from ._spectral import PARTIAL_MIN_N, check_eigensolver, spectrum
from ._validation import as_float_matrix, check_positive
from .kernels import center_kernel, rbf_kernel_vjp, squared_distances

__all__ = [
    "KRYLOV_AUTO_FRACTION",
    "RankHint",
    "rbf",
    "reduced_value_grad",
    "kernel_factor",
    "optimal_kernel_factor",
    "lbfgs_stage",
    "lbfgs_minimize",
    "PLATEAU_WINDOW",
    "StageInfo",
]


def rbf(S: np.ndarray, gamma: float) -> np.ndarray:
    return np.exp(-gamma * squared_distances(S))


#: "auto" switches to Lanczos ("krylov") once n >= PARTIAL_MIN_N and the previous evaluation kept at
#: most this fraction of the spectrum (measured: docs/PERFORMANCE.md#lanczos).
KRYLOV_AUTO_FRACTION = 0.16


class RankHint:
    """The rank of the previous evaluation, so "auto" can skip a partial decomposition that won't pay."""

    def __init__(self):
        self.rank: int | None = None

    def solver(self, eigensolver: str, n: int) -> str:
        """The eigensolver for this evaluation: "auto" becomes "krylov" when the last rank was small."""
        if eigensolver == "auto" and n >= PARTIAL_MIN_N and self.rank is not None:
            if self.rank <= KRYLOV_AUTO_FRACTION * n:
                return "krylov"
        return eigensolver


def reduced_value_grad(S, data_term, gamma, tau, rho, center, eigensolver="auto", hint=None):
    """E_rho(S), its gradient (n, d), and the spectrum (lam, U, l); no validation.

    ``eigensolver="full"`` is the reference: every eigenpair, ``dE/dK = U diag(rho gap) U^T`` (O(n^3)).
    Otherwise only the eigenpairs above the cubic's threshold are computed (see the maintenance note
    of :mod:`nldr._spectral`) and ``dE/dK = rho (K - C^T C)`` is formed from the kept ones, O(n^2 r)
    for rank r; the spectrum returned then holds only those eigenpairs.
    """
    K_rbf = rbf(S, gamma)
    K = center_kernel(K_rbf) if center else K_rbf
    if eigensolver == "full":
        lam, U, l = spectrum(K, tau, rho)
        gap = lam - l * l
        value = data_term.value(S) + 0.5 * rho * float(gap @ gap) + tau * float(l.sum())
        G = (U * (rho * gap)) @ U.T  # dE/dK = rho (K - C*^T C*), see the maintenance note
    else:
        if hint is not None:
            eigensolver = hint.solver(eigensolver, K.shape[0])
        lam, U, l = spectrum(K, tau, rho, eigensolver, None if hint is None else hint.rank)
        if hint is not None:
            hint.rank = lam.size
        UL = U[:, l > 0] * l[l > 0]  # C*^T, shape (n, r)
        D = K - UL @ UL.T  # K - C*^T C*
        d = D.ravel()
        value = data_term.value(S) + 0.5 * rho * float(d @ d) + tau * float(l.sum())
        G = np.multiply(D, rho, out=D)
        if not center:
            # G is exactly symmetric (K and UL UL^T are: numpy forms A A^T by a symmetric rank-k
            # update), so rbf_kernel_vjp's (G + G^T) o K is 2 G o K, here formed in place: same bits.
            M = np.multiply(G, K_rbf, out=G)
            vjp = (-4.0 * gamma) * (M.sum(axis=1)[:, None] * S - M @ S)
            return value, data_term.gradient(S) + vjp, (lam, U, l)
    if center:
        G = center_kernel(G)  # H G H (G symmetric)
    grad = data_term.gradient(S) + rbf_kernel_vjp(S, K_rbf, G, gamma)
    return value, grad, (lam, U, l)


def kernel_factor(l: np.ndarray, U: np.ndarray) -> np.ndarray:
    """C = diag(l) U^T zero-padded to (n, n) (U may hold only the leading eigenvectors)."""
    C = np.zeros((U.shape[0], U.shape[0]))
    C[: l.size] = l[:, None] * U.T
    return C


def optimal_kernel_factor(
    S, *, gamma: float, tau: float, rho: float, center: bool = False, eigensolver: str = "auto"
) -> np.ndarray:
    """The C-step: closed-form minimiser C of ``tau ||C||_* + rho/2 ||K(S) - C^T C||_F^2``.

    The literal C-step of :mod:`nldr.reference` and the tests' check of the solvers' C (users get
    C as ``RegularizerResult.C``, or the closed form as :class:`nldr.robust_kpca.RobustKernelPCA`).

    Parameters
    ----------
    S : array, shape (n_samples, n_features)
    gamma, tau, rho : float > 0
    center : bool, default=False
    eigensolver : {"auto", "partial", "krylov", "full"}, default="auto"
        See :func:`nldr.robust_kpca.closed_form_rank_penalty`.

    Returns
    -------
    C : array, shape (n_samples, n_samples)
        ``diag(l) U^T``, rows in decreasing eigenvalue order; rows beyond the rank are zero.
    """
    S = as_float_matrix(S, "S")
    gamma, tau, rho = check_positive(gamma, "gamma"), check_positive(tau, "tau"), check_positive(rho, "rho")
    if not isinstance(center, bool | np.bool_):
        raise ValueError(f"center must be True or False (double-centre the kernel or not); got {center!r}")
    K = rbf(S, gamma)
    if center:
        K = center_kernel(K)
    _, U, l = spectrum(K, tau, rho, check_eigensolver(eigensolver))
    return kernel_factor(l, U)


def lbfgs_stage(
    S, data_term, gamma, tau, rho, center, max_inner, tol, gtol, energies, eigensolver, hint, variables=None,
    plateau=None, scale=1.0,
):  # fmt: skip
    """One penalty stage: L-BFGS on the exact reduced energy from S (see :func:`lbfgs_minimize`).

    With ``variables`` (a linear change of variables S = A(Y), see ``minimize_regularized``) L-BFGS
    runs on Y, with the gradient A^T(dE/dS); the returned S is A(Y). ``plateau``, ``scale``: see
    :func:`lbfgs_minimize`.
    """
    if variables is not None:

        def value_grad_y(Y):
            value, grad, _ = reduced_value_grad(
                variables.to_samples(Y), data_term, gamma, tau, rho, center, eigensolver, hint
            )
            return value, variables.gradient_to_variables(grad)

        Y0 = variables.to_variables(S)
        Y, nit, ok, why = lbfgs_minimize(value_grad_y, Y0, max_inner, tol, gtol, energies, plateau, scale)
        return variables.to_samples(Y), nit, ok, why

    def value_grad(S):
        value, grad, _ = reduced_value_grad(S, data_term, gamma, tau, rho, center, eigensolver, hint)
        return value, grad

    return lbfgs_minimize(value_grad, S, max_inner, tol, gtol, energies, plateau, scale)


#: Iterations over which ``lbfgs_minimize(plateau=...)`` averages the energy's decrease.
PLATEAU_WINDOW = 10


def lbfgs_minimize(value_grad, S, max_inner, tol, gtol, energies, plateau=None, scale=1.0):
    """Minimise ``value_grad(S) -> (value, gradient of S's shape)`` by L-BFGS from S.

    Appends the energy after every iteration to ``energies``; returns ``(S, nit, converged, message)``.
    ``scale`` (> 0) is the unit of S: L-BFGS runs on x = S / scale and F(x) = E(scale x) / scale^2, so
    its tests read ``(E_k - E_{k+1}) / max(|E_k|, |E_{k+1}|, scale^2) <= tol`` and
    ``max |dE/dS| <= gtol * scale``, and its first step has length ``scale`` (see the maintenance note
    on scale in :mod:`nldr.regularizer`); with scale = 1 every number is the unscaled run's.
    ``plateau`` (optional, > 0): also stop once the energy fell by at most ``plateau`` (relative,
    ``max(|E|, scale^2)``) per iteration on average over the last :data:`PLATEAU_WINDOW` iterations,
    i.e. ``E_{k-w} - E_k <= w * plateau * max(|E_k|, scale^2)`` with E_0 the energy at the start S.
    """
    shape = S.shape
    history: list[float] = []  # F_0 (at S), then F after every iteration (F = E / scale^2)
    stopped = []  # set when the plateau test ended the run
    w = PLATEAU_WINDOW
    unit = scale * scale  # the energy unit

    def fun(x):
        value, grad = value_grad(x.reshape(shape) * scale)
        value, grad = value / unit, grad * (scale / unit)
        if not history:
            history.append(float(value))  # L-BFGS-B evaluates the start first
        return value, grad.ravel()

    def record(intermediate_result):
        energies.append(float(intermediate_result.fun) * unit)
        history.append(float(intermediate_result.fun))
        if plateau is not None and len(history) > w:
            if history[-1 - w] - history[-1] <= w * plateau * max(abs(history[-1]), 1.0):
                stopped.append(True)
                raise StopIteration  # scipy ends the run here and returns this iterate

    res = minimize(
        fun,
        S.ravel() / scale,
        jac=True,
        method="L-BFGS-B",
        callback=record,
        options={"maxiter": max_inner, "maxfun": 20 * max_inner, "ftol": tol, "gtol": gtol, "maxcor": 20},
    )
    # status 0: tolerance met; 1: iteration or evaluation limit; 2: line search could not make
    # progress, which at these tolerances means rounding noise at the minimum.
    converged = res.status != 1 or bool(stopped)
    message = str(res.message)
    if stopped:
        message = f"energy plateau: relative decrease <= {plateau:g} per iteration over the last {w}"
    return res.x.reshape(shape) * scale, int(res.nit), converged, message


@dataclass(frozen=True)
class StageInfo:
    """What ``minimize_regularized(callback=...)`` receives after every penalty stage.

    Attributes
    ----------
    stage : int
        Index of the stage (0 for rho0).
    n_stages : int
        Number of stages in the schedule.
    rho : float
        The stage's penalty weight.
    nit : int
        Inner iterations of this stage.
    energy : float
        Energy (1) at the end of the stage, at its rho.
    rank : int
        Rank of C at the end of the stage.
    converged : bool
        Whether the stage met its tolerance.
    seconds : float
        Wall-clock seconds the stage took.
    x : array, shape (n_samples, n_features)
        A copy of the estimate S at the end of the stage.
    """

    stage: int
    n_stages: int
    rho: float
    nit: int
    energy: float
    rank: int
    converged: bool
    seconds: float
    x: np.ndarray

    def __str__(self) -> str:
        return (
            f"stage {self.stage + 1}/{self.n_stages}: rho {self.rho:g}, {self.nit} iterations, "
            f"energy {self.energy:.8g}, rank {self.rank}, {self.seconds:.2f} s"
            + ("" if self.converged else " (iteration limit)")
        )
