"""The one hold-out search (nldr.model_selection.HoldoutSearch) on scikit-learn's imputers and toys."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.experimental import enable_iterative_imputer  # noqa: F401
from sklearn.impute import IterativeImputer, KNNImputer, SimpleImputer

from nldr.model_selection import EntryFolds, HoldoutSearch, holdout_folds
from nldr.model_selection._rules import choose as _choose


def data(n=30, d=5, p=0.2, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, 2)) @ rng.normal(size=(2, d)) + 0.1 * rng.normal(size=(n, d))
    mask = rng.random((n, d)) >= p
    mask[0] = True
    return X, np.where(mask, X, np.nan)


class Fill(TransformerMixin, BaseEstimator):
    """Column means times ``scale`` at the missing entries; counts its fits; NaN output if ``fail``."""

    fits = 0

    def __init__(self, scale=1.0, fail=False, warm_start=False):
        self.scale = scale
        self.fail = fail
        self.warm_start = warm_start

    def fit(self, X, y=None):
        type(self).fits += 1
        if self.scale == "boom":
            raise RuntimeError("boom")
        self.start_ = self.value_ if (self.warm_start and hasattr(self, "value_")) else None
        self.value_ = float(self.scale)
        self.means_ = np.nanmean(X, axis=0) * self.scale
        return self

    def transform(self, X):
        out = np.where(np.isnan(X), self.means_, X)
        return np.full_like(out, np.nan) if self.fail else out


def test_fold_errors_are_the_hand_computed_hidden_entry_errors_and_the_refit_is_the_estimator():
    _, W = data()
    grid = {"strategy": ["mean", "median"]}
    search = HoldoutSearch(SimpleImputer(), grid, n_folds=3, random_state=4).fit(W)
    folds = holdout_folds(~np.isnan(W), 3, 4)
    for k, hidden in enumerate(folds):
        train = np.where(hidden, np.nan, W)
        for c, strategy in enumerate(grid["strategy"]):
            fill = getattr(np, f"nan{strategy}")(train, axis=0)
            diff = (np.where(np.isnan(train), fill, train) - W)[hidden]
            assert search.cv_results_[f"split{k}_test_error"][c] == pytest.approx(np.mean(diff**2), rel=1e-12)
    means = np.array([search.cv_results_[f"split{k}_test_error"] for k in range(3)])
    np.testing.assert_allclose(search.cv_results_["mean_test_error"], means.mean(axis=0), rtol=1e-12)
    np.testing.assert_allclose(search.cv_results_["std_test_error"], means.std(axis=0, ddof=1), rtol=1e-12)
    best = int(np.argmin(means.mean(axis=0)))
    assert search.best_index_ == best and search.best_params_ == {"strategy": grid["strategy"][best]}
    assert search.best_score_ == search.cv_results_["mean_test_error"][best]
    expected = SimpleImputer(strategy=grid["strategy"][best]).fit(W)
    np.testing.assert_array_equal(search.transform(W[:5]), expected.transform(W[:5]))
    np.testing.assert_array_equal(search.fit_transform(W), expected.transform(W))
    assert [f.tolist() for f in search.folds_] == [f.tolist() for f in folds]
    assert len(pd.DataFrame(search.cv_results_)) == 2


def test_knn_and_iterative_imputers_run_unwrapped_and_same_seed_gives_same_search():
    _, W = data(n=25)
    grid = {"n_neighbors": [1, 3, 5], "weights": ["uniform", "distance"]}
    a = HoldoutSearch(KNNImputer(), grid, random_state=2).fit(W)
    b = HoldoutSearch(KNNImputer(), grid, random_state=2, n_jobs=2).fit(W)
    np.testing.assert_array_equal(a.cv_results_["mean_test_error"], b.cv_results_["mean_test_error"])
    assert a.best_params_ == b.best_params_
    it = HoldoutSearch(IterativeImputer(random_state=0), {"max_iter": [3]}, n_folds=2).fit(W)
    assert np.isfinite(it.best_score_)


def test_a_candidate_scoring_nan_is_never_chosen():
    _, W = data()
    # the failing candidate comes first: argmin over a NaN-first array would return it
    search = HoldoutSearch(Fill(), {"fail": [True, False]}, n_folds=3).fit(W)
    assert np.isnan(search.cv_results_["mean_test_error"][0])
    assert search.best_params_ == {"fail": False}


def test_a_candidate_failing_in_one_fold_only_is_never_chosen():
    _, W = data()

    def score(X, X_hat, hidden):  # candidate scale=1 fails in the fold hiding entry (0, 0)
        mean = np.nanmean(np.where(hidden, np.nan, X)[:, 0])
        return np.nan if hidden[0, 0] and X_hat[0, 0] == mean else 1.0

    folds = holdout_folds(~np.isnan(W), 3, 0)
    assert any(f[0, 0] for f in folds)
    search = HoldoutSearch(Fill(), {"scale": [1.0, 2.0]}, folds=folds, scoring=score).fit(W)
    assert np.isnan(search.cv_results_["mean_test_error"][0]) and search.best_index_ == 1


def test_every_candidate_failing_raises_saying_so():
    _, W = data()
    with pytest.raises(ValueError, match="every candidate failed"):
        HoldoutSearch(Fill(fail=True), {"scale": [1.0, 2.0]}, n_folds=3).fit(W)
    with pytest.raises(ValueError, match="every candidate failed"):
        HoldoutSearch(Fill(), {"scale": ["boom"]}, n_folds=3, error_score=np.nan).fit(W)


@pytest.mark.parametrize(
    ("grid", "extra", "match"),
    [
        ({"scael": [1.0]}, {}, "scael"),
        ({"scale": [1.0]}, {"fold_params": {"tol": 1e-3}}, "tol"),
        ({"scale": [1.0]}, {"rule": "best"}, "rule"),
        ({"scale": [1.0]}, {"scoring": "l2"}, "scoring"),
        ({"scale": [1.0]}, {"stop_factor": 2.0}, "path"),
        ({"scale": [1.0]}, {"prefer": ("tau",)}, "prefer"),
        ({"fail": [False]}, {"path": "scale"}, "path"),
        ({"scale": [1.0]}, {"path": "scale", "stop_factor": 1.0}, "stop_factor"),
        ({"scale": []}, {}, "param_grid"),
    ],
)
def test_every_option_of_the_search_and_its_fits_is_checked_before_any_fit(grid, extra, match):
    _, W = data()
    Fill.fits = 0
    with pytest.raises(ValueError, match=match):
        HoldoutSearch(Fill(), grid, **extra).fit(W)
    assert Fill.fits == 0


def test_an_invalid_parameter_value_is_refused_by_the_estimators_own_validation_before_any_fit():
    _, W = data()
    # the second candidate is bad: the first would have been solved in every fold before it
    with pytest.raises(ValueError, match="weights"):
        HoldoutSearch(KNNImputer(), {"weights": ["uniform", "uniformm"]}).fit(W)
    # a nested estimator's parameter (IterativeImputer's regressor) too
    from sklearn.ensemble import ExtraTreesRegressor

    forest = IterativeImputer(estimator=ExtraTreesRegressor(n_estimators=2))
    with pytest.raises(ValueError, match="max_features"):
        HoldoutSearch(forest, {"estimator__max_features": [1.0, -3.0]}).fit(W)


def test_a_fold_that_hides_nothing_is_refused_naming_the_mask():
    X = np.arange(12.0).reshape(4, 3)
    W = np.where(np.eye(4, 3, dtype=bool), X, np.nan)  # one observed entry per column
    with pytest.raises(ValueError, match="hides no entry: the mask of X"):
        HoldoutSearch(SimpleImputer(), {"strategy": ["mean"]}, n_folds=3).fit(W)


def test_folds_must_hide_observed_entries_of_the_shape_of_x():
    _, W = data()
    missing = np.isnan(W)
    with pytest.raises(ValueError, match="missing in X"):
        HoldoutSearch(SimpleImputer(), {"strategy": ["mean"]}, folds=[missing]).fit(W)
    with pytest.raises(ValueError, match="shape"):
        HoldoutSearch(SimpleImputer(), {"strategy": ["mean"]}, folds=[np.ones((2, 2), bool)]).fit(W)


def test_one_se_rule_follows_prefer_then_the_smallest_error():
    # candidate 0 best; 1, 2, 3 within one SE (0.1 / sqrt(4) = 0.05 above it); 4 outside
    candidates = [
        {"tau": 1.0, "gamma": 2.0},
        {"tau": 0.1, "gamma": 2.0},
        {"tau": 0.1, "gamma": 1.0},
        {"tau": 0.1, "gamma": 1.0},
        {"tau": 0.01, "gamma": 1.0},
    ]
    mean = np.array([1.0, 1.04, 1.03, 1.02, 1.2])
    std = np.array([0.1, 0.0, 0.0, 0.0, 0.0])
    assert _choose(mean, std, 4, "min", (), candidates) == 0
    assert _choose(mean, std, 4, "one_se", ("tau", "gamma"), candidates) == 3
    assert _choose(mean, std, 4, "one_se", ("tau", "-gamma"), candidates) == 1
    assert _choose(mean, std, 4, "one_se", (), candidates) == 0
    mean[0] = np.nan
    assert _choose(mean, std, 4, "min", (), candidates) == 3


def test_a_path_warm_starts_along_its_parameter_and_chains_the_groups_from_their_first_fit():
    _, W = data()
    starts = []

    class Recorder(Fill):
        def fit(self, X, y=None):
            super().fit(X)
            starts.append((self.fail, self.value_, self.start_))
            return self

    grid = {"fail": [False, True], "scale": [1.0, 2.0, 3.0]}
    HoldoutSearch(Recorder(), grid, folds=holdout_folds(~np.isnan(W), 2, 0)[:1], path="scale",
                  refit=False, error_score=np.nan).fit(W)
    # group fail=False: cold, then each from its neighbour; group fail=True from group 1's first fit
    assert starts == [(False, 1.0, None), (False, 2.0, 1.0), (False, 3.0, 2.0),
                      (True, 1.0, 1.0), (True, 2.0, 1.0), (True, 3.0, 2.0)]


def test_stop_factor_skips_the_rest_of_a_path_and_those_candidates_are_never_chosen():
    _, W = data()

    def score(X, X_hat, hidden):  # error 1 at scale 1, 10 at scale 2 (past 1.5 x 1), 0 at scale 3
        return {1.0: 1.0, 2.0: 10.0, 3.0: 0.0}[Recorder.last]

    class Recorder(Fill):
        last = None

        def fit(self, X, y=None):
            type(self).last = self.scale
            return super().fit(X)

    search = HoldoutSearch(Recorder(), {"scale": [1.0, 2.0, 3.0]}, n_folds=2, path="scale",
                           stop_factor=1.5, scoring=score).fit(W)
    assert search.cv_results_["n_solved"].tolist() == [2, 2, 0]
    assert np.isnan(search.cv_results_["mean_test_error"][2]) and search.best_params_ == {"scale": 1.0}


def test_row_folds_fit_on_some_rows_and_score_the_completion_of_the_others():
    X, W = data(n=20)
    W = X.copy()
    fit_rows = np.arange(20) >= 5
    hidden = np.zeros(W.shape, bool)
    hidden[:5, 1] = True
    search = HoldoutSearch(SimpleImputer(), {"strategy": ["mean"]}, folds=[(fit_rows, hidden)]).fit(W)
    expected = np.mean((X[5:, 1].mean() - X[:5, 1]) ** 2)
    assert search.best_score_ == pytest.approx(expected, rel=1e-12)


def test_row_folds_with_inputs_transform_them_and_score_against_x():
    """A fold (fit_rows, hidden, inputs) transforms ``inputs`` (say, corrupted copies of the scored
    rows) and scores the output against X, the clean rows, on the hidden entries."""
    X, _ = data(n=20)
    fit_rows = np.arange(20) >= 5
    hidden = np.zeros(X.shape, bool)
    hidden[:5] = True  # every entry of the scored rows
    inputs = X[:5] + 10.0
    inputs[:, 1] = np.nan
    search = HoldoutSearch(SimpleImputer(), {"strategy": ["mean"]}, folds=[(fit_rows, hidden, inputs)]).fit(X)
    out = inputs.copy()
    out[:, 1] = X[5:, 1].mean()  # the mean of the fit rows fills the NaN, the rest is returned as given
    assert search.best_score_ == pytest.approx(np.mean((out - X[:5]) ** 2), rel=1e-12)
    for bad in [(fit_rows, hidden, inputs[:4]), (fit_rows, hidden, inputs[:, :2])]:
        with pytest.raises(ValueError, match="inputs"):
            HoldoutSearch(SimpleImputer(), {"strategy": ["mean"]}, folds=[bad]).fit(X)


def test_entry_folds_are_holdout_folds_of_the_observed_entries():
    _, W = data()
    for holdout in (None, 0.1):
        a = EntryFolds(4, holdout=holdout, random_state=3).split(W)
        b = holdout_folds(~np.isnan(W), 4, 3, holdout=holdout)
        assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def test_derive_sets_parameters_from_each_fits_own_training_matrix():
    _, W = data()
    seen = []

    def derive(estimator, X_train):
        seen.append(int(np.isnan(X_train).sum()))
        return {"scale": 1.0}

    search = HoldoutSearch(Fill(), {"fail": [False]}, n_folds=3, derive=derive).fit(W)
    assert search.best_estimator_.scale == 1.0
    folds = holdout_folds(~np.isnan(W), 3, 0)
    assert seen == [int(np.isnan(W).sum() + f.sum()) for f in folds] + [int(np.isnan(W).sum())]


class Moved(Fill):
    """Fill that reports how far it moved from scale 1 (``move_``), as a method started elsewhere does."""

    def fit(self, X, y=None):
        super().fit(X)
        self.move_ = abs(float(self.scale) - 1.0)
        return self


def test_reference_rule_and_min_move_are_the_brute_force_choice_from_the_fold_errors():
    _, W = data(n=40, d=6, p=0.3, seed=5)
    W = W + 3.0  # column means away from zero: the fill's scale matters
    scales = [0.5, 0.9, 1.0, 1.02, 1.1, 1.5]
    folds = holdout_folds(~np.isnan(W), 4, 1)
    # by hand: every fold error, the paired differences from the reference, the eligible candidates
    errors = np.empty((4, len(scales)))
    for k, hidden in enumerate(folds):
        train = np.where(hidden, np.nan, W)
        for c, scale in enumerate(scales):
            filled = np.where(np.isnan(train), np.nanmean(train, axis=0) * scale, train)
            errors[k, c] = np.mean((filled - W)[hidden] ** 2)
    ref = scales.index(1.1)  # a default that 1.0 and 1.02 beat, but both move less than 0.05
    diff = errors - errors[:, [ref]]
    se = np.array([np.sqrt(np.sum((d - d.mean()) ** 2) / 3) / 2 for d in diff.T])  # sd / sqrt(4)
    chosen = []
    for min_move in (None, 0.05, 10.0):
        active = [True] * 6 if min_move is None else [abs(s - 1) >= min_move for s in scales]
        eligible = active if any(active) else [True] * 6
        better = [c for c in range(6) if eligible[c] and diff[:, c].mean() + se[c] < 0]
        expected = ref if not better else min(better, key=lambda c: (errors[:, c].mean(), c))
        search = HoldoutSearch(Moved(), {"scale": scales}, folds=folds, rule="reference",
                               reference={"scale": 1.1}, min_move=min_move, refit=False).fit(W)  # fmt: skip
        r = search.cv_results_
        np.testing.assert_allclose(r["mean_diff_reference"], diff.mean(axis=0), rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(r["se_diff_reference"], se, rtol=1e-12, atol=1e-15)
        assert search.best_index_ == expected, (min_move, better)
        chosen.append(expected)
        if min_move is not None:
            np.testing.assert_allclose(r["max_move"], [abs(s - 1) for s in scales])
            assert r["active"].tolist() == active
        # "min" under the same eligibility: the smallest mean among the eligible
        plain = HoldoutSearch(Moved(), {"scale": scales}, folds=folds, min_move=min_move, refit=False).fit(W)
        best = min((c for c in range(6) if eligible[c]), key=lambda c: (errors[:, c].mean(), c))
        assert plain.best_index_ == best
    assert ref in chosen and any(c != ref for c in chosen)  # both branches of the rule were exercised


def test_choose_reference_keeps_the_default_unless_an_eligible_candidate_beats_it_by_one_paired_se():
    candidates = [{"a": k} for k in range(4)]
    mean = np.array([1.0, 0.9, 0.8, 0.7])
    std = np.zeros(4)
    paired = (np.array([0.0, -0.1, -0.2, -0.3]), np.array([0.0, 0.05, 0.25, 0.1]))
    # 1 and 3 beat the reference 0 by more than one SE (2 does not: -0.2 + 0.25 > 0); 3 has the smaller mean
    assert _choose(mean, std, 4, "reference", (), candidates, None, 0, paired) == 3
    assert _choose(mean, std, 4, "reference", (), candidates, [True, True, True, False], 0, paired) == 1
    assert _choose(mean, std, 4, "reference", (), candidates, [True, False, True, False], 0, paired) == 0
    # nothing eligible: every finite candidate is
    assert _choose(mean, std, 4, "reference", (), candidates, [False] * 4, 0, paired) == 3
    assert _choose(mean, std, 4, "min", (), candidates, [True, True, False, False]) == 1


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"rule": "reference"}, "needs reference"),
        ({"rule": "reference", "reference": {"scale": 3.0}}, "one candidate"),
        ({"reference": {"scale": 1.0}}, "default of rule='reference'"),
        ({"min_move": -1.0}, "min_move"),
        ({"min_move": float("nan")}, "min_move"),
    ],
)
def test_reference_and_min_move_are_checked_before_any_fit(kwargs, match):
    _, W = data()
    Fill.fits = 0
    with pytest.raises(ValueError, match=match):
        HoldoutSearch(Fill(), {"scale": [1.0, 2.0]}, n_folds=2, **kwargs).fit(W)
    assert Fill.fits == 0


def test_min_move_needs_the_estimators_move():
    _, W = data()
    with pytest.raises(ValueError, match="move_"):
        HoldoutSearch(Fill(), {"scale": [1.0, 2.0]}, n_folds=2, min_move=0.1).fit(W)
