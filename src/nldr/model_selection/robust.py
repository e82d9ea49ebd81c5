"""Hold-out selection of the regularizer with the Huber data term (:func:`select_huber_regularizer`).

The Huber threshold delta and tau trade off against each other (an outlier pulls with force 2 delta
against the regularizer's tau), so delta is not a free third grid axis here but follows a robust-scale
rule for every candidate (tau, gamma), the one-step M-estimate recipe:

1. the least-squares fit at (tau, gamma) (:class:`~nldr.data_terms.MaskedLeastSquares`);
2. sigma = 1.4826 x the median absolute deviation of its residuals on the training entries (a
   consistent estimate of a Gaussian standard deviation that up to half the residuals being gross
   errors cannot break);
3. delta = ``delta_factor`` x sigma (Huber's 1.345: 95 % efficiency under Gaussian noise);
4. the Huber fit at (tau, gamma, delta) from mean imputation, scored on the fold's hidden entries.

The score is the absolute error per hidden entry by default: the hidden entries are corrupted too, and
a squared score would be dominated by the outliers among them, which no method can predict.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from .._cv import positive_grid, run_jobs, summarise_folds
from .._options import merge_solver_kwargs
from .._validation import check_count, check_positive
from ..baselines import mean_impute
from ..baselines._masked import check_masked_matrix, mean_fill
from ..data_terms import MaskedHuber, MaskedLeastSquares
from ..regularizer import RegularizerResult, minimize_regularized
from .folds import GAMMA_MULTIPLES, check_score, fold_score, holdout_folds, median_gamma

__all__ = ["HuberSelection", "select_huber_regularizer", "robust_scale", "HUBER_EFFICIENCY"]

#: Huber's threshold for 95 % efficiency at the Gaussian, in standard deviations.
HUBER_EFFICIENCY = 1.345


@dataclass(repr=False)
class HuberSelection:
    """Outcome of :func:`select_huber_regularizer`.

    Attributes
    ----------
    tau_, gamma_, delta_ : float
        The chosen trace-norm weight, RBF inverse squared width (1 / units of W squared) and the Huber
        threshold the rule gave for them on every observed entry (units of W).
    cv_results_ : DataFrame
        One row per candidate: ``tau, gamma, mean_test_error, std_test_error, fit_time`` (score per
        hidden entry, mean and sample sd over folds; seconds per fold of both fits).
    result_ : RegularizerResult
        The Huber fit on every observed entry at (tau_, gamma_, delta_).
    folds_ : list of bool arrays, shape (n, d)
    """

    tau_: float
    gamma_: float
    delta_: float
    cv_results_: pd.DataFrame
    result_: RegularizerResult
    folds_: list

    def __repr__(self) -> str:
        return (
            f"HuberSelection(tau_={self.tau_:.4g}, gamma_={self.gamma_:.4g}, delta_={self.delta_:.4g}, "
            f"candidates={len(self.cv_results_)})"
        )


def robust_scale(residuals) -> float:
    """1.4826 x the median absolute deviation from the median of ``residuals`` (1-d, units kept).

    Raises a ValueError if the residuals are empty or the scale is 0 (more than half of them equal).
    """
    r = np.asarray(residuals, dtype=np.float64).ravel()
    if r.size == 0:
        raise ValueError("residuals must not be empty")
    scale = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    if not scale > 0:
        raise ValueError("residuals have zero median absolute deviation: no scale to set delta from")
    return scale


def _huber_fit(W, train, S0, gamma, tau, delta_factor, center, options):
    """Least-squares fit, the delta rule on its training residuals, the Huber fit. Returns (result, delta)."""
    options = merge_solver_kwargs(options, {"gamma": gamma, "tau": tau, "options": {"isolation_guard": True}})
    ls = minimize_regularized(MaskedLeastSquares(W, train), S0, center=center, **options)
    delta = delta_factor * robust_scale((W - ls.x)[train])
    fit = minimize_regularized(MaskedHuber(W, train, delta), S0, center=center, **options)
    return fit, delta


def _huber_fold(W, train, hidden, candidates, delta_factor, center, options, score):
    with threadpool_limits(1):
        S0 = mean_fill(np.where(train, W, 0.0), train)
        rows = []
        for gamma, tau in candidates:
            start = time.perf_counter()
            fit, delta = _huber_fit(W, train, S0, gamma, tau, delta_factor, center, options)
            rows.append(
                {
                    "tau": tau,
                    "gamma": gamma,
                    "delta": delta,
                    "test_error": fold_score(fit.x, W, hidden, score),
                    "fit_time": time.perf_counter() - start,
                }
            )
        return rows


def select_huber_regularizer(
    W,
    mask,
    *,
    taus,
    gammas=None,
    delta_factor: float = HUBER_EFFICIENCY,
    center: bool = False,
    n_folds: int = 3,
    random_state=0,
    holdout: float | None = 0.1,
    score: str = "absolute",
    fold_tol: float = 1e-7,
    fold_gtol: float = 1e-4,
    n_jobs: int = 1,
    **solver_options,
) -> HuberSelection:
    """Choose tau and gamma of the Huber regularizer by hold-out CV, delta by the robust-scale rule.

    Parameters
    ----------
    W : array, shape (n, d)
        The data (possibly with gross errors); entries where ``mask`` is False are ignored.
    mask : bool array, shape (n, d)
        True where observed.
    taus : sequence of float > 0
        Candidate trace-norm weights.
    gammas : sequence of float > 0, optional
        Candidate RBF widths (1 / units of W squared); default :data:`GAMMA_MULTIPLES` times
        :func:`median_gamma`.
    delta_factor : float > 0, default 1.345
        delta = delta_factor x :func:`robust_scale` of the least-squares residuals (module docstring).
    center : bool, default False
    n_folds, random_state, holdout : as in :func:`select_regularizer` (same seed, same folds).
    score : {"squared", "absolute"}, default "absolute"
        Fold score per hidden entry (module docstring).
    fold_tol, fold_gtol : float > 0
        ``tol`` and ``gtol`` of the fold solves (they only rank candidates).
    n_jobs : int >= 1
        Processes over the folds.
    **solver_options
        Passed to :func:`~nldr.regularizer.minimize_regularized` (schedule, ``method``, ``options``).

    Returns
    -------
    HuberSelection
        The candidate with the smallest mean fold score (ties: the first, in increasing gamma then tau),
        refitted on every observed entry by the same rule.
    """
    W, mask = check_masked_matrix(W, mask)
    for key in ("gamma", "tau", "center", "isolation_guard"):
        if key in solver_options or key in (solver_options.get("options") or {}):
            raise ValueError(f"solver option {key!r} is set by select_huber_regularizer; remove it")
    delta_factor = check_positive(delta_factor, "delta_factor")
    score = check_score(score)
    n_jobs = check_count(n_jobs, "n_jobs")
    taus = positive_grid(taus, "taus")
    if gammas is None:
        gammas = np.asarray(GAMMA_MULTIPLES) * median_gamma(W, mask)
    gammas = positive_grid(gammas, "gammas")
    candidates = [(float(g), float(t)) for g in gammas for t in taus]
    fold = {"tol": check_positive(fold_tol, "fold_tol"), "gtol": check_positive(fold_gtol, "fold_gtol")}
    fold_options = merge_solver_kwargs(solver_options, {"options": fold})
    folds = holdout_folds(mask, n_folds, random_state, holdout=holdout)
    jobs = [
        (
            _huber_fold,
            (W, mask & ~hidden, hidden, candidates, delta_factor, bool(center), fold_options, score),
        )
        for hidden in folds
    ]
    rows = [row for fold in run_jobs(jobs, n_jobs) for row in fold]
    cv_results = summarise_folds(rows, ["gamma", "tau"])[
        ["tau", "gamma", "mean_test_error", "std_test_error", "fit_time"]
    ]
    best = int(np.argmin(cv_results["mean_test_error"].to_numpy()))
    tau, gamma = float(cv_results["tau"].iloc[best]), float(cv_results["gamma"].iloc[best])
    with threadpool_limits(1):
        S0 = mean_impute(np.where(mask, W, np.nan), mask)
        result, delta = _huber_fit(W, mask, S0, gamma, tau, delta_factor, bool(center), solver_options)
    return HuberSelection(tau, gamma, delta, cv_results, result, folds)
