"""Missingness mechanisms of the ``benchmark`` experiment: which entries of a complete matrix are hidden.

Every function takes the complete matrix X, shape (n, d), and a seed, and returns the observation
mask, a bool array of X's shape (True = observed). Three mechanisms (Rubin's taxonomy):

- :func:`mcar_mask`, missing completely at random: every entry hidden independently with probability p,
  ``P(M_ij = 1) = p``.
- :func:`mar_mask`, missing at random: a seeded half of the columns (at least one) are drivers and
  always observed; each other column j is paired with a driver c(j), and its entry in row i is hidden
  with probability ``P(M_ij = 1) = sigmoid(a_j + s z_{i c(j)})``, z the driver's column standardised
  by its mean and sd, s the slope. Whether an entry is hidden depends on an observed value only.
- :func:`mnar_mask`, missing not at random: every column is self-masked, its entry in row i hidden with
  probability ``P(M_ij = 1) = sigmoid(a_j + s z_ij)``, z_ij the entry itself standardised by its
  column's mean and sd: large values are more likely hidden.

The intercept a_j of each column is set (by bisection) so that the column's expected share of hidden
entries over its n rows is its target rate: p for MNAR; for MAR ``p d / (number of masked columns)``
(capped at 0.9), so that the share of hidden entries of the whole matrix is about p for both.

The rule for degenerate draws, the same for every mechanism: every row keeps at least one observed
entry and every column at least :data:`MIN_OBSERVED_PER_COLUMN` observed entries. Where a draw leaves
fewer, hidden entries of that row (column) are restored, chosen uniformly at random by the same
generator, until the rule holds (rows first, then columns; restoring only adds observed entries, so
the rows stay valid). With the benchmark's sizes this touches a few entries per thousand at most.
"""

from __future__ import annotations

import numpy as np

from .._validation import as_float_matrix

__all__ = [
    "MECHANISMS",
    "MIN_OBSERVED_PER_COLUMN",
    "mcar_mask",
    "mar_mask",
    "mar_drivers",
    "mnar_mask",
    "draw_mask",
]

#: mechanism names of :func:`draw_mask`
MECHANISMS = ("MCAR", "MAR", "MNAR")
#: fewest observed entries a column keeps (hold-out CV hides some of them, and needs one left to fit)
MIN_OBSERVED_PER_COLUMN = 2
#: highest target rate of a masked column under MAR
_MAR_MAX_RATE = 0.9


