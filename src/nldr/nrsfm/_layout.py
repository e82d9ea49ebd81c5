"""Array layouts of NRSfM data: the benchmark's stacked matrices <-> the library's samples-as-rows.

The CMU mocap files (Akhter et al. 2009) stack frames vertically:

- 3D shapes ``S`` (3F, P): rows 3f, 3f+1, 3f+2 hold X, Y, Z of the P points in frame f;
- image tracks ``W`` (2F, P): rows 2f, 2f+1 hold image x, y of frame f;
- cameras ``Rs`` (2F, 3): rows 2f, 2f+1 are the orthographic projection of frame f.

The library treats each frame as one sample (a row), so the regulariser sees shapes as points in
R^{3P} (:func:`stack_to_rows`; cameras ``Rs.reshape(F, 2, 3)``):

- shapes ``X`` (F, 3P): row f is ``S[3f:3f+3, :].ravel()`` (C order: all X, then all Y, then all Z);
- image tracks ``W`` (F, 2P): row f is ``W[2f:2f+2, :].ravel()`` (all x, then all y);
- cameras ``R`` (F, 2, 3).

A visibility mask is a bool array (F, P), True where point j is observed (both image coordinates)
in frame f: :func:`random_visibility_mask` draws the paper's missing-data masks,
:func:`visibility_folds` the hold-out folds of :mod:`nldr.nrsfm._selection`.
"""

from __future__ import annotations

import numpy as np

from .._validation import as_float_matrix, check_count, check_positive

__all__ = [
    "stack_to_rows",
    "random_visibility_mask",
    "visibility_folds",
]


def stack_to_rows(M, dim: int = 3) -> np.ndarray:
    """Stacked per-frame blocks (dim*F, P) -> samples as rows (F, dim*P).

    ``M`` is ``S`` (dim=3, 3D shapes) or ``W`` (dim=2, image tracks) with the frames stacked
    vertically; row f of the result is ``M[dim*f:dim*f+dim, :].ravel()`` (all x, then all y, ...).
    """
    M = as_float_matrix(M, "M", allow_nan=True)
    if dim not in (2, 3):
        raise ValueError(f"dim must be 3 (shapes) or 2 (image tracks); got {dim!r}")
    dim = int(dim)
    if M.shape[0] % dim:
        raise ValueError(f"M must have a multiple of dim={dim} rows (dim per frame); got shape {M.shape}")
    F, P = M.shape[0] // dim, M.shape[1]
    return M.reshape(F, dim * P).copy()


def random_visibility_mask(
    n_frames: int, n_points: int, missing_fraction: float, random_state=None
) -> np.ndarray:
    """Remove a fraction of the 2D point observations uniformly at random.

    Exactly ``round(missing_fraction * F * P)`` (frame, point) pairs are hidden, chosen uniformly
    without replacement (a point is hidden in both image coordinates at once), as in the paper's
    "randomly removing 50% of the image measurements" (Section 4.3).

    Parameters
    ----------
    n_frames, n_points : int
        F and P.
    missing_fraction : float in [0, 1)
    random_state : None, int or numpy.random.Generator

    Returns
    -------
    mask : bool array, shape (F, P)
        True where the point is observed.
    """
    F, P = check_count(n_frames, "n_frames"), check_count(n_points, "n_points")
    frac = check_positive(missing_fraction, "missing_fraction", allow_zero=True)
    if frac >= 1.0:
        raise ValueError(f"missing_fraction must be in [0, 1); got {missing_fraction!r}")
    rng = np.random.default_rng(random_state)
    n_missing = int(round(frac * F * P))
    mask = np.ones(F * P, dtype=bool)
    mask[rng.choice(F * P, size=n_missing, replace=False)] = False
    return mask.reshape(F, P)


def visibility_folds(
    mask, n_folds: int = 3, random_state=0, *, holdout_fraction: float | None = None
) -> list[np.ndarray]:
    """Hidden 2D points of the cross-validation folds: disjoint subsets of the observed points.

    The observed (frame, point) pairs are shuffled with ``random_state``; fold k hides the k-th chunk
    of ``round(holdout_fraction * n_observed)`` of them (default: the k-th of ``n_folds`` equal shares,
    a partition), then un-hides points, in shuffled order, until every frame keeps 3 training points (an
    orthographic camera has 5 degrees of freedom) and every point 1 frame. A frame or point with fewer
    observations than that in ``mask`` itself is never hidden.

    Parameters
    ----------
    mask : bool array, shape (F, P)
        True where point j is observed in frame f.
    n_folds : int >= 2, default 3
    random_state : int or numpy Generator, default 0
        Seed of the shuffle: the same seed gives the same folds.
    holdout_fraction : float in (0, 1 / n_folds], optional
        Share of the observed points each fold hides (before the un-hiding above); default 1 / n_folds.

    Returns
    -------
    folds : list of n_folds bool arrays, shape (F, P)
        True at the points fold k hides: observed, disjoint across folds.
    """
    mask = np.asarray(mask)
    if mask.ndim != 2 or mask.dtype != bool:
        raise ValueError(f"mask must be a 2-d bool array (F, P); got dtype {mask.dtype}, shape {mask.shape}")
    n_folds = check_count(n_folds, "n_folds")
    if n_folds < 2:
        raise ValueError(f"n_folds must be >= 2; got {n_folds}")
    if holdout_fraction is None:
        frac = 1.0 / n_folds
    else:
        frac = check_positive(holdout_fraction, "holdout_fraction")
        if frac * n_folds > 1.0 + 1e-12:
            raise ValueError(
                f"holdout_fraction * n_folds must be <= 1 (the folds are disjoint); got {frac} * {n_folds}"
            )
    observed = np.flatnonzero(mask.ravel())
    if observed.size < n_folds:
        raise ValueError(f"mask has {observed.size} observed points, fewer than n_folds = {n_folds}")
    order = np.random.default_rng(random_state).permutation(observed)
    size = observed.size // n_folds if holdout_fraction is None else int(round(frac * observed.size))
    F, P = mask.shape
    folds = []
    for k in range(n_folds):
        chunk = order[k::n_folds] if holdout_fraction is None else order[k * size : (k + 1) * size]
        hidden = np.zeros(mask.size, dtype=bool)
        hidden[chunk] = True
        hidden = hidden.reshape(F, P)
        for axis, minimum in ((1, 3), (0, 1)):  # training points per frame, frames per point
            train = (mask & ~hidden).sum(axis=axis)
            for idx in np.flatnonzero(train < minimum):
                # un-hide this frame's (point's) hidden points in shuffled order until it has enough
                line = chunk[(chunk // P == idx) if axis == 1 else (chunk % P == idx)]
                need = minimum - train[idx]
                for flat in line[:need]:
                    hidden[flat // P, flat % P] = False
        folds.append(hidden)
    return folds
