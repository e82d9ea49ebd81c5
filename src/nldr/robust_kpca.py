"""Closed-form robust kernel PCA (the paper's Algorithm 2 / Theorem 3.1).

Problem. For a symmetric kernel matrix K (n x n) and tau, rho > 0,

    min_C  tau ||C||_* + rho/2 ||K - C^T C||_F^2 .

Solution. With K = U diag(lambda) U^T, the minimiser is C = diag(l) U^T, where each l_i >= 0 is the
largest root of the cubic l^3 - lambda_i l + tau / (2 rho) = 0 when lambda_i exceeds a threshold known
in advance, and 0 otherwise. The derivation (the cubic, its threshold) and the choice between a full
and a partial eigendecomposition are the maintenance notes of :mod:`nldr._spectral`, which holds the
inner functions this module shares with :mod:`nldr.regularizer`.
"""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.utils.validation import check_is_fitted, validate_data

from ._preimage import LOSSES, Subspace, average_solutions, complete_from_starts, nearest_rows, preimage
from ._spectral import check_eigensolver, cubic_threshold, leading_eigenpairs, shrink, spectrum
from ._threads import blas_threads_for
from ._validation import (
    check_count,
    check_flag,
    check_magnitude,
    check_masked_matrix,
    check_positive,
    check_symmetric_kernel,
)
from .kernels import center_cross_kernel, center_kernel, rbf_kernel

__all__ = [
    "rank_penalty_threshold",
    "shrink_eigenvalues",
    "closed_form_rank_penalty",
    "rank_penalty_energy",
    "RobustKernelPCA",
]