def _check(X, p: float, seed) -> np.ndarray:
    X = as_float_matrix(X, "X")
    if X.shape[0] < MIN_OBSERVED_PER_COLUMN + 1 or X.shape[1] < 2:
        raise ValueError(f"X must have at least 3 rows and 2 columns; got shape {X.shape}")
    if not 0.0 < p < 1.0:
        raise ValueError(f"p must lie in (0, 1); got {p}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise ValueError(f"seed must be an integer; got {seed!r}")
    return X


def _standardised(x: np.ndarray) -> np.ndarray:
    sd = float(np.std(x))
    return (x - x.mean()) / sd if sd > 0 else np.zeros_like(x)


def _intercept(z: np.ndarray, slope: float, rate: float) -> float:
    """The a with mean(sigmoid(a + slope z)) = rate (bisection; the mean is increasing in a)."""
    low, high = -50.0, 50.0
    for _ in range(100):
        mid = 0.5 * (low + high)
        if np.mean(1.0 / (1.0 + np.exp(-(mid + slope * z)))) < rate:
            low = mid
        else:
            high = mid
    return 0.5 * (low + high)


def _enforce(mask: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Restore hidden entries (uniformly at random) until every row has one observed entry and every
    column :data:`MIN_OBSERVED_PER_COLUMN` (the module's rule)."""
    mask = mask.copy()
    for i in np.flatnonzero(~mask.any(axis=1)):
        mask[i, rng.integers(mask.shape[1])] = True
    for j in range(mask.shape[1]):
        short = MIN_OBSERVED_PER_COLUMN - int(mask[:, j].sum())
        if short > 0:
            hidden = np.flatnonzero(~mask[:, j])
            mask[rng.choice(hidden, size=short, replace=False), j] = True
    return mask


def mcar_mask(X, p: float, seed: int) -> np.ndarray:
    """Missing completely at random: each entry hidden independently with probability p.

    Parameters
    ----------
    X : array, shape (n, d), complete (only its shape is used)
    p : float in (0, 1), probability that an entry is hidden
    seed : int

    Returns
    -------
    mask : bool array, shape (n, d), True where observed (the module's rule applied)
    """
    X = _check(X, p, seed)
    rng = np.random.default_rng(seed)
    return _enforce(rng.random(X.shape) >= p, rng)


def mar_mask(X, p: float, seed: int, *, slope: float = 2.0) -> np.ndarray:
    """Missing at random: masked columns hidden with a probability set by a paired, always observed
    driver column (formula in the module docstring).

    Parameters
    ----------
    X : array, shape (n, d), complete
    p : float in (0, 1), about the share of hidden entries of the whole matrix
    seed : int, draws the drivers, the pairing and the mask
    slope : float > 0, default 2.0
        s: the log-odds of hiding rise by s per driver sd (a row one sd above the driver's mean is
        e^2 = 7.4 times more likely, in odds, to lose its paired entry at s = 2).

    Returns
    -------
    mask : bool array, shape (n, d), True where observed; the driver columns fully observed
    """
    X = _check(X, p, seed)
    if not slope > 0:
        raise ValueError(f"slope must be positive; got {slope}")
    rng = np.random.default_rng(seed)
    n, d = X.shape
    drivers, masked = _mar_pairs(rng, d)
    rate = min(_MAR_MAX_RATE, p * d / masked.size)
    mask = np.ones((n, d), dtype=bool)
    for c, j in zip(drivers, masked, strict=True):
        z = _standardised(X[:, c])
        prob = 1.0 / (1.0 + np.exp(-(_intercept(z, slope, rate) + slope * z)))
        mask[:, j] = rng.random(n) >= prob
    return _enforce(mask, rng)


def _mar_pairs(rng: np.random.Generator, d: int) -> tuple[np.ndarray, np.ndarray]:
    order = rng.permutation(d)
    pool, masked = order[: max(1, d // 2)], order[max(1, d // 2) :]
    return rng.choice(pool, size=masked.size), masked


def mar_drivers(d: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The pairs :func:`mar_mask` draws with this seed for d columns: ``(drivers, masked)``, two int
    arrays of equal length, masked column ``masked[k]`` driven by column ``drivers[k]``."""
    return _mar_pairs(np.random.default_rng(seed), d)


def mnar_mask(X, p: float, seed: int, *, slope: float = 2.0) -> np.ndarray:
    """Missing not at random: each entry hidden with a probability rising with its own value
    (formula in the module docstring).

    Parameters
    ----------
    X : array, shape (n, d), complete
    p : float in (0, 1), expected share of hidden entries of each column
    seed : int
    slope : float > 0, default 2.0, s of the module docstring

    Returns
    -------
    mask : bool array, shape (n, d), True where observed
    """
    X = _check(X, p, seed)
    if not slope > 0:
        raise ValueError(f"slope must be positive; got {slope}")
    rng = np.random.default_rng(seed)
    mask = np.ones(X.shape, dtype=bool)
    for j in range(X.shape[1]):
        z = _standardised(X[:, j])
        prob = 1.0 / (1.0 + np.exp(-(_intercept(z, slope, p) + slope * z)))
        mask[:, j] = rng.random(X.shape[0]) >= prob
    return _enforce(mask, rng)


def draw_mask(X, mechanism: str, p: float, seed: int, *, slope: float = 2.0) -> np.ndarray:
    """The mask of ``mechanism`` (one of :data:`MECHANISMS`; ``slope`` is ignored by MCAR)."""
    if mechanism == "MCAR":
        return mcar_mask(X, p, seed)
    if mechanism == "MAR":
        return mar_mask(X, p, seed, slope=slope)
    if mechanism == "MNAR":
        return mnar_mask(X, p, seed, slope=slope)
    raise ValueError(f"mechanism must be one of {', '.join(MECHANISMS)}; got {mechanism!r}")
