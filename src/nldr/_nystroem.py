"""The regularizer's reduced energy on a Nystroem (landmark) approximation of the kernel (opt-in).

Inner functions of :func:`nldr.regularizer.minimize_regularized` with ``method="nystroem"``; they trust their
input.

Maintenance note (the approximation and its gradient). Fix m landmark points Z (m, d) for one penalty
stage: the current positions of m samples chosen once per solve (a seeded random subset, or the
pivots of a greedy pivoted Cholesky factorisation of the start's kernel; re-read at the start of
every stage). With K_nZ = exp(-gamma ||s_i - z_j||^2) and P = K_ZZ^{+1/2} (P P^T the
pseudo-inverse of K_ZZ, eigenvalues below 1e-10 of the largest dropped), the kernel is replaced by

    K~(S) = Phi Phi^T,   Phi = K_nZ(S) P   (n x m'),

double-centred as (H Phi)(H Phi)^T when ``center``. K~ has at most m' nonzero eigenvalues, those of
the m' x m' matrix M = Phi^T Phi = W diag(lambda) W^T, and phi(0) = 0 for the rest, so the reduced
energy is f(S) + sum_i phi(lambda_i) with the same phi as the exact solver (nldr._reduced), and by
the perturbation formula d lambda_i = 2 w_i^T Phi^T dPhi w_i,

    dE / dPhi = 2 Phi W diag(phi'(lambda)) W^T,   phi'(lambda) = rho (lambda - l*^2),

then dE/dK_nZ = (dE/dPhi) P^T and the chain rule through exp(-gamma ||s_i - z_j||^2) with Z fixed.
One evaluation costs O(n m^2 + m^3) instead of the exact solver's O(n^2 r) plus an eigensolver on
n x n: at n = 1000 and m = 200 about a fifth; at n = 3000 a fiftieth.

The residual diagonal (why it is there). K~ <= K (Loewner order), and K~ alone misses what K keeps
of a sample the landmarks do not span: a sample far from every landmark has K_nZ row ~ 0, so it adds
nothing to K~ and pays nothing, while under the exact kernel it is an isolated sample with its own
eigenvalue 1 (see the isolation guard in :mod:`nldr.regularizer`). On K~ alone, moving unobserved
coordinates away from the landmarks therefore lowers the energy, and they escape (1000 oil rows,
100 landmarks, gamma 0.29: SSE 1e8 against the exact solver's 142). The energy therefore also
charges the residual K - K~ (PSD, unit diagonal minus K~'s) as if it were diagonal, the
"fully independent" correction of sparse Gaussian processes: with d_i = 1 - K~_ii in [0, 1]
(uncentred, also when ``center``), each d_i is one more eigenvalue, + sum_i phi(d_i), with
dd_i / dK_nZ[i] = -2 (K_nZ P P^T)_i. Exact in two limits: d = 0 when the sample is a landmark (or
spanned by them), and d_i = 1 with phi(1), the exact energy's, when sample i is isolated from the
others (tests/test_nystroem.py). Between them it is an approximation, so the minimiser is not the
exact one; benchmarks/bench_scale.py states its SSE against the exact solve. The C it reports is
diag(l) V^T with V = Phi W_k diag(lambda_k)^(-1/2), the eigenvectors of K~ (the residual diagonal
enters the energy and gradient only).
"""

from __future__ import annotations

import numpy as np

from ._spectral import shrink
from .kernels import squared_distances

__all__ = ["landmark_indices", "pivoted_landmarks", "landmark_map", "nystroem_value_grad", "nystroem_factor"]


def landmark_indices(n: int, m: int, seed: int) -> np.ndarray:
    """m distinct sample indices out of n (sorted), drawn from ``numpy.random.default_rng(seed)``."""
    return np.sort(np.random.default_rng(seed).choice(n, size=min(m, n), replace=False))


def pivoted_landmarks(S: np.ndarray, m: int, gamma: float) -> np.ndarray:
    """m sample indices (sorted; fewer when the kernel's rank is reached) chosen by greedy pivoted
    Cholesky of the RBF kernel ``exp(-gamma ||s_i - s_j||^2)`` of S (n, d).

    The first pivot is the sample nearest the mean of S; each next one is the sample the pivots so far
    span worst, the largest diagonal of the residual kernel K - K_nZ K_ZZ^{-1} K_Zn (the Nystroem
    kernel's error on the diagonal; the sample farthest, in feature space, from the landmarks' span).
    Each pivot lowers the trace of that residual by the most any one sample can (a greedy minimiser of
    the Nystroem error's trace), so isolated samples become landmarks and the landmarks cover the data
    at the kernel's width. Deterministic: the same set for the samples in any order (but for exact
    ties, e.g. duplicated samples). O(n m (m + d)) flops, no n x n matrix.
    """
    n = S.shape[0]
    residual = np.ones(n)  # the RBF kernel's diagonal
    L = np.zeros((min(m, n), n))  # the rows of the partial Cholesky factor
    chosen: list[int] = []
    pivot = int(np.argmin(np.sum((S - S.mean(axis=0)) ** 2, axis=1)))
    for k in range(L.shape[0]):
        if k > 0:
            pivot = int(np.argmax(residual))
        if residual[pivot] <= 1e-12:  # the pivots span the kernel to rounding
            break
        column = np.exp(-gamma * np.sum((S - S[pivot]) ** 2, axis=1))
        L[k] = (column - L[:k, pivot] @ L[:k]) / np.sqrt(residual[pivot])
        residual = np.maximum(residual - L[k] ** 2, 0.0)
        residual[pivot] = 0.0
        chosen.append(pivot)
    return np.sort(np.array(chosen, dtype=int))


