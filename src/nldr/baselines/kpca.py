"""Kernel PCA by rank truncation, the baseline of the paper's Table 1."""

from __future__ import annotations

import numpy as np

from .._validation import check_symmetric_kernel

__all__ = ["kpca_spectrum", "truncated_kernel"]


def kpca_spectrum(K) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (decreasing) and eigenvectors (columns) of a symmetric kernel, shapes (n,), (n, n)."""
    K = check_symmetric_kernel(K, "K")
    lam, U = np.linalg.eigh(K)
    return lam[::-1], U[:, ::-1]


def truncated_kernel(eigenvalues: np.ndarray, eigenvectors: np.ndarray, rank: int) -> np.ndarray:
    """Best rank-``rank`` PSD approximation U_r diag(max(lambda_r, 0)) U_r^T (KPCA's denoised kernel)."""
    if not 0 <= rank <= eigenvalues.size:
        raise ValueError(f"rank must be between 0 and {eigenvalues.size}; got {rank}")
    U = eigenvectors[:, :rank]
    return (U * np.maximum(eigenvalues[:rank], 0.0)) @ U.T
