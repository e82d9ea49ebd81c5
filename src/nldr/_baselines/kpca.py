"""Kernel PCA by rank truncation (the baseline of the paper's Table 1), the manifold error of a
denoised spectrum, and the coordinates of training and new points on a kernel manifold.

A denoised kernel here is ``U diag(d) U^T`` for the eigenvectors U of the (noisy) training kernel and
a spectrum d: KPCA at rank k keeps the k largest eigenvalues (``d = max(lam, 0)`` on them, 0 after),
the closed-form robust KPCA (:func:`nldr.robust_kpca.shrink_eigenvalues`) shrinks every eigenvalue to
``l_i^2``.
"""

from __future__ import annotations

import numpy as np

from .._validation import check_symmetric_kernel

__all__ = ["PROJECTIONS", "kpca_spectrum", "truncated_spectra", "spectral_kernel_errors", "project_points"]

#: How training and test points get coordinates on an estimated manifold (:func:`project_points`).
PROJECTIONS = ("factor", "eigenvectors", "whitened", "normalised")


def kpca_spectrum(K) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (decreasing) and eigenvectors (columns, in the same order) of a symmetric kernel.

    Parameters
    ----------
    K : array, shape (n, n), symmetric (to rounding).

    Returns
    -------
    eigenvalues : (n,), eigenvectors : (n, n)
    """
    check_symmetric_kernel(K, "K")
    lam, U = np.linalg.eigh(np.asarray(K, dtype=np.float64))
    return lam[::-1], U[:, ::-1]


def truncated_spectra(eigenvalues, ranks) -> np.ndarray:
    """KPCA's denoised spectra: for every rank k, ``max(lam_i, 0)`` for the k largest, 0 after.

    Parameters
    ----------
    eigenvalues : (n,) decreasing.
    ranks : (m,) ints in [0, n].

    Returns
    -------
    spectra : (m, n)
    """
    lam = np.asarray(eigenvalues, dtype=np.float64)
    ranks = np.asarray(ranks)
    if ranks.ndim != 1 or np.any(ranks < 0) or np.any(ranks > lam.size):
        raise ValueError(f"ranks must be a 1-d array of integers in [0, {lam.size}]; got {ranks.tolist()}")
    return np.where(np.arange(lam.size)[None, :] < ranks[:, None], np.maximum(lam, 0.0)[None, :], 0.0)


def spectral_kernel_errors(
    eigenvectors: np.ndarray, target: np.ndarray, denoised_eigenvalues: np.ndarray
) -> np.ndarray:
    """Relative errors ||U diag(d) U^T - T||_F^2 / ||T||_F^2 for many spectra d at once.

    With q_i = u_i^T T u_i and U orthonormal, ||U diag(d) U^T - T||^2 = ||T||^2 - 2 d.q + d.d, so
    after one O(n^3) product every candidate costs O(n).

    Parameters
    ----------
    eigenvectors : (n, n) orthonormal columns U
    target : (n, n) symmetric matrix T
    denoised_eigenvalues : (m, n) one spectrum d per row

    Returns
    -------
    errors : (m,)
    """
    q = np.einsum("ij,ij->j", target @ eigenvectors, eigenvectors)
    norm2 = float(np.sum(target**2))
    d = np.atleast_2d(denoised_eigenvalues)
    return (norm2 - 2.0 * d @ q + np.einsum("ij,ij->i", d, d)) / norm2


def project_points(U, lam, K_test, scale, projection: str = "factor"):
    """Coordinates of the training and test points on a manifold spanned by the leading eigenvectors.

    The manifold is the span of the k = len(scale) leading eigenvectors of the (centred) training
    kernel, whose component i carries the feature-space scale ``scale[i]``: ``sqrt(lam_i)`` for KPCA,
    the closed form's ``l_i`` (the rows of C = diag(l) U^T). Training point j gets
    ``U[j, :k] * scale`` (for the closed form: column j of C) and a test point with kernel row
    ``k_test`` gets ``k_test U_k * scale / lam_k``, the same map extended to new points (for a
    training point's own kernel row it returns its training coordinates, as K U = U diag(lam)).

    Parameters
    ----------
    U : (n, m) eigenvectors of the training kernel, leading first (m >= k).
    lam : (m,) their eigenvalues, positive for the first k.
    K_test : (t, n) test-versus-training kernel, centred like the training kernel.
    scale : (k,) feature-space scale of each kept component (see above).
    projection : {"factor", "eigenvectors", "whitened", "normalised"}
        "factor": the map above with the given scale (KPCA coordinates, the closed form's C);
        "eigenvectors": the same with ``sqrt(lam)`` whatever the scale (KPCA coordinates at the
        closed form's rank: only the subspace is the closed form's); "whitened": scale 1 (every
        component unit variance over the training set); "normalised": "factor" with every point's
        coordinates scaled to unit length (cosine geometry).

    Returns
    -------
    train : (n, k), test : (t, k)
    """
    if projection not in PROJECTIONS:
        raise ValueError(f"projection must be one of {PROJECTIONS}; got {projection!r}")
    scale = np.asarray(scale, dtype=np.float64)
    k = scale.size
    if k and np.any(lam[:k] <= 0):
        raise ValueError("lam must be positive on the kept components")
    if projection == "eigenvectors":
        scale = np.sqrt(lam[:k])
    elif projection == "whitened":
        scale = np.ones(k)
    train, test = U[:, :k] * scale, K_test @ U[:, :k] * (scale / lam[:k])
    if projection == "normalised":
        train, test = (
            Z / np.maximum(np.linalg.norm(Z, axis=1, keepdims=True), 1e-300) for Z in (train, test)
        )
    return train, test
