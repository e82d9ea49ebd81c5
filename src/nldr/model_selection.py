"""Choosing parameters from the data alone: hold-out cross-validation on the observed entries.

The paper sets tau and the kernel width by hand. With no ground truth, the only honest score of a
setting is how well it predicts entries it did not see: each fold hides a random share of the
*observed* entries, the method completes the matrix from the rest, and the fold's score is the mean
squared error on the hidden entries. The setting with the smallest mean score over the folds wins and is
refitted on every observed entry. A value chosen against ground truth is an oracle and must be labelled
as one; nothing here ever sees ground truth.

- :func:`select_regularizer` chooses (tau, gamma) of :func:`nldr.regularizer.minimize_regularized`
  with the masked least-squares data term (completion; denoising is the all-observed mask).
- :func:`select_imputer` applies the same folds to any imputation method with a knob (PPCA's
  dimension, PKPCA's and RKPCA's width and components): :func:`baseline_grid` gives default grids.

Folds. By default (``holdout=0.1``) each of the ``n_folds`` folds hides a fresh random tenth of the
observed entries (Monte-Carlo folds): the fold problems are nearly as dense as the refit's, which
5-fold partitions (a fifth hidden) are not. ``holdout=None`` deals the shuffled observed entries into
``n_folds`` disjoint groups instead. Either way a column whose observed entries would all be hidden
keeps one of them for training (it is then never scored in that fold), because a method starting
from column means needs one. Same seed, same folds, same answer.

Rule. The default ``rule="one_se"`` takes, among the candidates whose mean hold-out error is within
one standard error of the smallest, the one with the smallest tau (then the smallest error). On
Table 2's protocol the hold-out error is flat in tau from 0.01 to about 1 within that error, so
``"min"`` picks among ties by noise; and a fold solve at a larger tau is warm-started from its
smaller-tau neighbour and stays near it, while the refit starts cold and can land elsewhere (with
5-fold partitions, ``"min"`` chose tau = 3.16 on 2 of 10 masks at p = 0.5: refit SSE 73 and 100,
against 54 and 82 at tau = 0.01). The least regularised of the tied candidates is the one whose fold
solves are cold, like the refit. ``rule="min"`` takes the smallest mean error.

Cost. For the regularizer, the candidates of one fold form paths in tau, solved from the smallest tau
up: the first from mean imputation with the full penalty schedule, every later one warm-started from
its neighbour's solution with the last stage only (rho = rho_max). The neighbour is already close to a
minimiser of the limit problem, so the early stages, whose only purpose is to reach that region from a
poor start, are not needed again. The path goes up, not down, because a large tau can collapse the
samples onto one point (K ~ 1 1^T), a local minimum the last stage at a smaller tau does not leave, so
a downward path would score moderate taus at their over-smoothed neighbour's error. With
``warm_gamma`` (default) the first solve of each gamma is warm-started the same way from the previous
(smaller) gamma's, so a fold has one cold solve. A path stops once a candidate's hold-out error
exceeds ``stop_factor`` (1.5) times the path's best so far: past that the samples are collapsing and
the solves are the slowest of the path. The fold solves stop at looser tolerances (``fold_tol``,
``fold_gtol``) than the refit: they only rank candidates. The mean fill of each fold is shared by its
gammas; the folds are independent and run in parallel with ``n_jobs``. Every solve uses the isolation
guard (:func:`nldr.regularizer.isolation_safe_rho0`), so large tau cannot push hidden entries away.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from itertools import product

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from ._validation import check_count, check_positive
from .baselines import mean_impute, pkpca_impute, ppca_impute, rkpca_impute
from .baselines._masked import check_masked_matrix, mean_fill
from .data_terms import MaskedLeastSquares
from .kernels import squared_distances
from .regularizer import RegularizerResult, minimize_regularized

__all__ = [
    "DEFAULT_TAUS",
    "GAMMA_MULTIPLES",
    "median_gamma",
    "holdout_folds",
    "RegularizerSelection",
    "select_regularizer",
    "ImputerSelection",
    "select_imputer",
    "baseline_grid",
]

#: Default tau grid: log-spaced over four decades around the paper's 0.1 (Table 2) and 10 (denoising).
DEFAULT_TAUS = tuple(float(t) for t in np.logspace(-2, 2, 9))
#: Default widths, as multiples of :func:`median_gamma` (the inverse median squared row distance). Wider
#: kernels than the median rule: on oil flow (Table 2) the paper's 0.075 is 0.26 times it, and 4 times it
#: scored worse than every smaller width in every fold.
GAMMA_MULTIPLES = (0.25, 0.5, 1.0)


# --------------------------------------------------------------------------------------------------
# Folds and grids
# --------------------------------------------------------------------------------------------------


def median_gamma(W, mask) -> float:
    """1 / median squared distance between the rows of W after mean imputation.

    Parameters
    ----------
    W : array, shape (n, d); entries where ``mask`` is False are ignored.
    mask : bool array, shape (n, d), True where observed.

    Returns
    -------
    gamma : float > 0, in 1 / (units of W)^2.
    """
    W, mask = check_masked_matrix(W, mask)
    D = squared_distances(mean_fill(W, mask))
    med = float(np.median(D[np.triu_indices(D.shape[0], 1)]))
    if not med > 0:
        raise ValueError("the rows of W (after mean imputation) coincide: no median distance to set gamma")
    return 1.0 / med


def holdout_folds(
    mask, n_folds: int = 5, random_state=0, *, holdout: float | None = None
) -> list[np.ndarray]:
    """Hidden-entry masks of the cross-validation folds.

    Parameters
    ----------
    mask : bool array, shape (n, d)
        True where observed.
    n_folds : int >= 2
        Number of folds.
    random_state : int or numpy Generator
        Seed of the shuffles; the same seed gives the same folds.
    holdout : float in (0, 1), optional
        None (default): the folds partition the observed entries (each hides about 1/n_folds of
        them). A share: each fold hides round(holdout * n_observed) observed entries drawn afresh
        (Monte-Carlo folds; they may overlap), so the fold problems are as dense as the caller wants.

    Returns
    -------
    folds : list of n_folds bool arrays, shape (n, d)
        True at the entries fold k hides: observed only, and never every observed entry of a column
        (one is kept for training; see the module docstring). Disjoint when ``holdout`` is None.
    """
    mask = np.asarray(mask, dtype=bool)
    n_folds = check_count(n_folds, "n_folds")
    if n_folds < 2:
        raise ValueError(f"n_folds must be >= 2 (one fold would hide every observed entry); got {n_folds}")
    if holdout is not None and not (isinstance(holdout, (int, float)) and 0.0 < holdout < 1.0):
        raise ValueError(f"holdout must be None or a share in (0, 1); got {holdout!r}")
    observed = np.flatnonzero(mask.ravel())
    if observed.size < n_folds:
        raise ValueError(f"mask has {observed.size} observed entries, fewer than n_folds = {n_folds}")
    rng = np.random.default_rng(random_state)
    size = None if holdout is None else max(1, int(round(holdout * observed.size)))
    order = rng.permutation(observed)
    folds = []
    for k in range(n_folds):
        if size is not None and k > 0:
            order = rng.permutation(observed)
        chosen = order[k::n_folds] if size is None else order[:size]
        hidden = np.zeros(mask.size, dtype=bool)
        hidden[chosen] = True
        hidden = hidden.reshape(mask.shape)
        for j in np.flatnonzero(~(mask & ~hidden).any(axis=0)):
            hidden[order[order % mask.shape[1] == j][0] // mask.shape[1], j] = False
        folds.append(hidden)
    return folds


def _positive_grid(values, name: str) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(values, dtype=np.float64))
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-d sequence of numbers; got shape {arr.shape}")
    if not np.all(np.isfinite(arr) & (arr > 0)):
        raise ValueError(f"{name} must all be finite and > 0; got {arr.tolist()}")
    return np.unique(arr)


def _scores(X_hat: np.ndarray, W: np.ndarray, hidden: np.ndarray) -> float:
    diff = (X_hat - W)[hidden]
    return float(diff @ diff) / diff.size


def _summarise(rows: list[dict], keys: Sequence[str]) -> pd.DataFrame:
    frame = pd.DataFrame(rows)
    grouped = frame.groupby(list(keys), sort=True)
    out = grouped["test_error"].agg(mean_test_error="mean", std_test_error="std").reset_index()
    out["fit_time"] = grouped["fit_time"].mean().to_numpy()
    return out


# --------------------------------------------------------------------------------------------------
# The regularizer
# --------------------------------------------------------------------------------------------------


@dataclass(repr=False)
class RegularizerSelection:
    """Outcome of :func:`select_regularizer`.

    Attributes
    ----------
    tau_, gamma_ : float
        The chosen trace-norm weight and RBF inverse squared width (1 / units of W squared).
    cv_results_ : DataFrame
        One row per candidate, sorted by gamma then tau: ``tau, gamma, mean_test_error`` (mean over
        folds of the mean squared error per hidden entry, units of W squared), ``std_test_error``
        (sample standard deviation over folds), ``fit_time`` (mean seconds of the candidate's solve
        per fold; warm-started candidates are cheaper).
    result_ : RegularizerResult
        :func:`~nldr.regularizer.minimize_regularized` on every observed entry at (tau_, gamma_),
        from mean imputation, with the isolation guard.
    folds_ : list of bool arrays, shape (n, d)
        The hidden entries of each fold.
    """

    tau_: float
    gamma_: float
    cv_results_: pd.DataFrame
    result_: RegularizerResult
    folds_: list

    def __repr__(self) -> str:
        return (
            f"RegularizerSelection(tau_={self.tau_:.4g}, gamma_={self.gamma_:.4g}, "
            f"candidates={len(self.cv_results_)}, folds={len(self.folds_)})"
        )


def _regularizer_path(W, train, hidden, S0, gammas, taus, center, warm_start, warm_gamma, stop, options):
    """Solve one fold along ``taus`` (smallest first) for each of ``gammas`` (in the given order).

    Returns rows of (tau, gamma, test_error, fit_time). With ``warm_start`` every tau after the first
    starts from its neighbour's solution with the last penalty stage only; with ``warm_gamma`` the
    first tau of every gamma after the first starts the same way from the previous gamma's first
    solution, so the fold has one cold solve in all. A gamma's path stops (no rows for its larger
    taus) after a tau whose error exceeds ``stop`` times the smallest error of that path so far.
    """
    with threadpool_limits(1):
        data_term = MaskedLeastSquares(W, train)
        rho_max = options.get("rho_max", 1e4)
        stage = {**options, "rho0": rho_max, "rho_max": rho_max}
        rows, first = [], None
        for gamma in gammas:
            previous, lowest = first if warm_gamma else None, np.inf
            for k, tau in enumerate(sorted(taus)):
                if rows and rows[-1]["gamma"] == float(gamma) and rows[-1]["test_error"] > stop * lowest:
                    break
                start = time.perf_counter()
                warm = previous is not None and (warm_start or k == 0)
                res = minimize_regularized(
                    data_term,
                    previous if warm else S0,
                    gamma=gamma,
                    tau=tau,
                    center=center,
                    isolation_guard=True,
                    **(stage if warm else options),
                )
                previous = res.x
                if k == 0:
                    first = res.x
                rows.append(
                    {
                        "tau": float(tau),
                        "gamma": float(gamma),
                        "test_error": _scores(res.x, W, hidden),
                        "fit_time": time.perf_counter() - start,
                    }
                )
                lowest = min(lowest, rows[-1]["test_error"])
        return rows


def _choose(cv_results: pd.DataFrame, rule: str, n_folds: int) -> int:
    """Row of ``cv_results`` chosen by ``rule`` (see :func:`select_regularizer`)."""
    mean = cv_results["mean_test_error"].to_numpy()
    best = int(np.nanargmin(mean))
    if rule == "min":
        return best
    bound = mean[best] + cv_results["std_test_error"].to_numpy()[best] / np.sqrt(n_folds)
    close = np.flatnonzero(mean <= bound)
    taus = cv_results["tau"].to_numpy()
    smallest = close[taus[close] == taus[close].min()]
    return int(smallest[np.argmin(mean[smallest])])


def _run(jobs: list[tuple[Callable, tuple]], n_jobs: int) -> list:
    if n_jobs == 1 or len(jobs) == 1:
        return [fn(*args) for fn, args in jobs]
    with ProcessPoolExecutor(max_workers=min(n_jobs, len(jobs))) as pool:
        futures = [pool.submit(fn, *args) for fn, args in jobs]
        return [f.result() for f in futures]


def select_regularizer(
    W,
    mask,
    *,
    taus=None,
    gammas=None,
    center: bool = False,
    n_folds: int = 5,
    random_state=0,
    holdout: float | None = 0.1,
    rule: str = "one_se",
    warm_start: bool = True,
    warm_gamma: bool = True,
    stop_factor: float | None = 1.5,
    fold_tol: float = 1e-7,
    fold_gtol: float = 1e-4,
    n_jobs: int = 1,
    **solver_options,
) -> RegularizerSelection:
    """Choose tau and the kernel width of the regularizer by hold-out cross-validation.

    Parameters
    ----------
    W : array, shape (n_samples, n_features)
        The data; entries where ``mask`` is False are ignored (they may be NaN).
    mask : bool array, shape (n_samples, n_features)
        True where observed. All True is denoising.
    taus : sequence of float > 0, optional
        Candidate trace-norm weights; default :data:`DEFAULT_TAUS`.
    gammas : sequence of float > 0, optional
        Candidate RBF inverse squared widths (absolute, 1 / units of W squared); default
        :data:`GAMMA_MULTIPLES` times :func:`median_gamma`.
    center : bool, default=False
        Double-centre the kernel (passed to the solver).
    n_folds : int >= 2, default=5
        Folds of :func:`holdout_folds`.
    random_state : int, default=0
        Seed of the folds.
    holdout : float in (0, 1) or None, default=0.1
        Share of the observed entries each fold hides (Monte-Carlo folds, :func:`holdout_folds`); None
        partitions them into ``n_folds`` folds (each hides 1/n_folds). A small share keeps the fold
        problems nearly as dense as the refit's (module docstring, "Folds").
    rule : {"one_se", "min"}, default="one_se"
        "min": the candidate with the smallest mean hold-out error. "one_se": among the candidates whose
        mean error is within one standard error (``std_test_error / sqrt(n_folds)``) of that minimum,
        the smallest tau, and among those the smallest mean error (module docstring, "Rule").
    warm_start : bool, default=True
        Solve each (fold, gamma) path from the smallest tau up, warm-starting every candidate after the
        first from its neighbour with the last penalty stage only (module docstring). False solves every
        candidate from mean imputation with the full schedule.
    warm_gamma : bool, default=True
        Also warm-start the first (smallest-tau) solve of each gamma after the first (in increasing
        gamma) from the previous gamma's, with the last stage only: one cold solve per fold. The
        gammas of a fold then run in one job.
    stop_factor : float > 1 or None, default=1.5
        Early stop of a tau path: in a fold, once a candidate's hold-out error exceeds stop_factor
        times the smallest error of its path so far, the larger taus of that gamma are not solved
        in that fold. A candidate not solved in every fold gets NaN ``mean_test_error`` and
        ``std_test_error`` and is never chosen. None solves every candidate.
    fold_tol, fold_gtol : float > 0, defaults 1e-7, 1e-4
        ``tol`` and ``gtol`` of the fold solves (they override ``solver_options`` there; the refit uses
        ``solver_options``). Looser than the solver's defaults: a fold score only ranks candidates.
    n_jobs : int >= 1, default=1
        Processes over the folds (over the (fold, gamma) pairs if ``warm_gamma`` is False); each
        solve runs on one BLAS thread.
    **solver_options
        Passed to :func:`~nldr.regularizer.minimize_regularized` (``rho0, rho_growth, rho_max,
        max_inner, tol, gtol, eigensolver``); ``isolation_guard`` is always on.

    Returns
    -------
    RegularizerSelection
        ``tau_, gamma_, cv_results_, result_, folds_``. Ties go to the first row of ``cv_results_``.

    Raises
    ------
    ValueError
        Bad shapes, no observed entry in a column, non-positive candidates, fewer observed entries than
        folds, a ``holdout`` outside (0, 1), an unknown ``rule``, or a solver option this function sets
        itself (the message names it).
    """
    W, mask = check_masked_matrix(W, mask)
    for key in ("gamma", "tau", "center", "isolation_guard"):
        if key in solver_options:
            raise ValueError(f"solver option {key!r} is set by select_regularizer; remove it")
    n_jobs = check_count(n_jobs, "n_jobs")
    if rule not in ("one_se", "min"):
        raise ValueError(f"rule must be 'one_se' or 'min'; got {rule!r}")
    if stop_factor is not None and not check_positive(stop_factor, "stop_factor") > 1:
        raise ValueError(f"stop_factor must be > 1 or None; got {stop_factor}")
    stop = np.inf if stop_factor is None else float(stop_factor)
    taus = _positive_grid(DEFAULT_TAUS if taus is None else taus, "taus")
    if gammas is None:
        gammas = np.asarray(GAMMA_MULTIPLES) * median_gamma(W, mask)
    gammas = _positive_grid(gammas, "gammas")
    fold_options = {
        **solver_options,
        "tol": check_positive(fold_tol, "fold_tol"),
        "gtol": check_positive(fold_gtol, "fold_gtol"),
    }
    folds = holdout_folds(mask, n_folds, random_state, holdout=holdout)
    jobs = []
    for hidden in folds:
        train = mask & ~hidden
        S0 = mean_fill(np.where(train, W, 0.0), train)
        for group in [gammas] if warm_gamma else [[g] for g in gammas]:
            path = (W, train, hidden, S0, group, taus, bool(center), warm_start, warm_gamma, stop)
            jobs.append((_regularizer_path, (*path, fold_options)))
    rows = [row for path in _run(jobs, n_jobs) for row in path]
    grid = pd.MultiIndex.from_product([[float(g) for g in gammas], [float(t) for t in taus]])
    solved = pd.DataFrame(rows).groupby(["gamma", "tau"]).size().reindex(grid, fill_value=0).to_numpy()
    summary = _summarise(rows, ["gamma", "tau"]).set_index(["gamma", "tau"]).reindex(grid)
    cv_results = summary.rename_axis(["gamma", "tau"]).reset_index()[
        ["tau", "gamma", "mean_test_error", "std_test_error", "fit_time"]
    ]
    cv_results.loc[solved < len(folds), ["mean_test_error", "std_test_error"]] = np.nan  # path stopped
    best = _choose(cv_results, rule, len(folds))
    tau, gamma = float(cv_results["tau"].iloc[best]), float(cv_results["gamma"].iloc[best])
    with threadpool_limits(1):
        result = minimize_regularized(
            MaskedLeastSquares(W, mask),
            mean_impute(W, mask),
            gamma=gamma,
            tau=tau,
            center=bool(center),
            isolation_guard=True,
            **solver_options,
        )
    return RegularizerSelection(tau, gamma, cv_results, result, folds)


# --------------------------------------------------------------------------------------------------
# Any imputation method (the baselines)
# --------------------------------------------------------------------------------------------------


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


def _imputer_fold(impute, W, train, hidden, candidates):
    with threadpool_limits(1):
        rows = []
        W_train = np.where(train, W, np.nan)
        for k, params in enumerate(candidates):
            start = time.perf_counter()
            X_hat = _completed(impute(W_train, train, **params))
            seconds = time.perf_counter() - start
            rows.append({"candidate": k, "test_error": _scores(X_hat, W, hidden), "fit_time": seconds})
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

    Returns
    -------
    ImputerSelection
    """
    W, mask = check_masked_matrix(W, mask)
    n_jobs = check_count(n_jobs, "n_jobs")
    if not callable(impute):
        raise ValueError(f"impute must be callable as impute(W, mask, **params); got {type(impute).__name__}")
    names = list(param_grid)
    values = [list(param_grid[name]) for name in names]
    if any(len(v) == 0 for v in values):
        raise ValueError("param_grid must give at least one value per parameter")
    candidates = [dict(zip(names, combo, strict=True)) for combo in product(*values)]
    folds = holdout_folds(mask, n_folds, random_state)
    jobs = [(_imputer_fold, (impute, W, mask & ~hidden, hidden, candidates)) for hidden in folds]
    rows = [row for fold in _run(jobs, n_jobs) for row in fold]
    summary = _summarise(rows, ["candidate"])
    params = pd.DataFrame(candidates, columns=names) if names else pd.DataFrame(index=range(1))
    cv_results = pd.concat([params, summary.drop(columns="candidate")], axis=1)
    best = int(np.argmin(cv_results["mean_test_error"].to_numpy()))
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
    from .baselines import peers

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
