"""Orthographic reprojection data term of NRSfM (paper eq. 12-13), for the regularizer's loop.

f(X) = sum_{f,j} Z_fj ||w_f(x_j) - R_f s_f(x_j)||^2 with shapes as rows X (F, 3P), image tracks as
rows W (F, 2P), cameras R (F, 2, 3) and the visibility mask Z (F, P); see :mod:`nldr.nrsfm._layout`
and the data-term protocol in :mod:`nldr.data_terms`.

Also the pieces the other NRSfM modules share: the input checks (:func:`check_cameras`,
:func:`check_tracks`, :func:`check_shapes`), the batched per-frame residual (:func:`visibility_weights`,
:func:`masked_residual`) of the first-order TNH, the camera LM and the camera/shape alternation, and the
energies with cameras as arguments: :func:`reprojection_error` and :func:`tnh_energy`. The kernel
method's energy is :func:`nldr.nrsfm._joint_kernel.kernel_energy`.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp

from .._validation import as_float_matrix, check_magnitude, check_positive

__all__ = [
    "OrthographicReprojection",
    "check_cameras",
    "check_tracks",
    "check_shapes",
    "visibility_weights",
    "masked_residual",
    "reprojection_error",
    "tnh_energy",
]


def check_cameras(R, n_frames: int | None = None, name: str = "R") -> np.ndarray:
    """Validate cameras: a finite float array of shape (F, 2, 3) (rows need not be orthonormal)."""
    R = as_float_matrix(R, name, ndim=3)
    if R.shape[1:] != (2, 3):
        raise ValueError(
            f"{name} must have shape (F, 2, 3); got {R.shape} (stacked (2F, 3) cameras: reshape(F, 2, 3))"
        )
    if n_frames is not None and R.shape[0] != n_frames:
        raise ValueError(f"{name} must hold one camera per frame, {n_frames}; got {R.shape[0]}")
    return R


class OrthographicReprojection:
    """f(X) = sum_{f,j} mask_fj ||w_f(x_j) - R_f s_f(x_j)||^2, the NRSfM data term with known cameras.

    Residuals are ordered like the observed entries of ``W2d`` in C order (frame, image coordinate,
    point). They are linear in X, so the Jacobian is a constant sparse matrix built once; it has 3
    non-zeros per residual.

    Parameters
    ----------
    W2d : array, shape (F, 2P)
        Image tracks as rows: row f is (x_f1..x_fP, y_f1..y_fP), in the length unit of the shapes.
        Entries of unobserved points are ignored (they may be NaN).
    visible : bool array, shape (F, P), or None
        True where point j is observed in frame f (both coordinates); None: all observed.
    R : array, shape (F, 2, 3)
        Orthographic cameras: w_f(x_j) = R_f s_f(x_j).

    Attributes
    ----------
    shape : tuple (F, 3P)
        Shape of the variable X (shapes as rows).
    W : array, shape (F, 2P)
        Image tracks with unobserved entries set to 0.
    R : array, shape (F, 2, 3)
    mask : bool array, shape (F, P)
    n_residuals : int
        2 x number of observed (frame, point) pairs.
    """

    def __init__(self, W2d, visible, R):
        W, mask = check_tracks(W2d, visible, min_points=0)
        F, P = mask.shape
        mask2 = np.concatenate([mask, mask], axis=1)  # (F, 2P), same layout as W2d
        if not mask.any():
            raise ValueError("mask has no visible point: there is nothing to reconstruct from")
        check_magnitude(W[mask2], "W2d")
        empty = np.flatnonzero(~mask.any(axis=1))
        if empty.size:
            warnings.warn(
                f"frames {empty.tolist()[:10]}{' ...' if empty.size > 10 else ''} have no visible point: "
                "the data term does not constrain their shapes (only a regularizer does)",
                UserWarning,
                stacklevel=2,
            )
        self.n_frames, self.n_points = F, P
        self.shape = (F, 3 * P)
        self.W = W
        self.mask = mask
        self._mask2 = mask2
        self._observed = np.flatnonzero(mask2.ravel())
        self.n_residuals = int(self._observed.size)
        self.R = check_cameras(R, F)
        self._J = self._build_jacobian()

    def _build_jacobian(self) -> sp.csr_matrix:
        # Residual i is the observed entry (f, c, j) of W: r_i = W[f, cP + j] - sum_k R[f, c, k] X[f, kP + j],
        # so row i has -R[f, c, k] at column f*3P + k*P + j, k = 0, 1, 2.
        F, P = self.n_frames, self.n_points
        f, rest = np.divmod(self._observed, 2 * P)
        c, j = np.divmod(rest, P)
        k = np.arange(3)
        rows = np.repeat(np.arange(self.n_residuals), 3)
        cols = (f[:, None] * 3 * P + k[None, :] * P + j[:, None]).ravel()
        vals = -self.R[f[:, None], c[:, None], k[None, :]].ravel()
        return sp.csr_matrix((vals, (rows, cols)), shape=(self.n_residuals, F * 3 * P))

    def project(self, X: np.ndarray) -> np.ndarray:
        """Image tracks (F, 2P) of shapes X (F, 3P) under the cameras, all points (mask ignored)."""
        F, P = self.n_frames, self.n_points
        return np.einsum("fck,fkp->fcp", self.R, self._check_X(X).reshape(F, 3, P)).reshape(F, 2 * P)

    def _check_X(self, X) -> np.ndarray:
        if np.shape(X) != self.shape:
            raise ValueError(f"X must have shape (F, 3P) = {self.shape} (shapes as rows); got {np.shape(X)}")
        return X

    def residuals(self, X: np.ndarray) -> np.ndarray:
        """Observed W minus projection, shape (n_residuals,), in image length units."""
        return (self.W - self.project(X)).ravel()[self._observed]

    def jacobian(self, X: np.ndarray | None = None) -> sp.csr_matrix:
        """d residuals / d vec(X) (C order), shape (n_residuals, 3FP); constant, ``X`` is unused."""
        return self._J

    def value(self, X: np.ndarray) -> float:
        """f(X), the sum of squared reprojection errors over observed points (length unit squared)."""
        r = self.residuals(X)
        return float(r @ r)

    def gradient(self, X: np.ndarray) -> np.ndarray:
        """df/dX = -2 R_f^T (mask o (w_f - R_f s_f)) per frame, shape (F, 3P)."""
        F, P = self.n_frames, self.n_points
        E = np.where(self._mask2, self.W - self.project(X), 0.0).reshape(F, 2, P)
        return -2.0 * np.einsum("fck,fcp->fkp", self.R, E).reshape(self.shape)


# The batched per-frame form used by the first-order TNH, the camera LM and the camera/shape alternation
# (no sparse Jacobian): tracks W3 (F, 2, P) zero where unobserved, shapes S (F, 3, P), cameras R (F, 2, 3).


def check_tracks(W2d, mask, *, min_points: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Validate image tracks and their visibility for the camera estimation.

    W2d (F, 2P) are the tracks (unobserved entries ignored, may be NaN), ``mask`` (F, P) or None (all
    observed); every frame needs ``min_points`` observed points (an orthographic camera has 5 degrees of
    freedom). Returns the tracks with zeros where unobserved and the bool mask.
    """
    W2d = as_float_matrix(W2d, "W2d", allow_nan=True)
    if W2d.shape[1] % 2:
        raise ValueError(f"W2d must have shape (F, 2P) (image tracks as rows); got {W2d.shape}")
    F, P = W2d.shape[0], W2d.shape[1] // 2
    mask = np.ones((F, P), dtype=bool) if mask is None else np.asarray(mask)
    if mask.dtype != bool:
        if not (np.issubdtype(mask.dtype, np.number) and np.isin(mask, (0, 1)).all()):
            raise ValueError("mask must be boolean (or 0/1): True where point j is observed in frame f")
        mask = mask.astype(bool)
    if mask.shape != (F, P):
        raise ValueError(f"mask must have shape (F, P) = {(F, P)}; got {mask.shape}")
    mask2 = np.concatenate([mask, mask], axis=1)
    if not np.all(np.isfinite(W2d[mask2])):
        raise ValueError("W2d has NaN or infinite values at observed entries (where mask is True)")
    counts = mask.sum(axis=1)
    if np.any(counts < min_points):
        bad = np.flatnonzero(counts < min_points)
        raise ValueError(
            f"mask must leave at least {min_points} observed points in every frame (an orthographic camera "
            f"has 5 degrees of freedom); frames {bad[:10].tolist()} have fewer"
        )
    return np.where(mask2, W2d, 0.0), mask


