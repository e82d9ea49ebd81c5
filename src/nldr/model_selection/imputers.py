"""Hold-out selection of any imputation method's keyword arguments (:func:`select_imputer`) and the
default grids of the baselines and peers (:func:`baseline_grid`)."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from itertools import product

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from .._cv import run_jobs, say, summarise_folds
from .._validation import check_count
from ..baselines import peers, pkpca_impute, ppca_impute, rkpca_impute
from ..baselines._masked import check_masked_matrix, mean_fill
from .folds import GAMMA_MULTIPLES, check_score, fold_score, holdout_folds, median_gamma

__all__ = ["ImputerSelection", "select_imputer", "baseline_grid"]


@dataclass(repr=False)
class ImputerSelection:
    """Outcome of :func:`select_imputer`.

    Attributes
    ----------
    best_params_ : dict
        The chosen keyword arguments of the method.
    cv_results_ : DataFrame
        One row per candidate: one column per parameter, ``mean_test_error, std_test_error`` (mean
        squared error per hidden entry over the folds, units of W squared), ``fit_time`` (mean seconds).
    result_ : object
        The method's output refitted on every observed entry with ``best_params_``.
    folds_ : list of bool arrays, shape (n, d)
    """

    best_params_: dict
    cv_results_: pd.DataFrame
    result_: object
    folds_: list

    def __repr__(self) -> str:
        return f"ImputerSelection(best_params_={self.best_params_!r}, candidates={len(self.cv_results_)})"


def _completed(output) -> np.ndarray:
    return np.asarray(getattr(output, "x", output), dtype=np.float64)


def _imputer_fold(impute, W, train, hidden, candidates, score="squared", verbose=False, fold=""):
    with threadpool_limits(1):
        rows = []
        W_train = np.where(train, W, np.nan)
        for k, params in enumerate(candidates):
            start = time.perf_counter()
            X_hat = _completed(impute(W_train, train, **params))
            seconds = time.perf_counter() - start
            error = fold_score(X_hat, W, hidden, score)
            rows.append({"candidate": k, "test_error": error, "fit_time": seconds})
            say(verbose, "select_imputer", f"{fold}{params}: hold-out error {error:.5g} ({seconds:.2f} s)")
        return rows


def select_imputer(
    impute: Callable,
    W,
    mask,
    param_grid: Mapping[str, Sequence],
    *,
    n_folds: int = 5,
    random_state=0,
    n_jobs: int = 1,
    score: str = "squared",
    verbose: bool = False,
) -> ImputerSelection:
    """Choose the keyword arguments of an imputation method by hold-out cross-validation.

    Parameters
    ----------
    impute : callable ``impute(W, mask, **params)``
        Returns the completed (n, d) matrix, or a result whose ``x`` is that matrix (every baseline of
        :mod:`nldr.baselines`). It receives W with NaN at the entries it must not see.
    W : array, shape (n, d); entries where ``mask`` is False are ignored.
    mask : bool array, shape (n, d), True where observed.
    param_grid : mapping of parameter name to a non-empty sequence of values
        Every combination is a candidate (as scikit-learn's ``ParameterGrid``); see
        :func:`baseline_grid`.
    n_folds, random_state : as in :func:`select_regularizer` (same seed, same folds).
    n_jobs : int >= 1
        Processes over the folds (``impute`` must then be picklable).
    score : {"squared", "absolute"}, default "squared"
        Fold score per hidden entry: squared error, or absolute error (robust to gross outliers among
        the observed entries; :data:`nldr.model_selection.folds.SCORES`). ``cv_results_`` holds it.
    verbose : bool, default=False
        Print progress to stdout: a line per candidate fit (its fold, parameters, hold-out error and
        seconds; from the worker processes when ``n_jobs > 1``), a line per finished fold, the choice.

    Returns
    -------
    ImputerSelection
    """
    W, mask = check_masked_matrix(W, mask)
    n_jobs = check_count(n_jobs, "n_jobs")
    score = check_score(score)
    if not callable(impute):
        raise ValueError(f"impute must be callable as impute(W, mask, **params); got {type(impute).__name__}")
    names = list(param_grid)
    values = [list(param_grid[name]) for name in names]
    if any(len(v) == 0 for v in values):
        raise ValueError("param_grid must give at least one value per parameter")
    candidates = [dict(zip(names, combo, strict=True)) for combo in product(*values)]
    folds = holdout_folds(mask, n_folds, random_state)
    name = getattr(impute, "__name__", type(impute).__name__)
    say(verbose, "select_imputer", f"{name}: {len(candidates)} candidates, {len(folds)} folds")
    jobs = [
        (_imputer_fold, (impute, W, mask & ~h, h, candidates, score, verbose, f"fold {i + 1}/{len(folds)} "))
        for i, h in enumerate(folds)
    ]

    def done(finished, total, seconds):
        say(verbose, "select_imputer", f"folds done: {finished}/{total} ({seconds:.1f} s)")

    rows = [row for fold in run_jobs(jobs, n_jobs, done) for row in fold]
    summary = summarise_folds(rows, ["candidate"])
    params = pd.DataFrame(candidates, columns=names) if names else pd.DataFrame(index=range(1))
    cv_results = pd.concat([params, summary.drop(columns="candidate")], axis=1)
    best = int(np.argmin(cv_results["mean_test_error"].to_numpy()))
    say(verbose, "select_imputer", f"chose {candidates[best]}; refitting on every observed entry")
    with threadpool_limits(1):
        result = impute(np.where(mask, W, np.nan), mask, **candidates[best])
    return ImputerSelection(candidates[best], cv_results, result, folds)


def baseline_grid(method: str, W, mask) -> tuple[Callable, dict]:
    """Default ``(impute, param_grid)`` of a baseline or a peer, for :func:`select_imputer`.

    The paper's baselines with a knob (Table 2):

    - ``"PPCA"``: latent dimension 1 .. d-1.
    - ``"PKPCA"``: width (multiples :data:`GAMMA_MULTIPLES` of :func:`median_gamma`) and components
      (the variance rule, or 2, 4, 8).
    - ``"RKPCA"``: width as PKPCA, components 2, 4, 7, 10 (below n).

    The peers of :mod:`nldr.baselines.peers` (not in the paper):

    - ``"KNNImputer"``: ``n_neighbors`` 1, 2, 3, 5, 10, 20, 50 (below n) x ``weights`` uniform, distance.
    - ``"IterativeImputer"``: no knob (BayesianRidge learns its own penalty); the grid is the one fixed
      setting, ``{}``.
    - ``"missForest"``: ``max_features`` 1/3 (missForest's sqrt(d) rule near d = 12) and 1 (every
      column, scikit-learn's regression default); 10 trees, 5 sweeps, seed 0.
    - ``"SoftImpute"``: ``lam`` = :data:`nldr.baselines.peers.SOFT_IMPUTE_FRACTIONS` times the largest
      singular value of the centred mean-filled matrix (at that value and above, Z = 0).

    Parameters
    ----------
    method : {"PPCA", "PKPCA", "RKPCA", "KNNImputer", "IterativeImputer", "missForest", "SoftImpute"}
    W, mask : the data (n, d) and its observation mask (the grid's widths and sizes depend on them).

    Returns
    -------
    impute : callable ``impute(W, mask, **params)``
    param_grid : dict of parameter name -> list of candidate values (every combination is a candidate)
    """

    W, mask = check_masked_matrix(W, mask)
    n, d = W.shape
    if method == "PPCA":
        return ppca_impute, {"n_components": list(range(1, d))}
    if method == "KNNImputer":
        neighbours = [k for k in (1, 2, 3, 5, 10, 20, 50) if k < n]
        return peers.knn_impute, {"n_neighbors": neighbours, "weights": list(peers.KNN_WEIGHTS)}
    if method == "IterativeImputer":
        return peers.iterative_impute, {}
    if method == "missForest":
        return peers.missforest_impute, {"max_features": [1 / 3, 1.0]}
    if method == "SoftImpute":
        filled = mean_fill(W, mask)
        top = float(np.linalg.svd(filled - filled.mean(axis=0), compute_uv=False)[0])
        return peers.soft_impute, {"lam": [float(f * top) for f in peers.SOFT_IMPUTE_FRACTIONS]}
    gammas = [float(g) for g in np.asarray(GAMMA_MULTIPLES) * median_gamma(W, mask)]
    if method == "PKPCA":
        return pkpca_impute, {"gamma": gammas, "n_components": [None] + [q for q in (2, 4, 8) if q < n]}
    if method == "RKPCA":
        return rkpca_impute, {"gamma": gammas, "n_components": [q for q in (2, 4, 7, 10) if q < n]}
    known = ("PPCA", "PKPCA", "RKPCA", "KNNImputer", "IterativeImputer", "missForest", "SoftImpute")
    raise ValueError(f"method must be one of {', '.join(map(repr, known))}; got {method!r}")
