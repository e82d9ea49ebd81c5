"""One hold-out search for every knob of every method: :class:`HoldoutSearch`.

Folds hide observed entries (an entry is a number of X; NaN marks a missing one). Each candidate of
the grid completes every fold's training matrix (X with the fold's hidden entries set to NaN), and
its score on the fold is its error on the hidden entries. The folds depend only on the mask and the
seed, so every method searched on one matrix sees the same folds.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable, Mapping, Sequence
from numbers import Integral, Real

import numpy as np
import pandas as pd
from sklearn.base import BaseEstimator, TransformerMixin, _fit_context, clone
from sklearn.model_selection import ParameterGrid
from sklearn.utils._param_validation import HasMethods, Interval, StrOptions

from .._cv import run_jobs, say, summarise_folds
from .._threads import single_blas_thread
from ._folds import SCORES, EntryFolds, fold_score
from ._rules import RULES, choose, reference_index

__all__ = ["HoldoutSearch", "RULES"]



def _validate(estimator) -> None:
    """The estimator's own parameter validation, without fitting: scikit-learn's
    ``_validate_params`` (its declared ``_parameter_constraints``; the library's estimators add their
    cross-parameter rules to it), of the estimator and of the estimators among its parameters (a
    Pipeline's steps, IterativeImputer's regressor)."""
    for value in estimator.get_params(deep=False).values():
        if isinstance(value, BaseEstimator):
            _validate(value)
        elif isinstance(value, list):  # Pipeline steps: (name, estimator) pairs
            for item in value:
                if isinstance(item, tuple) and len(item) == 2 and isinstance(item[1], BaseEstimator):
                    _validate(item[1])
    if hasattr(estimator, "_parameter_constraints") and hasattr(estimator, "_validate_params"):
        estimator._validate_params()


def _score(scoring, X, X_hat, hidden) -> float:
    """Error of ``X_hat`` against ``X`` on the ``hidden`` entries (lower is better)."""
    if callable(scoring):
        return float(scoring(X, X_hat, hidden))
    return fold_score(np.asarray(X_hat, dtype=np.float64), X, hidden, scoring)


def _masked(X, hidden):
    return np.where(hidden, np.nan, X)


class _Fold:
    """One fold: the rows the estimator is fitted on (None: transductive, every row), hidden entries,
    and optionally the scored rows as the estimator sees them (default: with their hidden entries NaN)."""

    def __init__(self, hidden, fit_rows=None, inputs=None):
        self.hidden, self.fit_rows, self.inputs = hidden, fit_rows, inputs

    def complete(self, estimator, X):
        """The estimator's completion of the scored rows of X, and those rows' hidden entries."""
        if self.fit_rows is None:
            return estimator.fit_transform(_masked(X, self.hidden)), X, self.hidden
        apply = ~self.fit_rows
        estimator.fit(_masked(X[self.fit_rows], self.hidden[self.fit_rows]))
        inputs = _masked(X[apply], self.hidden[apply]) if self.inputs is None else self.inputs
        return estimator.transform(inputs), X[apply], self.hidden[apply]


def _solve(estimator, fold, X, scoring, error_score, derive, move):
    """Fit one candidate on one fold; a row ``test_error``, ``fit_time`` (seconds) and, with
    ``move``, the estimator's ``move_`` (NaN if the fit failed)."""
    start = time.perf_counter()
    moved = np.nan
    try:
        if derive is not None:
            rows = slice(None) if fold.fit_rows is None else fold.fit_rows
            estimator.set_params(**derive(clone(estimator), _masked(X[rows], fold.hidden[rows])))
        X_hat, X_true, hidden = fold.complete(estimator, X)
        error = _score(scoring, X_true, X_hat, hidden)
        if move:
            moved = getattr(estimator, "move_", None)
            if moved is None:
                raise ValueError(
                    f"min_move needs the estimator's fitted attribute move_; {type(estimator).__name__} "
                    "has none: set min_move=None"
                )
            moved = float(moved)
    except Exception:
        if isinstance(error_score, str):
            raise
        error = float(error_score)
    row = {"test_error": error, "fit_time": time.perf_counter() - start}
    return {**row, "move": moved} if move else row


