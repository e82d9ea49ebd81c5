"""Hold-out selection of the regularizer's tau and kernel width (:func:`select_regularizer`); the
method is described in :mod:`nldr.model_selection`."""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from .._cv import positive_grid, run_jobs, say, summarise_folds
from .._options import merge_solver_kwargs
from .._validation import check_count, check_positive
from ..baselines import mean_impute
from ..baselines._masked import check_masked_matrix, mean_fill
from ..data_terms import MaskedLeastSquares
from ..regularizer import RegularizerResult, minimize_regularized
from .folds import (
    DEFAULT_TAUS,
    GAMMA_MULTIPLES,
    check_score,
    fold_score,
    holdout_folds,
    median_gamma,
)

__all__ = ["RegularizerSelection", "select_regularizer"]


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


def _regularizer_path(
    W, train, hidden, S0, gammas, taus, center, warm_start, warm_gamma, stop, options, score="squared",
    verbose=False, fold=""
):
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
        stage = {**options, "rho0": rho_max, "rho_max": rho_max}  # options carries isolation_guard=True
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
                    **(stage if warm else options),
                )
                previous = res.x
                if k == 0:
                    first = res.x
                rows.append(
                    {
                        "tau": float(tau),
                        "gamma": float(gamma),
                        "test_error": fold_score(res.x, W, hidden, score),
                        "fit_time": time.perf_counter() - start,
                    }
                )
                lowest = min(lowest, rows[-1]["test_error"])
                say(
                    verbose,
                    "select_regularizer",
                    f"{fold}gamma={gamma:.4g} tau={tau:.4g}: hold-out error {rows[-1]['test_error']:.5g} "
                    f"({rows[-1]['fit_time']:.2f} s{', warm' if warm else ''})",
                )
        return rows