def landmark_map(Z: np.ndarray, gamma: float) -> np.ndarray:
    """P (m, m') with P P^T = K_ZZ^+ (pseudo-inverse; eigenvalues below 1e-10 of the largest dropped)."""
    w, V = np.linalg.eigh(np.exp(-gamma * squared_distances(Z)))
    keep = w > 1e-10 * w[-1]
    return V[:, keep] / np.sqrt(w[keep])


def _features(S, Z, P, gamma, center):
    """K_nZ (n, m), the Gram matrix Phi^T Phi (m', m') of the (centred) features, and K_nZ's column mean."""
    K_nZ = np.exp(-gamma * squared_distances(S, Z))
    G = K_nZ.T @ K_nZ  # (m, m); Phi^T Phi = P^T G P, without forming Phi
    mu = None
    if center:
        mu = K_nZ.mean(axis=0)
        G -= K_nZ.shape[0] * np.outer(mu, mu)  # K_nZ^T H K_nZ
    return K_nZ, P.T @ G @ P, mu


def _eig(M, tau, rho):
    lam, W = np.linalg.eigh(M)
    lam, W = lam[::-1], W[:, ::-1]
    return lam, W, shrink(lam, tau, rho)


def _residual_diagonal(K_nZ, P):
    """``(d, T)``: d_i = 1 - K~_ii >= 0 (n,), the kernel's diagonal that the landmarks do not span
    (uncentred; clipped at 0 against rounding), and T = K_nZ P P^T (n, m), with dd_i / dK_nZ[i] = -2 T_i."""
    T = K_nZ @ (P @ P.T)
    return np.maximum(1.0 - np.einsum("ij,ij->i", T, K_nZ), 0.0), T


def nystroem_value_grad(S, Z, P, data_term, gamma, tau, rho, center):
    """Reduced energy on the Nystroem kernel and its gradient (n, d) (see the maintenance note).

    With Phi = H^c K_nZ P (H^c = H if centred, else I) and M = Phi^T Phi = W diag(lambda) W^T,
    dE/dK_nZ = H^c 2 Phi W diag(phi') W^T P^T = 2 H^c K_nZ Q with Q = (PW) diag(phi') (PW)^T (m, m),
    plus the residual diagonal's -2 diag(phi'(d)) K_nZ P P^T.
    """
    K_nZ, M, mu = _features(S, Z, P, gamma, center)
    lam, W, l = _eig(M, tau, rho)
    d, T = _residual_diagonal(K_nZ, P)
    ld = shrink(d, tau, rho)
    gap, gap_d = lam - l * l, d - ld * ld
    penalty = 0.5 * rho * float(gap @ gap + gap_d @ gap_d) + tau * float(l.sum() + ld.sum())
    value = data_term.value(S) + penalty
    PW = P @ W
    Q = (PW * (2.0 * rho * gap)) @ PW.T
    A = K_nZ @ Q  # dE/dK_nZ (uncentred)
    if center:
        A -= mu @ Q  # H K_nZ Q = K_nZ Q - 1 (mu^T Q)  (H H = H)
    A -= (2.0 * rho * gap_d)[:, None] * T  # the residual diagonal's phi'(d) dd/dK_nZ
    B = A * K_nZ  # dE/dK_nZ times K_nZ, elementwise
    vjp = (-2.0 * gamma) * (B.sum(axis=1)[:, None] * S - B @ Z)
    return value, data_term.gradient(S) + vjp


def nystroem_factor(S, Z, P, gamma, tau, rho, center):
    """``(l, V)``: the kept values l > 0 and eigenvectors V (n, k) of the Nystroem kernel."""
    K_nZ, M, _ = _features(S, Z, P, gamma, center)
    lam, W, l = _eig(M, tau, rho)
    k = l > 0
    Phi = K_nZ @ P
    if center:
        Phi -= Phi.mean(axis=0)
    return l[k], (Phi @ W[:, k]) / np.sqrt(lam[k])