def _fold_job(estimator, candidates, fold_params, fold, X, path, stop, scoring, error_score, derive, move,
              verbose, label):
    """Every candidate on one fold: rows (candidate, test_error, fit_time[, move]). Along a ``path`` the
    candidates of one group (same parameters but ``path``) share one warm-started estimator, and the
    first of every group after the first starts from a copy of the previous group's first fit."""
    with single_blas_thread():
        rows = []
        if path is None:
            for k, params in enumerate(candidates):
                est = clone(estimator).set_params(**params, **fold_params)
                rows.append({"candidate": k, **_solve(est, fold, X, scoring, error_score, derive, move)})
                _said(verbose, label, params, rows[-1])
            return rows
        groups: dict = {}
        for k, params in enumerate(candidates):
            key = tuple(sorted((n, repr(v)) for n, v in params.items() if n != path))
            groups.setdefault(key, []).append(k)
        warm = "warm_start" in estimator.get_params()
        previous_first = None
        for members in groups.values():
            est, lowest, first = None, np.inf, None
            for k in members:
                if rows and rows[-1]["candidate"] in members and rows[-1]["test_error"] > stop * lowest:
                    break
                params = candidates[k]
                if not warm:
                    est = clone(estimator).set_params(**fold_params)
                elif est is None:
                    est = clone(estimator) if previous_first is None else copy.deepcopy(previous_first)
                    est.set_params(**fold_params, warm_start=previous_first is not None)
                est.set_params(**params)
                row = _solve(est, fold, X, scoring, error_score, derive, move)
                if warm:
                    est.set_params(warm_start=True)
                    if first is None:
                        first = copy.deepcopy(est)
                rows.append({"candidate": k, **row})
                lowest = min(lowest, row["test_error"])
                _said(verbose, label, params, row)
            previous_first = first
        return rows


def _said(verbose, label, params, row) -> None:
    say(verbose, "HoldoutSearch", f"{label}{params}: error {row['test_error']:.5g} ({row['fit_time']:.2f} s)")


