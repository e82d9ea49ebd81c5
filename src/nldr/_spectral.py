"""Spectral inner functions of the closed form (Theorem 3.1), shared by the robust KPCA and the regularizer.

These trust their input (validate at the edge, trust inside): the validated public versions are
:func:`nldr.robust_kpca.rank_penalty_threshold`, :func:`nldr.robust_kpca.shrink_eigenvalues` and
:func:`nldr.robust_kpca.closed_form_rank_penalty`.

Maintenance note (the cubic and its threshold). Write K = U diag(lambda) U^T. The minimiser of
tau ||C||_* + rho/2 ||K - C^T C||_F^2 is C = diag(l) U^T, where each l_i >= 0 solves the scalar problem

    min_{l >= 0}  phi(l) = rho/2 (lambda_i - l^2)^2 + tau l .

phi'(l) = 0 is the depressed cubic l^3 - lambda l + b = 0 with b = tau / (2 rho). With b > 0 it has
positive roots only when lambda >= 3 (b/2)^(2/3); the largest is the local minimum, found in closed
form by the trigonometric formula l = 2 sqrt(lambda/3) cos(arccos(-(3 sqrt(3) b) / (2 lambda^1.5)) / 3).
It beats l = 0 exactly when phi(l) < phi(0) = rho/2 lambda^2; substituting l^3 = lambda l - b gives
phi(l) - phi(0) = rho/2 * l (3b - lambda l), so the root wins iff lambda l > 3b, which happens iff

    lambda > lambda_star = 3 (b^2 / 2)^(1/3)       (= 2^(1/3) times the existence threshold).

So every eigenvalue at or below lambda_star (and every negative eigenvalue) maps to zero, and the
threshold is known before any decomposition. Only tau / rho matters for the minimiser; rho scales the
energy. The paper's Algorithm 2 solves the cubic per eigenvalue in a loop; here it is one vectorised
expression over the whole spectrum.

Maintenance note (partial decompositions). Because the threshold is known first, only the eigenpairs
with lambda > lambda_star are needed: everything else maps to l = 0 and drops out of C. LAPACK's
MRRR driver (``syevr`` through ``scipy.linalg.eigh(subset_by_value=...)``) computes just those. It
still reduces K to tridiagonal form (the O(n^3) part every method shares) but skips the eigenvectors
that are not wanted. It pays only when few eigenvalues pass the threshold and n is large: below
:data:`PARTIAL_MIN_N` the full ``numpy.linalg.eigh`` is faster, and when more than
:data:`PARTIAL_MAX_FRACTION` of the spectrum passes, MRRR's per-eigenvector work exceeds the full
divide-and-conquer (measured: docs/PERFORMANCE.md#closed-form). :func:`leading_eigenpairs`
chooses, and falls back to the full decomposition if the partial one fails.

Maintenance note (Krylov decompositions). MRRR still pays for the O(n^3) tridiagonal reduction
however few eigenpairs pass. When the number k that passes is a small fraction of n, implicitly
restarted Lanczos (ARPACK through ``scipy.sparse.linalg.eigsh``) costs O(n^2) per matrix-vector product
instead, and is the faster at n = 1000 (measured: docs/PERFORMANCE.md#lanczos). It needs the count in
advance, so
:func:`krylov_eigenpairs` asks for ``expected`` plus a margin and, until the smallest eigenvalue it
returns lies at or below the threshold (so that every eigenvalue above it was found), doubles the
request; past :data:`KRYLOV_MAX_FRACTION` of n it hands over to MRRR. ARPACK runs to machine precision
(``tol=0``: residuals ||K u - lam u|| <= eps |lam|) from a fixed starting vector, so the result does
not depend on earlier calls. Lanczos could in principle miss an eigenvalue whose eigenvector is
orthogonal to every Krylov vector; with a random start that happens with probability zero, and
tests/test_spectral_krylov.py checks the eigenpairs against the full decomposition.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse.linalg

__all__ = [
    "shrink_singular_values",
    "EIGENSOLVERS",
    "PARTIAL_MIN_N",
    "PARTIAL_MAX_FRACTION",
    "check_eigensolver",
    "cubic_threshold",
    "shrink",
    "KRYLOV_MAX_FRACTION",
    "leading_eigenpairs",
    "krylov_eigenpairs",
    "spectrum",
]

#: Eigensolver choices: "auto" (partial when it pays, see the maintenance note), "partial" (always the
#: eigenpairs above the threshold, MRRR), "krylov" (the same eigenpairs by Lanczos, see the maintenance
#: note), "full" (every eigenpair, numpy.linalg.eigh).
EIGENSOLVERS = ("auto", "partial", "krylov", "full")
#: Smallest n for which "auto" tries the partial decomposition (see the maintenance note; measured:
#: docs/PERFORMANCE.md#closed-form).
PARTIAL_MIN_N = 300
#: "auto" uses the full decomposition when more than this fraction of eigenvalues is expected to pass.
PARTIAL_MAX_FRACTION = 0.25
#: :func:`krylov_eigenpairs` hands over to MRRR once it would ask for more than this fraction of n.
KRYLOV_MAX_FRACTION = 0.2


def check_eigensolver(eigensolver) -> str:
    """Return ``eigensolver`` if it is one of :data:`EIGENSOLVERS`, else raise a ValueError naming it."""
    if eigensolver not in EIGENSOLVERS:
        raise ValueError(f"eigensolver must be one of {EIGENSOLVERS}; got {eigensolver!r}")
    return eigensolver


def cubic_threshold(tau: float, rho: float) -> float:
    """lambda_star = 3 (b^2/2)^(1/3), b = tau/(2 rho): eigenvalues at or below it map to l = 0."""
    b = tau / (2.0 * rho)
    return 3.0 * (b * b / 2.0) ** (1.0 / 3.0)


def shrink(lam: np.ndarray, tau: float, rho: float) -> np.ndarray:
    """Optimal singular values l >= 0 of C for kernel eigenvalues lam (vectorised; no validation)."""
    b = tau / (2.0 * rho)
    lam = np.asarray(lam, dtype=np.float64)
    l = np.zeros_like(lam)
    keep = lam > cubic_threshold(tau, rho)
    if np.any(keep):
        a = lam[keep]
        arg = np.clip(-(3.0 * np.sqrt(3.0) * b) / (2.0 * a**1.5), -1.0, 1.0)
        root = 2.0 * np.sqrt(a / 3.0) * np.cos(np.arccos(arg) / 3.0)
        # One Newton step polishes the trigonometric root to machine precision; the derivative
        # 3 l^2 - a is positive at the largest root because that root exceeds sqrt(a / 3).
        root -= (root**3 - a * root + b) / (3.0 * root**2 - a)
        # Candidate comparison as in Algorithm 2 (guards the boundary against rounding).
        better = rho / 2.0 * (a - root**2) ** 2 + tau * root < rho / 2.0 * a**2
        l[keep] = np.where(better, root, 0.0)
    return l


def leading_eigenpairs(
    K: np.ndarray, threshold: float, eigensolver: str = "auto", expected: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of symmetric K with eigenvalue > threshold, in decreasing order (no validation).

    Returns ``(lam, U)`` with lam of shape (k,) and U of shape (n, k). ``expected`` is a guess of k
    (e.g. the previous iterate's rank); "auto" goes straight to the full decomposition when it exceeds
    ``PARTIAL_MAX_FRACTION * n``.
    """
    n = K.shape[0]
    if eigensolver == "krylov":
        return krylov_eigenpairs(K, threshold, expected)
    partial = eigensolver == "partial" or (
        eigensolver == "auto"
        and n >= PARTIAL_MIN_N
        and (expected is None or expected <= PARTIAL_MAX_FRACTION * n)
    )
    if partial:
        try:
            lam, U = scipy.linalg.eigh(
                K, subset_by_value=(threshold, np.inf), driver="evr", check_finite=False
            )
        except (np.linalg.LinAlgError, ValueError):
            pass  # fall back to the full decomposition below
        else:
            return lam[::-1], U[:, ::-1]
    lam, U = np.linalg.eigh(K)
    k = int(np.count_nonzero(lam > threshold))
    return lam[::-1][:k], U[:, ::-1][:, :k]