def rank_penalty_threshold(tau: float, rho: float) -> float:
    """Largest kernel eigenvalue that the closed form maps to zero: 3 (b^2/2)^(1/3), b = tau/(2 rho)."""
    return cubic_threshold(check_positive(tau, "tau"), check_positive(rho, "rho"))


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
    return shrink(lam, check_positive(tau, "tau"), check_positive(rho, "rho"))


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
    eigensolver : {"auto", "partial", "krylov", "full"}, default "auto"
        How to decompose K. Only eigenpairs above :func:`rank_penalty_threshold` enter C, so
        "partial" computes just those (LAPACK MRRR), "krylov" by Lanczos; "full" computes every
        eigenpair; "auto" picks
        "partial" for n >= 300 (see the maintenance notes of :mod:`nldr._spectral`). All give the same C up to
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
    lam, U = leading_eigenpairs(K, cubic_threshold(tau, rho), check_eigensolver(eigensolver))
    l = shrink(lam, tau, rho)
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
    eigensolver : {"auto", "partial", "krylov", "full"}, default="auto"
        How to decompose the training kernel. "full": every eigenpair (``numpy.linalg.eigh``);
        "partial": only those above :func:`rank_penalty_threshold`, the only ones kept; "krylov": the
        same by Lanczos; "auto":
        "partial" for n_samples >= 300 (see the maintenance notes of :mod:`nldr._spectral`). All agree
        up to rounding.

    Attributes
    ----------
    X_fit_ : array, shape (n_samples, n_features)
    gamma_ : float, the kernel parameter used
    eigenvalues_ : array, shape (n_components_,), kernel eigenvalues lambda of the kept components
    singular_values_ : array, shape (n_components_,), shrunk values l (``l**2 <= lambda``)
    eigenvectors_ : array, shape (n_samples, n_components_)
    n_components_ : int, the rank chosen by the threshold
    kernel_column_means_ : array, shape (n_samples,), column means of the uncentred training kernel
    n_features_in_ : int

    See Also
    --------
    closed_form_rank_penalty : The closed form on a given kernel matrix (the paper's Algorithm 2).
    nldr.impute.RobustKernelPCAImputer : Completes and denoises new rows against this manifold.
    sklearn.decomposition.KernelPCA : Rank truncation instead of shrinkage.

    Notes
    -----
    ``transform`` projects new points onto the principal axes of the training features and scales
    each coordinate by l_i / sqrt(lambda_i), the same shrinkage the fit applied, so that
    ``transform(X_fit_)`` equals ``fit_transform``'s output ``U diag(l)`` = C^T (up to rounding).
    The kernel is decomposed as computed, not symmetrised first (the centred kernel is symmetric
    only up to rounding), so with ``eigensolver="full"`` the coordinates are exactly those of
    ``lam, U = numpy.linalg.eigh(K)`` reversed to decreasing order: ``U[:, :k] * l[:k]`` for the
    training points and ``(K_new @ U[:, :k]) * (l[:k] / lam[:k])`` for new points.

    Examples
    --------
    >>> import numpy as np
    >>> from nldr.robust_kpca import RobustKernelPCA
    >>> X = np.array([[1.0, 2.0, 3.0], [3.0, 6.1, 9.0], [5.0, 9.9, 15.1], [6.0, 12.0, 18.0]])
    >>> model = RobustKernelPCA(gamma=0.05, tau=0.01).fit(X)
    >>> Z = model.transform(X)
    >>> Z.shape == (4, model.n_components_), bool(np.allclose(Z, model.fit_transform(X)))
    (True, True)
    >>> bool(np.all(model.singular_values_ ** 2 <= model.eigenvalues_))  # shrunk, never grown
    True
    """

    def __init__(self, gamma=None, tau=1.0, rho=1.0, center=True, eigensolver="auto"):
        self.gamma = gamma
        self.tau = tau
        self.rho = rho
        self.center = center
        self.eigensolver = eigensolver

    def _kernel(self, X, Y=None):
        return rbf_kernel(X, self.gamma_, Y)

    def fit(self, X, y=None):
        """Fit on X, shape (n_samples, n_features). Returns self."""
        X = validate_data(self, X, ensure_min_samples=2, dtype=np.float64)
        self.gamma_ = 1.0 / X.shape[1] if self.gamma is None else check_positive(self.gamma, "gamma")
        tau = check_positive(self.tau, "tau")
        rho = check_positive(self.rho, "rho")
        eigensolver = check_eigensolver(self.eigensolver)
        center = check_flag(self.center, "center")
        with blas_threads_for(X.shape[0]):  # one BLAS thread on small problems (nldr._threads)
            K = self._kernel(X)
            self.kernel_column_means_ = K.mean(axis=0)
            Kc = center_kernel(K) if center else K
            lam, U, l = spectrum(Kc, tau, rho, eigensolver)
        k = int(np.count_nonzero(l))
        if k == 0:
            warnings.warn(
                f"tau = {tau:g} with rho = {rho:g} removes every component (every kernel eigenvalue "
                f"is below the threshold {rank_penalty_threshold(tau, rho):.3g}): transform returns "
                "(n, 0) arrays. Lower tau",
                UserWarning,
                stacklevel=2,
            )
        self.n_components_ = k
        self.eigenvalues_ = lam[:k]
        self.singular_values_ = l[:k]
        self.eigenvectors_ = U[:, :k]
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

    def _subspace(self) -> Subspace:
        return Subspace(
            X_fit=self.X_fit_,
            gamma=self.gamma_,
            V=self.eigenvectors_ / np.sqrt(self.eigenvalues_)[None, :],
            column_means=self.kernel_column_means_ if self.center else None,
        )

    def inverse_transform(self, Z, *, max_iter: int = 500):
        """Pre-images of points given by their coordinates, so that ``inverse_transform(transform(X))``
        is X pulled onto the learned manifold.

        Parameters
        ----------
        Z : array, shape (m, n_components_)
            Coordinates as :meth:`transform` returns them (shrunk by l / sqrt(lambda) per axis).
        max_iter : int, default 500
            L-BFGS iterations per block of rows.

        Returns
        -------
        X : array, shape (m, n_features_in_)
            For each row z, a local minimiser of the feature-space distance ||phi(x) - mu - sum_i a_i
            e_i||^2 with a_i = z_i sqrt(lambda_i) / l_i (the point of the subspace that ``transform``
            mapped to z), started at the training sample whose coordinates are nearest to z
            (:mod:`nldr._preimage`). Unlike scikit-learn's ``KernelPCA``, no regression is learned: the
            pre-image is computed.
        """
        check_is_fitted(self)
        Z = np.asarray(Z, dtype=np.float64)
        if Z.ndim != 2 or Z.shape[1] != self.n_components_:
            raise ValueError(
                f"Z must have shape (n_samples, {self.n_components_}) (n_components_); got {Z.shape}"
            )
        if not np.all(np.isfinite(Z)):
            raise ValueError("Z contains NaN or infinite values")
        check_magnitude(Z, "Z")  # the distances to the training coordinates square Z
        T = self.eigenvectors_ * self.singular_values_[None, :]
        D = (Z**2).sum(axis=1)[:, None] - 2.0 * Z @ T.T + (T**2).sum(axis=1)[None, :]
        X0 = self.X_fit_[np.argmin(D, axis=1)]
        A = Z * (np.sqrt(self.eigenvalues_) / self.singular_values_)[None, :]
        with blas_threads_for(self.X_fit_.shape[0]):
            X, _ = preimage(self._subspace(), A, X0, max_iter=check_count(max_iter, "max_iter"))
        return X

    def complete(
        self,
        X,
        mask,
        *,
        rho=None,
        loss: str = "squared",
        delta=None,
        n_neighbors: int = 5,
        starts: str = "mean",
        weights: str = "uniform",
        max_iter: int = 500,
    ):
        """Complete (and with finite rho denoise) rows never seen in ``fit`` against the learned manifold.

        Each row w with observation mask m solves the pre-image problem

            min_x sum_j m_j l(x_j - w_j) + rho * dist(phi(x), principal subspace)^2

        with l the squared loss or the Huber loss h_delta (:func:`nldr.data_terms.huber_loss`: equal
        to the squared loss within delta, linear beyond) and dist the feature-space distance of phi(x)
        to its projection onto the learned principal subspace (kernel units). ``rho=None`` is the hard
        limit: the observed entries are kept and the missing ones minimise the distance alone
        (completion); with a finite rho every entry may move, so ``mask`` all True denoises, and with
        ``loss="huber"`` an observed entry with a gross error is pulled back to the manifold instead
        of dragging the row to it.

        Starts. The problem is not convex, so the answer is a local minimum. The neighbours are the
        ``n_neighbors`` training rows nearest on the observed entries (mean loss l over them,
        :func:`nldr._preimage.nearest_rows`). ``starts="mean"``: one start, the missing entries at the
        neighbours' mean. ``starts="each"``: the problem is solved from each neighbour and the local
        minima are averaged (``weights`` "uniform", or "distance": by inverse root-mean loss); when
        many entries are missing, several branches of the manifold agree with the observed ones, one
        local minimum commits to one branch, and the average has the lower expected squared error
        (it costs ``n_neighbors`` solves). With the squared loss the observed entries start at w;
        with Huber and finite rho they start at the neighbours' values (w may hold gross errors).

        Parameters
        ----------
        X : array, shape (m, n_features_in_)
            New rows; entries where ``mask`` is False are ignored (NaN allowed there).
        mask : bool array, shape (m, n_features_in_)
            True where observed.
        rho : float > 0 or None, default None
            Weight of the squared feature distance against the data loss (data units^2).
        loss : {"squared", "huber"}, default "squared"
            Data loss l on the observed entries (with rho None it only measures neighbour distances).
        delta : float > 0, required with ``loss="huber"``
            Huber threshold, in the units of X.
        n_neighbors : int, default 5
            Training rows nearest on the observed entries, that give the starts.
        starts : {"mean", "each"}, default "mean"
            One start at the neighbours' mean, or one start per neighbour with the results averaged.
        weights : {"uniform", "distance"}, default "uniform"
            How ``starts="each"`` averages its solutions (ignored with "mean").
        max_iter : int, default 500
            Newton iterations per row (``rho=None``) or L-BFGS iterations per block of rows.

        Returns
        -------
        X_hat : array, shape (m, n_features_in_)
        """
        if starts not in ("mean", "each"):
            raise ValueError(f"starts must be 'mean' or 'each'; got {starts!r}")
        if weights not in ("uniform", "distance"):
            raise ValueError(f"weights must be 'uniform' or 'distance'; got {weights!r}")
        if starts == "each":
            solutions, distance = self.complete_each(
                X, mask, rho=rho, loss=loss, delta=delta, n_neighbors=n_neighbors, max_iter=max_iter
            )
            return average_solutions(solutions, distance, weights)
        X, mask, rho, delta = self._check_complete(X, mask, rho, loss, delta)
        nearest, _ = nearest_rows(
            self.X_fit_, X, mask, check_count(n_neighbors, "n_neighbors"), loss=loss, delta=delta
        )
        mean = self.X_fit_[nearest].mean(axis=1, keepdims=True)
        return self._complete_from(X, mask, mean, rho, loss, delta, max_iter)[:, 0]

    def complete_each(
        self,
        X,
        mask,
        *,
        rho=None,
        loss: str = "squared",
        delta=None,
        n_neighbors: int = 5,
        max_iter: int = 500,
    ):
        """The local minima of :meth:`complete`'s problem from each neighbour, before averaging.

        Same parameters as :meth:`complete`. Returns ``(solutions, distance)``: solutions, shape
        (m, k, n_features_in_), the solution from the j-th nearest training row (nearest first), and
        distance, shape (m, k), that row's mean loss on the observed entries (k = min(n_neighbors,
        n_samples)). ``nldr._preimage.average_solutions(solutions[:, :j], distance[:, :j], weights)``
        is ``complete(..., n_neighbors=j, starts="each", weights=weights)`` for any j <= k: up to
        rounding with ``rho=None`` (each row is solved on its own), up to the solver's tolerance with a
        finite rho (rows are solved in blocks that share L-BFGS's stopping test).
        """
        X, mask, rho, delta = self._check_complete(X, mask, rho, loss, delta)
        nearest, distance = nearest_rows(
            self.X_fit_, X, mask, check_count(n_neighbors, "n_neighbors"), loss=loss, delta=delta
        )
        return self._complete_from(X, mask, self.X_fit_[nearest], rho, loss, delta, max_iter), distance

    def _complete_from(self, X, mask, rows, rho, loss, delta, max_iter):
        """Solve every row of X (m, d) from each of its k starts built on ``rows`` (m, k, d) ->
        solutions (m, k, d)."""
        X0 = self._starts(X, mask, rows, rho, loss)
        max_iter = check_count(max_iter, "max_iter")
        with blas_threads_for(self.X_fit_.shape[0]):
            return complete_from_starts(
                self._subspace(), X, mask, X0, rho=rho, loss=loss, delta=delta, max_iter=max_iter
            )

    def _starts(self, X, mask, rows, rho, loss):
        """Starts (m, k, d) from neighbour rows (m, k, d): the observed entries at X (squared loss or
        the hard limit) or at the neighbours' values (Huber with finite rho); rows with nothing
        observed start at the training mean."""
        rows = np.array(rows)
        rows[~mask.any(axis=1)] = self.X_fit_.mean(axis=0)
        if loss == "huber" and rho is not None:
            return rows
        return np.where(mask[:, None, :], np.where(mask, X, 0.0)[:, None, :], rows)

    def _check_complete(self, X, mask, rho, loss, delta):
        check_is_fitted(self)
        # the feature names and count are checked as in transform; then the library's one mask check
        X = validate_data(self, X, reset=False, dtype=np.float64, ensure_all_finite=False)
        X, mask = check_masked_matrix(X, mask, require_observed_columns=False, name="X")
        rho = None if rho is None else check_positive(rho, "rho")
        if loss not in LOSSES:
            raise ValueError(f"loss must be one of {LOSSES}; got {loss!r}")
        if loss == "huber":
            if delta is None:
                raise ValueError("delta (the Huber threshold, units of X) is required with loss='huber'")
            delta = check_positive(delta, "delta")
        return X, mask, rho, delta

    def fit_transform(self, X, y=None):
        """Fit and return the training coordinates ``U diag(l)``, shape (n_samples, n_components_)."""
        self.fit(X)
        return self.eigenvectors_ * self.singular_values_[None, :]

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.pairwise = False
        return tags