class HoldoutSearch(TransformerMixin, BaseEstimator):
    """Hold-out search of an imputer's parameters on masked entries, refitted on every entry.

    Works for any estimator whose ``fit_transform(X)`` completes a matrix with NaN at its missing
    entries (every imputer of :mod:`nldr.impute`, scikit-learn's ``KNNImputer``, ``SimpleImputer`` and
    ``IterativeImputer``, a ``Pipeline`` ending in one). Every candidate of ``param_grid`` completes
    each fold's training matrix (X with the fold's hidden entries set to NaN), and scores the error on
    the hidden entries; the rule chooses among the mean errors, and the chosen parameters are refitted
    on X.

    Entries and folds. An entry is one number of X. By default the folds are
    :class:`EntryFolds` (``n_folds``, ``holdout``, ``random_state``) over the observed entries:
    they depend only on the mask and the seed, so the same folds serve every method on a matrix.
    ``folds`` replaces them with any fold set over X's entries, for problems whose unit of
    observation spans several entries: for NRSfM tracks W (F, 2P) (row f: the x then the y image
    coordinates of the P points), a fold hiding the (frame, point) pairs ``h`` (F, P) is the entry
    mask ``np.hstack([h, h])``, and ``scoring`` can score per point. A fold can also fit on some rows
    and score others (``(fit_rows, hidden)``: ``fit`` on the fit rows, ``transform`` of the others
    with their hidden entries set to NaN): completion of new rows against a manifold learnt on others.
    A triple ``(fit_rows, hidden, inputs)`` transforms ``inputs`` instead, the scored rows (in X's
    order) as the estimator is to see them, and scores the output against X on the hidden entries:
    for a denoiser, X's rows corrupted by a simulated noise, scored against the clean X.

    Parameters
    ----------
    estimator : estimator
        Cloned for every fit; never fitted itself.
    param_grid : dict of name -> sequence, or list of such dicts
        As scikit-learn's ``ParameterGrid``; candidates are in its order.
    n_folds : int >= 2, default 5
    holdout : float in (0, 1) or None, default None
        Folds partition the observed entries (None) or each hides this share afresh.
    random_state : int, default 0
        Seed of the default folds.
    folds : object with ``split(X)``, or sequence, optional
        The folds, instead of ``EntryFolds(n_folds, holdout=holdout, random_state=random_state)``:
        each a bool array of X's shape (True: hidden; a subset of the observed entries, not empty), or
        a pair ``(fit_rows, hidden)`` with ``fit_rows`` a bool array (n,), or a triple
        ``(fit_rows, hidden, inputs)`` with ``inputs`` an array (rows not in fit_rows, d) (see above).
    rule : {"min", "one_se", "reference"}, default "min"
        "min": the smallest mean hold-out error. "one_se": among the candidates within one standard
        error (``std / sqrt(n_folds)``) of the smallest, filtered by ``prefer`` in turn, then the
        smallest mean error. "reference": the ``reference`` candidate (a default), unless some
        candidates beat it by more than one standard error of the paired fold differences: with
        d_k = error_k(candidate) - error_k(reference) in fold k, those with ``mean(d) + sd(d) /
        sqrt(n_folds) < 0``; then the one of those with the smallest mean error. It leaves a default
        only on evidence, for scores whose differences between candidates are smaller than their
        spread over folds but consistent from fold to fold. Every rule chooses among the eligible
        candidates (``min_move``). Ties go to the first candidate.
    reference : dict, optional
        With ``rule="reference"`` (and only then): the default's parameters; exactly one candidate
        must have them (numbers compared with ``numpy.isclose``).
    prefer : sequence of str, default ()
        The one-SE rule's order of simplicity: parameter names, each keeping its smallest value among
        the remaining candidates ("-name": its largest). The regularizer's is ``("tau", "gamma")``: the
        smallest tau, then the widest kernel.
    scoring : {"squared", "absolute"} or callable, default "squared"
        Error per hidden entry (mean squared or mean absolute), or ``scoring(X, X_hat, hidden)``
        returning a float (lower is better).
    fold_params : dict, optional
        Parameters set on the fold fits only (looser tolerances, an approximate kernel); the refit
        uses the estimator's own.
    path : str, optional
        A parameter solved as a path: in a fold, the candidates that differ only in it are fitted in
        the grid's order of that parameter. If the estimator has a ``warm_start`` parameter, they
        share one estimator with ``warm_start=True`` (each fit starts from the previous one's
        answer), and the first candidate of every later group starts from a copy of the previous
        group's first fit; otherwise each is fitted cold. None: every candidate is fitted cold, in
        the grid's order.
    stop_factor : float > 1, optional
        Along a ``path``: once a candidate's error exceeds stop_factor times the smallest error of its
        path so far in a fold, the rest of that path is not solved in that fold (those candidates get
        NaN and are never chosen).
    derive : callable, optional
        ``derive(estimator, X_train) -> dict`` of parameters set on each fit just before it from its
        own training matrix (a threshold from a robust scale of a preliminary fit, say); called for
        the fold fits and the refit.
    min_move : float >= 0, optional
        For estimators that start from another method's answer and report how far a fit moved from
        it in the fitted attribute ``move_`` (a float, e.g. the relative change of the estimate): a
        candidate whose ``move_`` is below ``min_move`` in every fold is inactive and not eligible,
        since its score is the start's, not the method's. If no candidate is active, all are
        eligible. None (default): every candidate is eligible and ``move_`` is not read.
    refit : bool, default True
        Refit the chosen candidate on X (``best_estimator_``).
    n_jobs : int >= 1, default 1
        Processes over the folds (the estimator must be picklable).
    error_score : "raise" or float, default "raise"
        What a fit that raises scores; NaN marks the candidate failed.
    verbose : bool, default False
        A line per candidate fit, per fold and for the choice (stdout).

    Attributes
    ----------
    cv_results_ : dict of numpy arrays
        As scikit-learn's ``GridSearchCV`` (``pandas.DataFrame(cv_results_)`` tabulates it), one entry
        per candidate: ``params``, ``param_<name>``, ``split<k>_test_error``, ``mean_test_error``,
        ``std_test_error`` (sample standard deviation over folds), ``rank_test_error``,
        ``mean_fit_time`` (seconds), ``n_solved`` (folds in which it was solved); with ``min_move``
        also ``max_move`` (the largest ``move_`` over folds) and ``active``; with
        ``rule="reference"`` also ``mean_diff_reference`` and ``se_diff_reference`` (mean and
        standard error over folds of the candidate's error minus the reference's). Errors, not scores:
        lower is better. A candidate with a NaN error in any fold, or not solved in every fold, has NaN
        mean and std and is never chosen.
    best_index_ : int
    best_params_ : dict
    best_score_ : float
        Mean hold-out error of the chosen candidate (lower is better).
    best_estimator_ : estimator
        The chosen candidate fitted on X (when ``refit``).
    folds_ : list of bool arrays
        The hidden entries of each fold.
    n_splits_ : int

    Raises
    ------
    ValueError
        Before any fit: a bad option of the search, an unknown or invalid parameter of a candidate or of
        ``fold_params`` (every candidate is cloned, set and validated first), a fold that hides nothing
        or hides an unobserved entry. After the folds: every candidate failed.

    See Also
    --------
    EntryFolds : The default folds over the observed entries.
    sklearn.model_selection.GridSearchCV : The same interface for supervised estimators.

    Notes
    -----
    A value chosen on ground truth is an oracle; this search sees only the observed entries. The
    regularizer's grid and rule, and what they choose on the paper's data:
    docs/REPRODUCTION.md#selection.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[1.0, 2.0, 3.0], [2.0, np.nan, 5.9], [3.0, 6.1, 9.0],
    ...               [4.0, 7.9, np.nan], [5.0, 9.9, 15.1], [6.0, 12.0, 18.0]])
    >>> from nldr.impute import SoftImputer
    >>> from nldr.model_selection import HoldoutSearch
    >>> search = HoldoutSearch(SoftImputer(), {"lam": [0.1, 1.0, 10.0]}, n_folds=2).fit(X)
    >>> sorted(search.best_params_), search.n_splits_, len(search.cv_results_["params"])
    (['lam'], 2, 3)
    >>> X_hat = search.transform(X)  # the chosen candidate, refitted on every observed entry
    >>> X_hat.shape, bool(np.isnan(X_hat).any())
    ((6, 3), False)
    """

    def __init__(
        self,
        estimator,
        param_grid,
        *,
        n_folds: int = 5,
        holdout: float | None = None,
        random_state=0,
        folds=None,
        rule: str = "min",
        prefer: Sequence[str] = (),
        scoring: str | Callable = "squared",
        fold_params: Mapping | None = None,
        path: str | None = None,
        stop_factor: float | None = None,
        derive: Callable | None = None,
        reference: Mapping | None = None,
        min_move: float | None = None,
        refit: bool = True,
        n_jobs: int = 1,
        error_score="raise",
        verbose: bool = False,
    ):
        self.estimator = estimator
        self.param_grid = param_grid
        self.n_folds = n_folds
        self.holdout = holdout
        self.random_state = random_state
        self.folds = folds
        self.rule = rule
        self.prefer = prefer
        self.scoring = scoring
        self.fold_params = fold_params
        self.path = path
        self.stop_factor = stop_factor
        self.derive = derive
        self.reference = reference
        self.min_move = min_move
        self.refit = refit
        self.n_jobs = n_jobs
        self.error_score = error_score
        self.verbose = verbose

    # -- validation, all before the first fit ---------------------------------------------------

    _parameter_constraints: dict = {
        "estimator": [HasMethods(["fit", "fit_transform"])],
        "param_grid": [dict, list],
        "n_folds": [Interval(Integral, 2, None, closed="left")],
        "holdout": [Interval(Real, 0, 1, closed="neither"), None],
        "random_state": [Interval(Integral, 0, None, closed="left"), np.random.Generator, None],
        "folds": [HasMethods(["split"]), "array-like", None],
        "rule": [StrOptions(set(RULES))],
        "prefer": [list, tuple],
        "scoring": [StrOptions(set(SCORES)), callable],
        "fold_params": [dict, None],
        "path": [str, None],
        "stop_factor": [Interval(Real, 1, np.inf, closed="neither"), None],
        "derive": [callable, None],
        "reference": [dict, None],
        "min_move": [Interval(Real, 0, np.inf, closed="left"), None],
        "refit": ["boolean"],
        "n_jobs": [Interval(Integral, 1, None, closed="left")],
        "error_score": [StrOptions({"raise"}), Real],
        "verbose": ["verbose"],
    }

    def _candidates(self) -> list[dict]:
        try:
            candidates = list(ParameterGrid(self.param_grid))
        except (TypeError, ValueError) as err:
            raise ValueError(f"param_grid: {err}") from err
        if not candidates:
            raise ValueError("param_grid gives no candidate")
        fold_params = dict(self.fold_params or {})
        for params in candidates:
            for extra in ({}, fold_params):
                try:
                    est = clone(self.estimator).set_params(**params, **extra)
                except ValueError as err:
                    raise ValueError(f"candidate {params} (fold_params {extra}): {err}") from err
                try:
                    _validate(est)
                except (TypeError, ValueError) as err:
                    raise ValueError(f"candidate {params} (fold_params {extra}): {err}") from err
        if self.path is not None:
            if not all(self.path in params for params in candidates):
                raise ValueError(f"path={self.path!r} must be a parameter of every candidate of param_grid")
        for name in self.prefer:
            if not all(name.lstrip("-") in params for params in candidates):
                raise ValueError(f"prefer: {name.lstrip('-')!r} is not a parameter of every candidate")
        return candidates

    def _validate_params(self):
        """The declared constraints, then the rule that ties two parameters together."""
        super()._validate_params()
        if self.stop_factor is not None and self.path is None:
            raise ValueError("stop_factor applies along a path: set path too, or stop_factor=None")

    def _folds(self, X) -> list[_Fold]:
        observed = ~np.isnan(X)
        raw = self.folds
        if raw is None:
            raw = EntryFolds(self.n_folds, holdout=self.holdout, random_state=self.random_state)
        raw = raw.split(X) if hasattr(raw, "split") else list(raw)
        if len(raw) < 1:
            raise ValueError("folds gives no fold")
        folds = []
        for k, fold in enumerate(raw):
            fit_rows, hidden, inputs = (*fold, None)[:3] if isinstance(fold, tuple) else (None, fold, None)
            hidden = np.asarray(hidden)
            if hidden.shape != X.shape or hidden.dtype != bool:
                raise ValueError(f"fold {k}: hidden entries must be a bool array of X's shape {X.shape}")
            if not hidden.any():
                raise ValueError(
                    f"fold {k} hides no entry: the mask of X ({int(observed.sum())} observed of {X.size}; "
                    f"fewest per column {int(observed.sum(axis=0).min())}) leaves the fold nothing to "
                    "hide, as a column keeps one observed entry for training; observe more entries"
                )
            if np.any(hidden & ~observed):
                raise ValueError(f"fold {k} hides entries that are missing in X: hide observed entries only")
            if fit_rows is not None:
                fit_rows = np.asarray(fit_rows, dtype=bool)
                if fit_rows.shape != (X.shape[0],) or fit_rows.all() or not fit_rows.any():
                    raise ValueError(f"fold {k}: fit_rows must be bool ({X.shape[0]},), neither all nor none")
            if inputs is not None:
                inputs = np.asarray(inputs, dtype=np.float64)
                if fit_rows is None or inputs.shape != (int((~fit_rows).sum()), X.shape[1]):
                    raise ValueError(
                        f"fold {k}: inputs must come with fit_rows and hold the scored rows, shape "
                        f"(number of rows not in fit_rows, {X.shape[1]})"
                    )
            folds.append(_Fold(hidden, fit_rows, inputs))
        return folds

    # -- the search ---------------------------------------------------------------------------------

    def _search(self, X):
        X = np.asarray(X, dtype=np.float64) if not hasattr(X, "to_numpy") else X.to_numpy(dtype=np.float64)
        if X.ndim != 2 or X.size == 0:
            raise ValueError(f"X must be a non-empty 2-d array (NaN where missing); got shape {X.shape}")
        if np.isinf(X).any():
            raise ValueError("X has infinite entries; mark missing entries with NaN")
        candidates = self._candidates()
        reference = reference_index(candidates, self.rule, self.reference)
        folds = self._folds(X)
        stop = np.inf if self.stop_factor is None else float(self.stop_factor)
        fold_params = dict(self.fold_params or {})
        say(self.verbose, "HoldoutSearch", f"{len(candidates)} candidates, {len(folds)} folds")
        jobs = [
            (
                _fold_job,
                (self.estimator, candidates, fold_params, fold, X, self.path, stop, self.scoring,
                 self.error_score, self.derive, self.min_move is not None, self.verbose,
                 f"fold {k + 1}/{len(folds)} "),
            )
            for k, fold in enumerate(folds)
        ]

        def done(finished, total, seconds):
            say(self.verbose, "HoldoutSearch", f"folds done: {finished}/{total} ({seconds:.1f} s)")

        per_fold = run_jobs(jobs, int(self.n_jobs), done)
        self._results(candidates, per_fold, reference)
        self.folds_ = [fold.hidden for fold in folds]
        self.n_splits_ = len(folds)
        mean = self.cv_results_["mean_test_error"]
        if not np.isfinite(mean).any():
            raise ValueError(
                f"every candidate failed: no candidate has a finite hold-out error in all {len(folds)} "
                "folds (a fit returned NaN or raised); check the estimator on this X"
            )
        r = self.cv_results_
        paired = None if reference is None else (r["mean_diff_reference"], r["se_diff_reference"])
        self.best_index_ = choose(
            mean, r["std_test_error"], len(folds), self.rule, self.prefer, candidates, r.get("active"),
            reference, paired,
        )  # fmt: skip
        self.best_params_ = dict(candidates[self.best_index_])
        self.best_score_ = float(mean[self.best_index_])
        say(self.verbose, "HoldoutSearch", f"chose {self.best_params_} ({self.rule})")
        return X

    def _results(self, candidates, per_fold, reference=None):
        rows = [{**row, "fold": k} for k, fold in enumerate(per_fold) for row in fold]
        frame = pd.DataFrame(rows)
        summary = summarise_folds(rows, ["candidate"]).set_index("candidate").reindex(range(len(candidates)))
        split = np.full((len(per_fold), len(candidates)), np.nan)
        split[frame["fold"].to_numpy(), frame["candidate"].to_numpy()] = frame["test_error"].to_numpy()
        failed = ~np.isfinite(split).all(axis=0)
        mean = summary["mean_test_error"].to_numpy(dtype=np.float64).copy()
        std = summary["std_test_error"].to_numpy(dtype=np.float64).copy()
        mean[failed], std[failed] = np.nan, np.nan
        results = {"params": np.array(candidates, dtype=object)}
        for name in dict.fromkeys(n for c in candidates for n in c):
            results[f"param_{name}"] = np.array([c.get(name) for c in candidates], dtype=object)
        for k in range(len(per_fold)):
            results[f"split{k}_test_error"] = split[k]
        order = np.argsort(np.where(np.isfinite(mean), mean, np.inf), kind="stable")
        rank = np.empty(len(candidates), dtype=np.int64)
        rank[order] = np.arange(1, len(candidates) + 1)
        results.update(
            mean_test_error=mean,
            std_test_error=std,
            rank_test_error=rank,
            mean_fit_time=summary["fit_time"].to_numpy(dtype=np.float64),
        )
        solved = np.zeros(len(candidates), dtype=np.int64)
        np.add.at(solved, frame["candidate"].to_numpy(), 1)
        results["n_solved"] = solved
        if self.min_move is not None:
            moves = np.full(split.shape, np.nan)
            moves[frame["fold"].to_numpy(), frame["candidate"].to_numpy()] = frame["move"].to_numpy()
            largest = np.max(np.where(np.isnan(moves), -np.inf, moves), axis=0)
            results["max_move"] = np.where(np.isfinite(largest), largest, np.nan)
            results["active"] = largest >= float(self.min_move)
        if reference is not None:
            diff = split - split[:, [reference]]  # paired by fold; NaN where either failed
            results["mean_diff_reference"] = diff.mean(axis=0)
            results["se_diff_reference"] = diff.std(axis=0, ddof=1) / np.sqrt(diff.shape[0])
        self.cv_results_ = results

    def _best(self, X):
        est = clone(self.estimator).set_params(**self.best_params_)
        if self.derive is not None:
            est.set_params(**self.derive(clone(est), X))
        return est

    # the estimator and its candidates are the user's: validated by _candidates, not skipped
    @_fit_context(prefer_skip_nested_validation=False)
    def fit(self, X, y=None):
        """Search on X (array (n, d), NaN where missing) and, with ``refit``, fit the chosen candidate."""
        X = self._search(X)
        if self.refit:
            with single_blas_thread():
                self.best_estimator_ = self._best(X).fit(X)
        return self

    @_fit_context(prefer_skip_nested_validation=False)
    def fit_transform(self, X, y=None):
        """Search on X, refit the chosen candidate with its ``fit_transform(X)`` and return that (n, d)."""
        X = self._search(X)
        with single_blas_thread():
            self.best_estimator_ = self._best(X)
            return self.best_estimator_.fit_transform(X)

    def transform(self, X):
        """``best_estimator_.transform(X)``."""
        if not hasattr(self, "best_estimator_"):
            raise ValueError("HoldoutSearch is not fitted with refit=True; call fit first")
        return self.best_estimator_.transform(X)
