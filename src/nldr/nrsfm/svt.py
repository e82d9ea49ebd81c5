"""Singular value soft-thresholding, the proximal operator of the nuclear norm, two ways.

``prox_{t ||.||_*}(Y) = U (S - t)_+ V^T`` for ``Y = U S V^T``. Both TNH solvers apply it once per
iteration: ADMM (:mod:`nldr.nrsfm.admm`) and FISTA (:mod:`nldr.nrsfm.fista`) both through
:func:`soft_threshold_singular_values_gram` by default.

:func:`soft_threshold_singular_values` takes a full thin SVD. It is the accurate one, the one the tests
compare the Gram version against, and the fallback of the Gram version. For ADMM the switch was
measured (docs/PERFORMANCE.md, "Scale"): the same iteration counts, nuclear norms equal to 10 digits,
iterates within 1.5e-10 relative, 1.4-2.1x less CPU.

Maintenance note (the Gram version). :func:`soft_threshold_singular_values_gram` takes the
eigendecomposition of the small Gram matrix Y Y^T (F x F when F <= 3P) instead of the SVD of Y, which
is cheaper for the short, wide matrices of NRSfM (timings: benchmarks/bench_table4.py). Eigenvalues of
a Gram matrix carry an absolute error of order eps s_max^2, i.e. a singular value near the threshold t
would be off by eps s_max^2 / t (on Table 4's pickup problem at tau = 0.1, 2e-11: as large as the
objective decrease FISTA's stopping test must resolve). So the singular values are not taken from the
eigenvalues but recomputed as the norms of the rows of U^T Y (Rayleigh-Ritz: the eigenvectors are
accurate to O(eps) against the dominant directions, which is what these norms need), accurate to
eps ||Y|| like an SVD's. What stays less accurate is the orthogonality of the right singular vectors of
components near the threshold, O(eps s_max^2 / t^2); the Gram path is used only while
n eps s_max^2 <= :data:`GRAM_SAFETY` t^2 and the SVD otherwise (on pickup at tau = 0.1 the ratio is
2e-8).
"""

from __future__ import annotations

import numpy as np

from .._spectral import shrink_singular_values

__all__ = ["GRAM_SAFETY", "soft_threshold_singular_values", "soft_threshold_singular_values_gram"]

_EPS = float(np.finfo(np.float64).eps)
#: The Gram path needs n eps s_max^2 <= GRAM_SAFETY t^2 (see the module's maintenance note).
GRAM_SAFETY = 1e-4


def soft_threshold_singular_values(Y: np.ndarray, t: float) -> tuple[np.ndarray, float]:
    """Singular value soft-thresholding by a full thin SVD.

    Parameters
    ----------
    Y : array, shape (m, n)
    t : float >= 0
        Threshold.

    Returns
    -------
    X : array, shape (m, n)
        U (S - t)_+ V^T.
    nuclear_norm : float
        ||X||_* = sum (s_i - t)_+.
    """
    X, kept = shrink_singular_values(Y, t)
    return X, float(kept.sum())


def soft_threshold_singular_values_gram(Y: np.ndarray, t: float) -> tuple[np.ndarray, float]:
    """Singular value soft-thresholding of Y (m, n) at t > 0 through the Gram matrix of its short side.

    Returns the thresholded matrix (m, n) and its nuclear norm, sum (s_i - t)_+, like
    :func:`soft_threshold_singular_values`. With A the short-side orientation of Y (k x N, k <= N) and
    A A^T = U diag(lam) U^T, the singular values are taken as ||U^T A||'s row norms (accurate to
    eps ||Y||, see the module note) and the result is U_+ diag(1 - t / s_+) U_+^T A over the components
    with s > t. Falls back to :func:`soft_threshold_singular_values` when the eigenvalue error
    eps s_max^2 is not negligible against t^2.
    """
    transpose = Y.shape[0] > Y.shape[1]
    A = Y.T if transpose else Y
    lam, U = np.linalg.eigh(A @ A.T)  # ascending
    noise = A.shape[0] * _EPS * max(float(lam[-1]), 0.0)
    if noise > GRAM_SAFETY * t * t:
        return soft_threshold_singular_values(Y, t)
    first = int(np.searchsorted(lam, 0.25 * t * t))  # candidates: s >= t / 2 by the (inaccurate) eigenvalues
    U = U[:, first:]
    B = U.T @ A
    s = np.sqrt(np.einsum("ij,ij->i", B, B))
    keep = s > t
    if not keep.any():
        return np.zeros_like(Y), 0.0
    s = s[keep]
    X = (U[:, keep] * (1.0 - t / s)) @ B[keep]
    return (X.T if transpose else X), float((s - t).sum())
