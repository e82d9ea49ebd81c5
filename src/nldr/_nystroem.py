"""The regularizer's reduced energy on a Nystroem (landmark) approximation of the kernel (opt-in).

Inner functions of :func:`nldr.regularizer.minimize_regularized` with ``landmarks=m``; they trust their
input.

Maintenance note (the approximation and its gradient). Fix m landmark points Z (m, d) for one penalty
stage: the current positions of m samples chosen once per solve (a seeded random subset, re-read at
the start of every stage). With K_nZ = exp(-gamma ||s_i - z_j||^2) and P = K_ZZ^{+1/2} (P P^T the
pseudo-inverse of K_ZZ, eigenvalues below 1e-10 of the largest dropped), the kernel is replaced by

    K~(S) = Phi Phi^T,   Phi = K_nZ(S) P   (n x m'),

double-centred as (H Phi)(H Phi)^T when ``center``. K~ has at most m' nonzero eigenvalues, those of
the m' x m' matrix M = Phi^T Phi = W diag(lambda) W^T, and phi(0) = 0 for the rest, so the reduced
energy is f(S) + sum_i phi(lambda_i) with the same phi as the exact solver (nldr._reduced), and by
the perturbation formula d lambda_i = 2 w_i^T Phi^T dPhi w_i,

    dE / dPhi = 2 Phi W diag(phi'(lambda)) W^T,   phi'(lambda) = rho (lambda - l*^2),

then dE/dK_nZ = (dE/dPhi) P^T and the chain rule through exp(-gamma ||s_i - z_j||^2) with Z fixed.
One evaluation costs O(n m^2 + m^3) instead of the exact solver's O(n^2 r) plus an eigensolver on
n x n: at n = 1000 and m = 200 about a fifth; at n = 3000 a fiftieth. What it gives up: K~ <= K
(Loewner order), and the part of K that the landmarks do not span is neither penalised nor kept, so
the minimiser is not the exact one; benchmarks/bench_scale.py states its SSE against the exact solve.
The C it reports is diag(l) V^T with V = Phi W_k diag(lambda_k)^(-1/2), the eigenvectors of K~.
"""

from __future__ import annotations

import numpy as np

from ._spectral import shrink
from .kernels import squared_distances

__all__ = ["landmark_indices", "landmark_map", "nystroem_value_grad", "nystroem_factor"]


def landmark_indices(n: int, m: int, seed: int) -> np.ndarray:
    """m distinct sample indices out of n (sorted), drawn from ``numpy.random.default_rng(seed)``."""
    return np.sort(np.random.default_rng(seed).choice(n, size=min(m, n), replace=False))


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


def nystroem_value_grad(S, Z, P, data_term, gamma, tau, rho, center):
    """Reduced energy on the Nystroem kernel and its gradient (n, d) (see the maintenance note).

    With Phi = H^c K_nZ P (H^c = H if centred, else I) and M = Phi^T Phi = W diag(lambda) W^T,
    dE/dK_nZ = H^c 2 Phi W diag(phi') W^T P^T = 2 H^c K_nZ Q with Q = (P W) diag(phi') (P W)^T (m, m).
    """
    K_nZ, M, mu = _features(S, Z, P, gamma, center)
    lam, W, l = _eig(M, tau, rho)
    gap = lam - l * l
    value = data_term.value(S) + 0.5 * rho * float(gap @ gap) + tau * float(l.sum())
    PW = P @ W
    Q = (PW * (2.0 * rho * gap)) @ PW.T
    A = K_nZ @ Q  # dE/dK_nZ (uncentred)
    if center:
        A -= mu @ Q  # H K_nZ Q = K_nZ Q - 1 (mu^T Q)  (H H = H)
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