def krylov_eigenpairs(K: np.ndarray, threshold: float, expected: int | None = None):
    """Eigenpairs of symmetric K with eigenvalue > threshold by Lanczos, decreasing (no validation).

    Asks ARPACK for ``expected`` (default 16) plus a margin of max(8, 10 %) eigenpairs and doubles
    the request until the smallest one returned is <= threshold; MRRR takes over beyond
    :data:`KRYLOV_MAX_FRACTION` of n or if ARPACK fails (see the module's maintenance note).
    Returns ``(lam, U)``, shapes (k,) and (n, k).
    """
    n = K.shape[0]
    k = 16 if expected is None else expected + max(8, expected // 10)
    v0 = np.random.default_rng(0).standard_normal(n)  # fixed start: same K, same answer
    while k <= KRYLOV_MAX_FRACTION * n:
        try:
            lam, U = scipy.sparse.linalg.eigsh(
                K, k=k, which="LA", v0=v0, tol=0, ncv=min(n, max(20, int(1.5 * k) + 10))
            )
        except (scipy.sparse.linalg.ArpackError, scipy.sparse.linalg.ArpackNoConvergence):
            break
        order = np.argsort(lam)[::-1]
        lam, U = lam[order], U[:, order]
        if lam[-1] <= threshold:
            keep = lam > threshold
            return lam[keep], U[:, keep]
        k *= 2
    return leading_eigenpairs(K, threshold, "partial")


def spectrum(K: np.ndarray, tau: float, rho: float, eigensolver: str = "full", expected: int | None = None):
    """``(lam, U, l)`` in decreasing eigenvalue order, ``l = shrink(lam)`` (no validation).

    ``eigensolver="full"``: every eigenpair of K (``numpy.linalg.eigh``). Otherwise only the eigenpairs
    above :func:`cubic_threshold` (:func:`leading_eigenpairs`, with ``expected`` as its rank guess).
    """
    if eigensolver == "full":
        lam, U = np.linalg.eigh(K)
        lam, U = lam[::-1], U[:, ::-1]
    else:
        lam, U = leading_eigenpairs(K, cubic_threshold(tau, rho), eigensolver, expected)
    return lam, U, shrink(lam, tau, rho)


def shrink_singular_values(Y: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """``U (S - t)_+ V^T`` for ``Y = U S V^T`` (thin SVD), the proximal map of ``t ||.||_*``.

    Returns the (m, n) result and its nonzero singular values ``s_i - t > 0`` (descending): their sum
    is its nuclear norm, their count its rank. Used by TNH (:mod:`nldr.nrsfm._tnh`) and SoftImpute
    (:mod:`nldr._baselines.peers`).
    """
    U, s, Vt = np.linalg.svd(Y, full_matrices=False)
    s = s - t
    k = int(np.count_nonzero(s > 0))  # s is descending, so the kept values come first
    return (U[:, :k] * s[:k]) @ Vt[:k], s[:k]