def _choose(cv_results: pd.DataFrame, rule: str, n_folds: int) -> int:
    """Row of ``cv_results`` chosen by ``rule`` (see :func:`select_regularizer`)."""
    mean = cv_results["mean_test_error"].to_numpy()
    best = int(np.nanargmin(mean))
    if rule == "min":
        return best
    bound = mean[best] + cv_results["std_test_error"].to_numpy()[best] / np.sqrt(n_folds)
    close = np.flatnonzero(mean <= bound)
    taus, gammas = cv_results["tau"].to_numpy(), cv_results["gamma"].to_numpy()
    smallest = close[taus[close] == taus[close].min()]
    widest = smallest[gammas[smallest] == gammas[smallest].min()]
    return int(widest[np.argmin(mean[widest])])


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
    fold_landmarks: int | None = None,
    refit_options: Mapping | None = None,
    n_jobs: int = 1,
    score: str = "squared",
    verbose: bool = False,
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
        the smallest tau, and among those the widest kernel (smallest gamma), then the smallest mean
        error (module docstring, "Rule").
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
    fold_landmarks : int >= 1, optional
        Opt-in approximation for large n: the fold solves use the Nystroem kernel on this many landmark
        samples (:func:`~nldr.regularizer.minimize_regularized` ``method="nystroem"``), so the hold-out errors
        are those of the approximate solve; the refit (``result_``) is always the exact solve unless
        ``solver_options`` asks otherwise. None (default): every solve exact. At n = 1000,
        ``fold_landmarks=200`` costs about a fifth of an exact evaluation (docs/PERFORMANCE.md).
    n_jobs : int >= 1, default=1
        Processes over the folds (over the (fold, gamma) pairs if ``warm_gamma`` is False); each
        solve runs on one BLAS thread.
    refit_options : mapping, optional
        Further options of the refit's :func:`~nldr.regularizer.minimize_regularized` alone (e.g.
        ``{"method": "nystroem-warm", "options": {"landmarks": 100}}``: a faster path to the exact minimum at
        scale, docs/PERFORMANCE.md#scale); the fold solves do not see them.
    score : {"squared", "absolute"}, default "squared"
        Fold score per hidden entry: squared error, or absolute error (robust to gross outliers among
        the observed entries; :data:`nldr.model_selection.folds.SCORES`).
    verbose : bool, default=False
        Print progress to stdout: a line per candidate solve (its fold, gamma, tau, hold-out error and
        seconds; from the worker processes when ``n_jobs > 1``, which a notebook does not show), a line
        per finished fold job, the choice and the refit.
    **solver_options
        Passed to :func:`~nldr.regularizer.minimize_regularized` (``rho0, rho_growth, rho_max``,
        ``method`` and ``options``, e.g. ``options={"max_inner": 500}``); the option
        ``isolation_guard`` is always on.

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
        if key in solver_options or key in (solver_options.get("options") or {}):
            raise ValueError(f"solver option {key!r} is set by select_regularizer; remove it")
    refit = dict(refit_options or {})
    for key in ("gamma", "tau", "center", "isolation_guard"):
        if key in refit or key in (refit.get("options") or {}):
            raise ValueError(f"refit option {key!r} is set by select_regularizer; remove it")
    n_jobs = check_count(n_jobs, "n_jobs")
    score = check_score(score)
    if rule not in ("one_se", "min"):
        raise ValueError(f"rule must be 'one_se' or 'min'; got {rule!r}")
    if stop_factor is not None and not check_positive(stop_factor, "stop_factor") > 1:
        raise ValueError(f"stop_factor must be > 1 or None; got {stop_factor}")
    stop = np.inf if stop_factor is None else float(stop_factor)
    taus = positive_grid(DEFAULT_TAUS if taus is None else taus, "taus")
    if gammas is None:
        gammas = np.asarray(GAMMA_MULTIPLES) * median_gamma(W, mask)
    gammas = positive_grid(gammas, "gammas")
    fold = {"tol": check_positive(fold_tol, "fold_tol"), "gtol": check_positive(fold_gtol, "fold_gtol")}
    fold_options = merge_solver_kwargs(solver_options, {"options": {**fold, "isolation_guard": True}})
    if fold_landmarks is not None:
        landmarks = check_count(fold_landmarks, "fold_landmarks")
        nystroem = {"method": "nystroem", "options": {"landmarks": landmarks}}
        fold_options = merge_solver_kwargs(fold_options, nystroem)
    folds = holdout_folds(mask, n_folds, random_state, holdout=holdout)
    jobs = []
    for i, hidden in enumerate(folds):
        train = mask & ~hidden
        S0 = mean_fill(np.where(train, W, 0.0), train)
        for group in [gammas] if warm_gamma else [[g] for g in gammas]:
            path = (W, train, hidden, S0, group, taus, bool(center), warm_start, warm_gamma, stop)
            label = f"fold {i + 1}/{len(folds)} "
            jobs.append((_regularizer_path, (*path, fold_options, score, verbose, label)))
    say(verbose, "select_regularizer", f"{len(gammas)} gammas x {len(taus)} taus, {len(folds)} folds")

    def done(finished, total, seconds):
        say(verbose, "select_regularizer", f"fold jobs done: {finished}/{total} ({seconds:.1f} s)")

    rows = [row for path in run_jobs(jobs, n_jobs, done) for row in path]
    grid = pd.MultiIndex.from_product([[float(g) for g in gammas], [float(t) for t in taus]])
    solved = pd.DataFrame(rows).groupby(["gamma", "tau"]).size().reindex(grid, fill_value=0).to_numpy()
    summary = summarise_folds(rows, ["gamma", "tau"]).set_index(["gamma", "tau"]).reindex(grid)
    cv_results = summary.rename_axis(["gamma", "tau"]).reset_index()[
        ["tau", "gamma", "mean_test_error", "std_test_error", "fit_time"]
    ]
    cv_results.loc[solved < len(folds), ["mean_test_error", "std_test_error"]] = np.nan  # path stopped
    best = _choose(cv_results, rule, len(folds))
    tau, gamma = float(cv_results["tau"].iloc[best]), float(cv_results["gamma"].iloc[best])
    say(verbose, "select_regularizer", f"chose tau={tau:.4g}, gamma={gamma:.4g} ({rule}); refitting")
    with threadpool_limits(1):
        result = minimize_regularized(
            MaskedLeastSquares(W, mask),
            mean_impute(W, mask),
            gamma=gamma,
            tau=tau,
            center=bool(center),
            **merge_solver_kwargs(solver_options, refit, {"options": {"isolation_guard": True}}),
        )
    say(verbose, "select_regularizer", f"refit: {result.message}")
    return RegularizerSelection(tau, gamma, cv_results, result, folds)