def check_shapes(X, F: int, P: int, name: str = "X") -> np.ndarray:
    """Validate shapes as rows: a finite float array of shape (F, 3P)."""
    X = as_float_matrix(X, name)
    if X.shape != (F, 3 * P):
        raise ValueError(f"{name} must have shape (F, 3P) = {(F, 3 * P)}; got {X.shape}")
    return X


def visibility_weights(mask: np.ndarray) -> np.ndarray | None:
    """Visibility (F, P) as 0.0/1.0 weights (F, 1, P) broadcasting over image rows; None if all observed."""
    return None if mask.all() else mask[:, None, :].astype(float)


def masked_residual(W3: np.ndarray, m3: np.ndarray | None, R: np.ndarray, S: np.ndarray) -> np.ndarray:
    """mask o (W - R S) per frame (F, 2, P) from the tracks W3 (F, 2, P) (zero where unobserved), ``m3``
    from :func:`visibility_weights` (None: all observed), cameras R (F, 2, 3) and shapes S (F, 3, P)."""
    E = W3 - R @ S
    if m3 is not None:
        E *= m3
    return E


def reprojection_error(W2d, mask, R, X) -> float:
    """Sum over the points (f, j) where ``mask`` is True of ``||w_f(x_j) - R_f s_f(x_j)||^2`` (both
    image coordinates; unit of the tracks squared): the data term with cameras R.

    Tracks W2d (F, 2P) (finite where ``mask`` is True), ``mask`` (F, P) or None (all points), cameras R
    (F, 2, 3) known or estimated, shapes X (F, 3P).
    """
    W, mask = check_tracks(W2d, mask, min_points=0)
    F, P = mask.shape
    R, X = check_cameras(R, F), check_shapes(X, F, P)
    squared = np.sum((W.reshape(F, 2, P) - R @ X.reshape(F, 3, P)) ** 2, axis=1)[mask]
    return float(squared.sum())


def tnh_energy(W2d, mask, R, X, tau: float) -> float:
    """TNH's energy tau ||X||_* + :func:`reprojection_error` over the observed points (unit of the
    tracks squared), with cameras R (F, 2, 3) known or estimated and shapes X (F, 3P)."""
    error = reprojection_error(W2d, mask, R, X)  # validates W2d, mask, R and X
    nuclear = float(np.linalg.svd(np.asarray(X, float), compute_uv=False).sum())
    return check_positive(tau, "tau") * nuclear + error
