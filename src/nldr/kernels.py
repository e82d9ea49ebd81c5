"""RBF kernel, its gradient with respect to the data, centring, and kernel-width heuristics.

Convention (used everywhere in nldr): data are stored **one sample per row**, ``X`` of shape
``(n_samples, n_features)``, and the Gaussian (RBF) kernel is

    K_ij = exp(-gamma * ||x_i - x_j||^2),

so ``gamma`` is the *inverse squared width* (the paper's "inverse width", 0.075 on oil flow). This is
scikit-learn's ``rbf_kernel`` convention; ``gamma = 1 / (2 sigma^2)`` for a Gaussian of width sigma.
The paper writes samples as columns of S; transposing changes nothing else.
"""

from __future__ import annotations

import numpy as np

from ._validation import as_float_matrix, check_positive

__all__ = [
    "squared_distances",
    "rbf_kernel",
    "rbf_kernel_vjp",
    "center_kernel",
    "center_cross_kernel",
    "d_max_width",
    "d_med_width",
]


def squared_distances(X: np.ndarray, Y: np.ndarray | None = None) -> np.ndarray:
    """Pairwise squared Euclidean distances, shape (n_X, n_Y), clipped at 0 against rounding."""
    Y_ = X if Y is None else Y
    xx = np.einsum("ij,ij->i", X, X)
    yy = xx if Y is None else np.einsum("ij,ij->i", Y_, Y_)
    D = xx[:, None] + yy[None, :] - 2.0 * (X @ Y_.T)
    np.maximum(D, 0.0, out=D)
    if Y is None:
        np.fill_diagonal(D, 0.0)
    return D


def rbf_kernel(X, gamma: float, Y=None) -> np.ndarray:
    """RBF kernel matrix.

    Parameters
    ----------
    X : array, shape (n, d)
        Samples as rows.
    gamma : float > 0
        Inverse squared width: ``K_ij = exp(-gamma ||x_i - y_j||^2)``.
    Y : array, shape (m, d), optional
        Second set of samples; defaults to ``X`` (then K is exactly symmetric with unit diagonal).

    Returns
    -------
    K : array, shape (n, m)
    """
    X = as_float_matrix(X, "X")
    gamma = check_positive(gamma, "gamma")
    if Y is not None:
        Y = as_float_matrix(Y, "Y")
        if Y.shape[1] != X.shape[1]:
            raise ValueError(f"X and Y must have the same number of columns; got {X.shape} and {Y.shape}")
    D = squared_distances(X, Y)
    if not np.all(np.isfinite(D)):
        raise ValueError(
            f"squared distances between the samples overflow float64 (largest |entry| "
            f"{max(np.abs(X).max(), 0 if Y is None else np.abs(Y).max()):.3g}); rescale the data"
        )
    return np.exp(-gamma * D)


def rbf_kernel_vjp(X: np.ndarray, K: np.ndarray, G: np.ndarray, gamma: float) -> np.ndarray:
    """Gradient of a scalar function E(K(X)) with respect to X, given G = dE/dK.

    Maintenance note. With K_ij = exp(-gamma ||x_i - x_j||^2),
    dK_ij / dx_i = -2 gamma K_ij (x_i - x_j) and dK_ij / dx_j = -dK_ij / dx_i. Summing over every
    entry that involves x_i (row i and column i of K):

        dE/dx_i = -2 gamma sum_j M_ij (x_i - x_j),   M = (G + G^T) o K,

    i.e. dE/dX = -2 gamma (diag(M 1) X - M X): two matrix products, O(n^2 d), no loop over points.

    Parameters
    ----------
    X : array, shape (n, d)
    K : array, shape (n, n), the RBF kernel of X with this gamma
    G : array, shape (n, n), the gradient of E with respect to K (need not be symmetric)
    gamma : float

    Returns
    -------
    grad : array, shape (n, d)
    """
    M = (G + G.T) * K
    return -2.0 * gamma * (M.sum(axis=1)[:, None] * X - M @ X)


def center_kernel(K: np.ndarray) -> np.ndarray:
    """Double-centred kernel H K H with H = I - 11^T / n (the Gram matrix of mean-removed features).

    ``K`` is a finite square (n, n) array; a ValueError names any other input.
    """
    K = as_float_matrix(K, "K")
    if K.shape[0] != K.shape[1]:
        raise ValueError(f"K must be a square (n, n) kernel matrix; got shape {K.shape}")
    row = K.mean(axis=0)
    total = row.mean()
    return K - row[None, :] - row[:, None] + total


def center_cross_kernel(K_new: np.ndarray, fit_column_means: np.ndarray) -> np.ndarray:
    """Centre a test-versus-training kernel (m, n) with the training features' mean.

    ``fit_column_means`` is ``K_fit.mean(axis=0)`` of the (n, n) training kernel. Equivalent to
    scikit-learn's ``KernelCenterer().fit(K_fit).transform(K_new)``.
    """
    return K_new - fit_column_means[None, :] - K_new.mean(axis=1)[:, None] + fit_column_means.mean()


def _pairwise_distances_upper(X) -> np.ndarray:
    X = as_float_matrix(X, "X")
    if X.shape[0] < 2:
        raise ValueError(f"X needs at least 2 samples to define a kernel width; got {X.shape[0]}")
    iu = np.triu_indices(X.shape[0], k=1)
    return np.sqrt(squared_distances(X)[iu])


def d_max_width(X) -> float:
    """gamma for which the most distant pair of samples gets kernel value exp(-9/2).

    The paper's maximum-distance criterion: the largest distance is 3 sigma in a Gaussian of width
    sigma, so gamma = 1 / (2 sigma^2) = 9 / (2 d_max^2).
    """
    d = _pairwise_distances_upper(X).max()
    if d <= 0:
        raise ValueError("all samples in X coincide; the kernel width is undefined")
    return 9.0 / (2.0 * d**2)


def d_med_width(X) -> float:
    """gamma for which the median pairwise distance gets kernel value 1/2: gamma = ln 2 / d_med^2."""
    d = float(np.median(_pairwise_distances_upper(X)))
    if d <= 0:
        raise ValueError("the median pairwise distance of X is 0; the kernel width is undefined")
    return float(np.log(2.0) / d**2)
