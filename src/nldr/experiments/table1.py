"""Table 1 / Figure 3: KPCA rank truncation against the closed-form robust KPCA on noisy oil flow.

One run = one noise level and one noise draw. Both methods see the centred RBF kernel of the noisy
training data; their denoised kernels are compared with the centred kernel of the clean data by the
relative manifold error ||K_est - K_gt||_F^2 / ||K_gt||_F^2 (docs/REPRODUCTION.md gives the evidence
for centring and for the normalisation). KPCA is evaluated at every rank, the closed form at every
tau of a sweep (rho = 1: only tau / rho matters). The best setting of each method is then scored by
1-nearest-neighbour classification of the clean test points projected onto its manifold.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from sklearn.neighbors import KNeighborsClassifier

from .._validation import as_float_matrix, check_positive
from ..kernels import center_cross_kernel, center_kernel, rbf_kernel
from ..robust_kpca import shrink_eigenvalues

__all__ = ["spectral_kernel_errors", "run_noise_level", "summarise", "figure3_curves"]


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


def _nn_error(train_coords, y_train, test_coords, y_test) -> float:
    """Percentage of test points whose nearest training point (Euclidean) has another label.

    NaN for an empty (rank 0) manifold, where every point projects to the origin.
    """
    if train_coords.shape[1] == 0:
        return float("nan")
    clf = KNeighborsClassifier(n_neighbors=1).fit(train_coords, y_train)
    return float(100.0 * np.mean(clf.predict(test_coords) != y_test))


def run_noise_level(
    X_train,
    y_train,
    X_test,
    y_test,
    *,
    noise_std: float,
    seed: int,
    gamma: float,
    max_rank: int,
    taus,
    center: bool = True,
) -> pd.DataFrame:
    """One noise draw of the Table 1 experiment.

    Parameters
    ----------
    X_train : (n, d) clean training data; Gaussian noise of standard deviation ``noise_std`` is added.
    y_train : (n,) int labels.
    X_test : (m, d) clean test data, projected onto each estimated manifold for 1-NN classification.
    y_test : (m,) int labels.
    noise_std : standard deviation of the additive noise (data units).
    seed : seed of the noise draw (numpy ``default_rng``).
    gamma : RBF inverse squared width.
    max_rank : KPCA is evaluated at ranks 1..max_rank.
    taus : 1-d array of trace-norm weights for the closed form (rho = 1).
    center : centre the kernels in feature space.

    Returns
    -------
    DataFrame with one row per evaluated model: columns ``noise_std, seed, method`` ("KPCA" or
    "CFS"), ``tau`` (NaN for KPCA), ``rank``, ``manifold_error``, ``best`` (True on each method's
    lowest manifold error) and ``classification_error`` (percent; only on the best rows).
    """
    X_train = as_float_matrix(X_train, "X_train")
    X_test = as_float_matrix(X_test, "X_test")
    if X_test.shape[1] != X_train.shape[1]:
        raise ValueError(f"X_test must have {X_train.shape[1]} columns; got {X_test.shape[1]}")
    noise_std = check_positive(noise_std, "noise_std", allow_zero=True)
    taus = np.asarray(taus, dtype=np.float64)
    if taus.ndim != 1 or taus.size == 0 or np.any(taus <= 0):
        raise ValueError("taus must be a non-empty 1-d array of positive values")
    n = X_train.shape[0]
    if not 1 <= max_rank <= n:
        raise ValueError(f"max_rank must be between 1 and {n}; got {max_rank}")

    rng = np.random.default_rng(seed)
    X_noisy = X_train + rng.normal(0.0, noise_std, size=X_train.shape)
    K_noisy = rbf_kernel(X_noisy, gamma)
    K_gt = rbf_kernel(X_train, gamma)
    K_test = rbf_kernel(X_test, gamma, X_noisy)
    if center:
        K_test = center_cross_kernel(K_test, K_noisy.mean(axis=0))
        K_noisy, K_gt = center_kernel(K_noisy), center_kernel(K_gt)
    lam, U = np.linalg.eigh(K_noisy)
    lam, U = lam[::-1], U[:, ::-1]

    ranks = np.arange(1, max_rank + 1)
    kpca_spectra = np.where(np.arange(n)[None, :] < ranks[:, None], np.maximum(lam, 0.0)[None, :], 0.0)
    cfs_l = np.stack([shrink_eigenvalues(lam, tau, 1.0) for tau in taus])
    kpca_err = spectral_kernel_errors(U, K_gt, kpca_spectra)
    cfs_err = spectral_kernel_errors(U, K_gt, cfs_l**2)

    frames = [
        pd.DataFrame({"method": "KPCA", "tau": np.nan, "rank": ranks, "manifold_error": kpca_err}),
        pd.DataFrame(
            {"method": "CFS", "tau": taus, "rank": np.count_nonzero(cfs_l, axis=1), "manifold_error": cfs_err}
        ),
    ]
    out = pd.concat(frames, ignore_index=True)
    out.insert(0, "seed", seed)
    out.insert(0, "noise_std", noise_std)
    out["best"] = False
    out["classification_error"] = np.nan

    # Coordinates on each manifold: training points U_k diag(s), test points K_test U_k diag(s / lam)
    # (KPCA: s = sqrt(lam); closed form: s = l, the same shrinkage the fit applied).
    k = int(ranks[np.argmin(kpca_err)])
    s = np.sqrt(lam[:k])
    kpca_cls = _nn_error(U[:, :k] * s, y_train, K_test @ U[:, :k] * (s / lam[:k]), y_test)
    best_tau = int(np.argmin(cfs_err))
    l = cfs_l[best_tau]
    k = int(np.count_nonzero(l))
    cfs_cls = _nn_error(U[:, :k] * l[:k], y_train, K_test @ U[:, :k] * (l[:k] / lam[:k]), y_test)
    for method, errors, cls in (("KPCA", kpca_err, kpca_cls), ("CFS", cfs_err, cfs_cls)):
        idx = out.index[out["method"] == method][int(np.argmin(errors))]
        out.loc[idx, ["best", "classification_error"]] = [True, cls]
    return out


def summarise(runs: pd.DataFrame) -> pd.DataFrame:
    """Aggregate :func:`run_noise_level` frames over noise draws into Table 1's tidy rows.

    Returns columns ``setting, method, metric, value``: per noise level and method the mean and
    standard deviation over draws of the best manifold error and of the 1-NN error, the mean chosen
    rank, and the number of draws.
    """
    best = runs[runs["best"]]
    rows = []
    for std in sorted(best["noise_std"].unique()):
        by_method = {m: best[(best["noise_std"] == std) & (best["method"] == m)] for m in ("KPCA", "CFS")}
        stats = {
            "manifold_error": lambda g: g["manifold_error"].mean(),
            "manifold_error_sd": lambda g: g["manifold_error"].std(ddof=0),
            "classification_error_pct": lambda g: g["classification_error"].mean(),
            "classification_error_pct_sd": lambda g: g["classification_error"].std(ddof=0),
            "best_rank": lambda g: g["rank"].mean(),
            "n_draws": lambda g: float(len(g)),
        }
        for metric, stat in stats.items():
            for method, group in by_method.items():
                rows.append((f"std={std:g}", method, metric, float(stat(group))))
    return pd.DataFrame(rows, columns=["setting", "method", "metric", "value"])


def figure3_curves(runs: pd.DataFrame) -> pd.DataFrame:
    """Per noise level and rank: KPCA's mean error over draws, and the closed form's best (mean over
    draws of the per-draw best at that rank) with its best-to-worst range over every tau and draw.

    Returns columns ``noise_std, method, rank, error, error_min, error_max``.
    """
    kpca = (
        runs[runs["method"] == "KPCA"]
        .groupby(["noise_std", "rank"], as_index=False)["manifold_error"]
        .agg(error="mean", error_min="min", error_max="max")
        .assign(method="KPCA")
    )
    cfs = runs[(runs["method"] == "CFS") & (runs["rank"] > 0)]
    per_draw_best = cfs.groupby(["noise_std", "rank", "seed"])["manifold_error"].min()
    cfs_curve = per_draw_best.groupby(["noise_std", "rank"]).mean().rename("error").reset_index()
    spread = cfs.groupby(["noise_std", "rank"])["manifold_error"].agg(error_min="min", error_max="max")
    cfs_curve = cfs_curve.merge(spread.reset_index(), on=["noise_std", "rank"]).assign(method="CFS")
    cols = ["noise_std", "method", "rank", "error", "error_min", "error_max"]
    return pd.concat([kpca[cols], cfs_curve[cols]], ignore_index=True)
