"""Closed-form robust kernel PCA (the paper's Algorithm 2 / Theorem 3.1).

Problem. For a symmetric kernel matrix K (n x n) and tau, rho > 0,

    min_C  tau ||C||_* + rho/2 ||K - C^T C||_F^2 .

Maintenance note (the cubic and its threshold). Write K = U diag(lambda) U^T. The minimiser is
C = diag(l) U^T, where each l_i >= 0 solves the scalar problem

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
that are not wanted, which is where a full decomposition spends most of its time once n is a few
hundred. It pays only when few eigenvalues pass the threshold and n is large: below
``_PARTIAL_MIN_N`` the full ``numpy.linalg.eigh`` is faster, and when more than
``_PARTIAL_MAX_FRACTION`` of the spectrum passes, MRRR's per-eigenvector work exceeds the full
divide-and-conquer (measured: benchmarks/bench_spectrum.py). :func:`_leading_eigenpairs` chooses, and
falls back to the full decomposition if the partial one fails.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.utils.validation import check_is_fitted, validate_data

from ._validation import check_positive, check_symmetric_kernel
from .kernels import center_cross_kernel, center_kernel, rbf_kernel

__all__ = [
    "EIGENSOLVERS",
    "rank_penalty_threshold",
    "shrink_eigenvalues",
    "RankPenaltySpectrum",
    "rank_penalty_spectrum",
    "closed_form_rank_penalty",
    "rank_penalty_energy",
    "RobustKernelPCA",
]


#: Eigensolver choices: "auto" (partial when it pays, see the maintenance note), "partial" (always the
#: eigenpairs above the threshold), "full" (every eigenpair, numpy.linalg.eigh).
EIGENSOLVERS = ("auto", "partial", "full")
#: Smallest n for which "auto" tries the partial decomposition (benchmarks/bench_spectrum.py).
_PARTIAL_MIN_N = 300
#: "auto" uses the full decomposition when more than this fraction of eigenvalues is expected to pass.
_PARTIAL_MAX_FRACTION = 0.25


def rank_penalty_threshold(tau: float, rho: float) -> float:
    """Largest kernel eigenvalue that the closed form maps to zero: 3 (b^2/2)^(1/3), b = tau/(2 rho)."""
    return _threshold(check_positive(tau, "tau"), check_positive(rho, "rho"))


def _threshold(tau: float, rho: float) -> float:
    b = tau / (2.0 * rho)
    return 3.0 * (b * b / 2.0) ** (1.0 / 3.0)


def _check_eigensolver(eigensolver) -> str:
    if eigensolver not in EIGENSOLVERS:
        raise ValueError(f"eigensolver must be one of {EIGENSOLVERS}; got {eigensolver!r}")
    return eigensolver


def _leading_eigenpairs(
    K: np.ndarray, threshold: float, eigensolver: str = "auto", expected: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of symmetric K with eigenvalue > threshold, in decreasing order (no validation).

    Returns ``(lam, U)`` with lam of shape (k,) and U of shape (n, k). ``expected`` is a guess of k
    (e.g. the previous iterate's rank); "auto" goes straight to the full decomposition when it exceeds
    ``_PARTIAL_MAX_FRACTION * n``.
    """
    n = K.shape[0]
    partial = eigensolver == "partial" or (
        eigensolver == "auto"
        and n >= _PARTIAL_MIN_N
        and (expected is None or expected <= _PARTIAL_MAX_FRACTION * n)
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


def _shrink(lam: np.ndarray, tau: float, rho: float) -> np.ndarray:
    """Optimal singular values l >= 0 of C for kernel eigenvalues lam (no validation; vectorised)."""
    b = tau / (2.0 * rho)
    lam = np.asarray(lam, dtype=np.float64)
    l = np.zeros_like(lam)
    keep = lam > _threshold(tau, rho)
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


def shrink_eigenvalues(lam, tau: float, rho: float) -> np.ndarray:
    """Singular values of the optimal C for given kernel eigenvalues.

    Parameters
    ----------
    lam : array, shape (n,)
        Eigenvalues of the kernel matrix (any order, may be negative).
    tau, rho : float > 0
        Trace-norm weight and penalty weight.

    Returns
    -------
    l : array, shape (n,)
        ``argmin_{l >= 0} rho/2 (lam - l^2)^2 + tau l`` elementwise; ``l**2`` is the denoised eigenvalue.
    """
    lam = np.asarray(lam, dtype=np.float64)
    if not np.all(np.isfinite(lam)):
        raise ValueError("lam contains NaN or infinite values")
    return _shrink(lam, check_positive(tau, "tau"), check_positive(rho, "rho"))


@dataclass(frozen=True)
class RankPenaltySpectrum:
    """Spectral form of the closed-form solution, eigenvalues sorted in decreasing order.

    Attributes
    ----------
    eigenvalues : (n,) eigenvalues lambda of K
    singular_values : (n,) singular values l of C (zero below the threshold)
    eigenvectors : (n, n) orthonormal eigenvectors U of K, one per column
    tau, rho : the parameters used
    """

    eigenvalues: np.ndarray
    singular_values: np.ndarray
    eigenvectors: np.ndarray
    tau: float
    rho: float

    @property
    def rank(self) -> int:
        """Number of non-zero singular values of C (the dimension of the recovered manifold)."""
        return int(np.count_nonzero(self.singular_values))

    @property
    def C(self) -> np.ndarray:
        """The minimiser C = diag(l) U^T, shape (n, n)."""
        return self.singular_values[:, None] * self.eigenvectors.T

    @property
    def low_rank_kernel(self) -> np.ndarray:
        """C^T C = U diag(l^2) U^T, shape (n, n)."""
        U = self.eigenvectors
        return (U * self.singular_values**2) @ U.T

    @property
    def energy(self) -> float:
        """tau ||C||_* + rho/2 ||K - C^T C||_F^2, evaluated from the spectrum."""
        lam, l = self.eigenvalues, self.singular_values
        return float(self.rho / 2.0 * np.sum((lam - l**2) ** 2) + self.tau * np.sum(l))


def rank_penalty_spectrum(K, tau: float, rho: float) -> RankPenaltySpectrum:
    """Closed-form robust KPCA in spectral form; see :func:`closed_form_rank_penalty`."""
    K = check_symmetric_kernel(K, "K")
    tau = check_positive(tau, "tau")
    rho = check_positive(rho, "rho")
    lam, U = np.linalg.eigh(K)
    lam, U = lam[::-1], U[:, ::-1]
    return RankPenaltySpectrum(lam, _shrink(lam, tau, rho), U, tau, rho)


def closed_form_rank_penalty(K, tau: float, rho: float, *, eigensolver: str = "auto") -> np.ndarray:
    """Minimise ``tau ||C||_* + rho/2 ||K - C^T C||_F^2`` over C in closed form.

    Parameters
    ----------
    K : array, shape (n, n)
        Symmetric, finite kernel matrix (need not be positive semidefinite; negative eigenvalues map
        to zero).
    tau : float > 0
        Weight of the trace norm of C (equal to the trace norm of the feature-space data).
    rho : float > 0
        Weight of the kernel-mismatch penalty. Only tau / rho changes the minimiser.
    eigensolver : {"auto", "partial", "full"}, default "auto"
        How to decompose K. Only eigenpairs above :func:`rank_penalty_threshold` enter C, so
        "partial" computes just those (LAPACK MRRR); "full" computes every eigenpair; "auto" picks
        "partial" for n >= 300 (see the module's maintenance note). All give the same C up to
        rounding.

    Returns
    -------
    C : array, shape (n, n)
        ``diag(l) U^T`` with rows ordered by decreasing kernel eigenvalue; rows beyond the recovered
        rank are zero. ``C.T @ C`` is the denoised kernel.

    Raises
    ------
    ValueError
        If K is not a finite symmetric square matrix, tau, rho are not finite and positive, or the
        eigensolver is unknown.
    """
    K = check_symmetric_kernel(K, "K")
    tau = check_positive(tau, "tau")
    rho = check_positive(rho, "rho")
    lam, U = _leading_eigenpairs(K, _threshold(tau, rho), _check_eigensolver(eigensolver))
    l = _shrink(lam, tau, rho)
    C = np.zeros_like(K)
    C[: l.size] = l[:, None] * U.T
    return C


def rank_penalty_energy(K, C, tau: float, rho: float) -> float:
    """The objective ``tau ||C||_* + rho/2 ||K - C^T C||_F^2`` at a given C (for checks and plots)."""
    K = np.asarray(K, dtype=np.float64)
    C = np.asarray(C, dtype=np.float64)
    nuclear = np.linalg.svd(C, compute_uv=False).sum()
    return float(tau * nuclear + rho / 2.0 * np.sum((K - C.T @ C) ** 2))


class RobustKernelPCA(TransformerMixin, BaseEstimator):
    """Robust kernel PCA by the closed-form trace-norm penalty on the feature-space data.

    Fitting computes the (optionally centred) RBF kernel of the training data and replaces its
    eigenvalues lambda_i by l_i^2, where l_i minimises rho/2 (lambda_i - l^2)^2 + tau l: eigenvalues
    below a threshold vanish (choosing the rank) and the others shrink. Unlike rank truncation,
    the number of components follows from tau / rho.

    Parameters
    ----------
    gamma : float, default=None
        RBF inverse squared width, ``K_ij = exp(-gamma ||x_i - x_j||^2)``. None means 1 / n_features.
    tau : float, default=1.0
        Trace-norm weight.
    rho : float, default=1.0
        Kernel-mismatch weight; only tau / rho matters.
    center : bool, default=True
        Centre the kernel in feature space before the decomposition (as kernel PCA does).

    Attributes
    ----------
    X_fit_ : array, shape (n_samples, n_features)
    gamma_ : float, the kernel parameter used
    eigenvalues_ : array, shape (n_components_,), kernel eigenvalues lambda of the kept components
    singular_values_ : array, shape (n_components_,), shrunk values l (``l**2 <= lambda``)
    eigenvectors_ : array, shape (n_samples, n_components_)
    n_components_ : int, the rank chosen by the threshold
    spectrum_ : RankPenaltySpectrum, the full solution (every eigenpair)
    kernel_column_means_ : array, shape (n_samples,), column means of the uncentred training kernel
    n_features_in_ : int

    Notes
    -----
    ``transform`` projects new points onto the principal axes of the training features and scales
    each coordinate by l_i / sqrt(lambda_i), the same shrinkage the fit applied, so that
    ``transform(X_fit_)`` equals ``fit_transform``'s output ``U diag(l)`` = C^T.
    """

    def __init__(self, gamma=None, tau=1.0, rho=1.0, center=True):
        self.gamma = gamma
        self.tau = tau
        self.rho = rho
        self.center = center

    def _kernel(self, X, Y=None):
        return rbf_kernel(X, self.gamma_, Y)

    def fit(self, X, y=None):
        """Fit on X, shape (n_samples, n_features). Returns self."""
        X = validate_data(self, X, ensure_min_samples=2, dtype=np.float64)
        self.gamma_ = 1.0 / X.shape[1] if self.gamma is None else check_positive(self.gamma, "gamma")
        tau = check_positive(self.tau, "tau")
        rho = check_positive(self.rho, "rho")
        K = self._kernel(X)
        self.kernel_column_means_ = K.mean(axis=0)
        Kc = center_kernel(K) if self.center else K
        self.spectrum_ = rank_penalty_spectrum(Kc, tau, rho)
        k = self.spectrum_.rank
        self.n_components_ = k
        self.eigenvalues_ = self.spectrum_.eigenvalues[:k]
        self.singular_values_ = self.spectrum_.singular_values[:k]
        self.eigenvectors_ = self.spectrum_.eigenvectors[:, :k]
        self.X_fit_ = X
        return self

    def transform(self, X):
        """Coordinates of X on the robust principal axes, shape (n_samples, n_components_)."""
        check_is_fitted(self)
        X = validate_data(self, X, reset=False, dtype=np.float64)
        K = self._kernel(X, self.X_fit_)
        if self.center:
            K = center_cross_kernel(K, self.kernel_column_means_)
        scale = self.singular_values_ / self.eigenvalues_
        return (K @ self.eigenvectors_) * scale[None, :]

    def fit_transform(self, X, y=None):
        """Fit and return the training coordinates ``U diag(l)``, shape (n_samples, n_components_)."""
        self.fit(X)
        return self.eigenvectors_ * self.singular_values_[None, :]

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.pairwise = False
        return tags
