"""The scikit-learn imputers of nldr.impute: the estimator contract, the paper's settings reproducing
the solver functions, and use inside scikit-learn (Pipeline, cross_val_score, clone, GridSearchCV)."""

import numpy as np
import pandas as pd
import pytest
from sklearn.base import clone
from sklearn.linear_model import LogisticRegression
from sklearn.model_selection import GridSearchCV, cross_val_score
from sklearn.pipeline import Pipeline
from sklearn.utils import estimator_checks
from sklearn.utils.estimator_checks import parametrize_with_checks

from nldr._baselines import mean_impute
from nldr.data_terms import MaskedLeastSquares
from nldr.impute import (
    KernelRegularizerImputer,
    NearestNeighbourImputer,
    PKPCAImputer,
    PPCAImputer,
    RKPCAImputer,
    RobustPCAImputer,
    SoftImputer,
)
from nldr.impute._regularizer import MEDIAN_RULE_MULTIPLE
from nldr.regularizer import minimize_regularized

ESTIMATORS = [
    # the whole check list at fixed knobs (one solve a fit); the self-tuning default has its own checks
    KernelRegularizerImputer(gamma=None, tau=0.1, n_neighbors=5, starts="mean"),
    PPCAImputer(),
    PKPCAImputer(),
    RKPCAImputer(),
    NearestNeighbourImputer(),
    SoftImputer(),
    RobustPCAImputer(),
]


def _expected_failed_checks(estimator) -> dict:
    """scikit-learn's checks that a method fails by design, with the reason."""
    if isinstance(estimator, PKPCAImputer | RKPCAImputer):
        # check_transformer_n_iter (run for estimators with max_iter) fits complete data: with no
        # missing entry the kernel baselines' outer loop has nothing to move and reports nit = 0
        return {"check_transformer_n_iter": "no missing entry: nothing to iterate, n_iter_ = 0"}
    return {}


@parametrize_with_checks(ESTIMATORS, expected_failed_checks=_expected_failed_checks)
def test_scikit_learn_estimator_checks(estimator, check):
    check(estimator)


#: the checks that fit and transform, where the default's tuning runs (inside fit, and at the first
#: new row): fitting twice, pickling, the parameters left as given, transform's invariances
DEFAULT_CHECKS = [
    estimator_checks.check_fit_idempotent,
    estimator_checks.check_estimators_pickle,
    estimator_checks.check_dont_overwrite_parameters,
    estimator_checks.check_estimators_overwrite_params,
    estimator_checks.check_transformer_general,
    estimator_checks.check_methods_subset_invariance,
    estimator_checks.check_methods_sample_order_invariance,
    estimator_checks.check_dict_unchanged,
    estimator_checks.check_fit2d_1sample,
]


@pytest.mark.parametrize("check", DEFAULT_CHECKS, ids=lambda c: c.__name__)
def test_the_self_tuning_default_passes_the_fitting_checks(check):
    check("KernelRegularizerImputer", KernelRegularizerImputer())


def surface(n, rng, noise=0.0):
    """Rows on a curved two-dimensional surface in R^6, optionally noisy."""
    t, s = rng.uniform(0, 1, n), rng.uniform(0, 1, n)
    X = np.c_[t, t**2, np.sin(3 * t), s, s * t, np.cos(2 * s)]
    return X + noise * rng.standard_normal(X.shape)


def hide(X, p, rng):
    mask = rng.random(X.shape) >= p
    mask[np.arange(X.shape[0]), rng.integers(0, X.shape[1], X.shape[0])] = True  # a value in each row
    return np.where(mask, X, np.nan), mask


def test_paper_settings_reproduce_the_solver_call_bit_for_bit(rng):
    X = surface(40, rng, noise=0.02)
    W, mask = hide(X, 0.25, rng)
    ref = minimize_regularized(MaskedLeastSquares(W, mask), mean_impute(W, mask), gamma=0.075, tau=0.1)
    est = KernelRegularizerImputer(standardize=False, gamma=0.075, tau=0.1, method="exact", denoise=True)
    np.testing.assert_array_equal(est.fit_transform(W), ref.x)
    np.testing.assert_array_equal(est.result_.C, ref.C)
    assert est.result_.nit == ref.nit


def test_standardised_solve_is_the_solve_on_standardised_columns(rng):
    X = surface(40, rng, noise=0.02) * np.array([1.0, 10.0, 0.1, 3.0, 1.0, 2.0]) + 5.0
    W, mask = hide(X, 0.25, rng)
    mu = np.nanmean(W, axis=0)
    sd = np.nanstd(W, axis=0)
    Z = (W - mu) / sd
    ref = minimize_regularized(MaskedLeastSquares(Z, mask), mean_impute(Z, mask), gamma=0.3, tau=0.3)
    est = KernelRegularizerImputer(gamma=0.3, tau=0.3, method="exact", denoise=True).fit(W)
    np.testing.assert_allclose(est.mean_, mu, rtol=1e-12)
    np.testing.assert_allclose(est.scale_, sd, rtol=1e-12)
    # the same problem up to rounding in the standardisation: the same minimiser to the solver's tolerance
    np.testing.assert_allclose(est.completed_, ref.x * sd + mu, rtol=1e-5, atol=1e-5 * sd.max())


def test_default_width_is_the_median_rule_in_standardised_units(rng):
    X = surface(30, rng) * 100.0
    W, mask = hide(X, 0.2, rng)
    est = KernelRegularizerImputer(gamma=None, tau=0.1, method="exact").fit(W)
    S0 = mean_impute((W - est.mean_) / est.scale_, mask)
    d2 = ((S0[:, None, :] - S0[None, :, :]) ** 2).sum(axis=2)[np.triu_indices(30, 1)]
    assert est.gamma_ == pytest.approx(MEDIAN_RULE_MULTIPLE / np.median(d2), rel=1e-12)


def test_completion_beats_mean_imputation_on_a_surface(rng):
    X = surface(80, rng)
    W, mask = hide(X, 0.25, rng)
    X_hat = KernelRegularizerImputer().fit_transform(W)
    sse = np.sum((X_hat - X)[~mask] ** 2)
    assert sse < 0.5 * np.sum((mean_impute(W, mask) - X)[~mask] ** 2)


def test_transform_new_rows_keeps_observed_entries_and_beats_the_column_means(rng):
    X = surface(140, rng)
    W, mask = hide(X, 0.25, rng)
    est = KernelRegularizerImputer().fit(W[:100])
    X_new = est.transform(W[100:])
    new_mask = mask[100:]
    np.testing.assert_array_equal(X_new[new_mask], W[100:][new_mask])
    means = np.nanmean(W[:100], axis=0)
    err = np.sum((X_new - X[100:])[~new_mask] ** 2)
    err_mean = np.sum((np.broadcast_to(means, X_new.shape) - X[100:])[~new_mask] ** 2)
    assert err < 0.5 * err_mean


def test_transform_of_the_training_rows_is_fit_transform(rng):
    W, _ = hide(surface(30, rng), 0.3, rng)
    est = KernelRegularizerImputer()
    X_hat = est.fit_transform(W)
    np.testing.assert_array_equal(est.transform(W), X_hat)
    np.testing.assert_array_equal(est.transform(W[::-1]), X_hat[::-1])


def test_each_start_averages_the_local_minima(rng):
    X = surface(60, rng)
    W, mask = hide(X, 0.3, rng)
    est = KernelRegularizerImputer(gamma=None, tau=0.1, starts="each", n_neighbors=3).fit(W[:50])
    one = clone(est).set_params(n_neighbors=1).fit(W[:50])
    mean_one = KernelRegularizerImputer(gamma=None, tau=0.1, starts="mean", n_neighbors=1).fit(W[:50])
    # with one neighbour, "each" and "mean" solve the same problem from the same start
    np.testing.assert_allclose(one.transform(W[50:]), mean_one.transform(W[50:]), atol=1e-12)
    assert np.isfinite(est.transform(W[50:])).all()


def test_nystroem_warm_path_gives_a_finite_answer_with_an_exact_last_stage(rng):
    X = surface(120, rng, noise=0.01)
    W, mask = hide(X, 0.25, rng)
    est = KernelRegularizerImputer(gamma=None, tau=0.1, method="nystroem-warm", random_state=0).fit(W)
    assert est.method_ == "nystroem-warm"
    assert est.result_.n_stages == len(est.result_.rho_history)
    assert est.result_.rho_history[-1] == est.result_.rho_history[-2]  # the last rho solved twice
    assert np.isfinite(est.completed_).all()
    again = KernelRegularizerImputer(gamma=None, tau=0.1, method="nystroem-warm", random_state=0).fit(W)
    np.testing.assert_array_equal(again.completed_, est.completed_)


def test_auto_method_by_size(rng):
    W, _ = hide(surface(30, rng), 0.2, rng)
    assert KernelRegularizerImputer().fit(W).method_ == "exact"


def test_auto_method_runs_every_stage_on_pivoted_landmarks_above_its_threshold(rng, monkeypatch):
    """Above AUTO_EXACT_MAX_ROWS rows "auto" is method="nystroem" on AUTO_LANDMARKS landmarks chosen by
    AUTO_LANDMARK_RULE, the stages before the last stopping at AUTO_STAGE_TOL (the warm start's own
    options dropped) and the last at AUTO_NYSTROEM_TOL, from the nearest rows' fill from AUTO_KNN_MIN_ROWS
    rows (init="knn"; below, and on an explicit path, the mean fill); at or below AUTO_EXACT_MAX_ROWS the
    exact solver."""
    from nldr.impute import _regularizer as module

    monkeypatch.setattr(module, "AUTO_EXACT_MAX_ROWS", 49)
    monkeypatch.setattr(module, "AUTO_LANDMARKS", 15)
    monkeypatch.setattr(module, "AUTO_KNN_MIN_ROWS", 60)
    W, _ = hide(surface(60, rng, noise=0.01), 0.25, rng)
    kw = {"gamma": None, "tau": 0.1, "random_state": 4}
    auto = KernelRegularizerImputer(**kw, options={"exact_stages": 1}).fit(W)
    rule = {"landmark_rule": module.AUTO_LANDMARK_RULE, "stage_tol": module.AUTO_STAGE_TOL}
    explicit = {**kw, "method": "nystroem", "n_landmarks": 15, "options": rule}
    explicit["tol"] = module.AUTO_NYSTROEM_TOL
    assert auto.method_ == "nystroem"
    knn = KernelRegularizerImputer(**explicit, init="knn").fit(W)
    np.testing.assert_array_equal(auto.completed_, knn.completed_)  # the same computation
    mean = KernelRegularizerImputer(**explicit, init="mean").fit(W)
    np.testing.assert_array_equal(KernelRegularizerImputer(**explicit).fit(W).completed_, mean.completed_)
    monkeypatch.setattr(module, "AUTO_KNN_MIN_ROWS", 61)  # below it "auto" starts from the mean
    np.testing.assert_array_equal(KernelRegularizerImputer(**kw).fit(W).completed_, mean.completed_)
    assert KernelRegularizerImputer(**kw).fit(W[:49]).method_ == "exact"
    assert np.isfinite(auto.transform(W[:5] + 0.01)).all()


def test_tol_auto_is_looser_on_the_approximate_path_only(rng, monkeypatch):
    """tol="auto" stops the last stage of "auto"'s approximate path at AUTO_NYSTROEM_TOL and every other
    path's stages at DEFAULT_TOL; a tol passed holds on every path. AUTO_NYSTROEM_TOL is set far from
    DEFAULT_TOL here, so that the two stop at different iterations on this small problem."""
    from nldr.impute import _regularizer as module

    monkeypatch.setattr(module, "AUTO_EXACT_MAX_ROWS", 49)
    monkeypatch.setattr(module, "AUTO_LANDMARKS", 15)
    monkeypatch.setattr(module, "AUTO_NYSTROEM_TOL", 1e-4)
    W, _ = hide(surface(60, rng, noise=0.01), 0.25, rng)
    kw = {"gamma": None, "tau": 0.1}
    auto = KernelRegularizerImputer(**kw).fit(W)
    np.testing.assert_array_equal(auto.completed_, KernelRegularizerImputer(**kw, tol=1e-4).fit(W).completed_)
    strict = KernelRegularizerImputer(**kw, tol=module.DEFAULT_TOL).fit(W)
    assert auto.method_ == strict.method_ == "nystroem" and auto.result_.nit < strict.result_.nit
    for rows, method in ((60, "exact"), (60, "nystroem"), (49, "auto")):
        default = KernelRegularizerImputer(**kw, method=method).fit(W[:rows])
        passed = KernelRegularizerImputer(**kw, method=method, tol=module.DEFAULT_TOL).fit(W[:rows])
        np.testing.assert_array_equal(default.completed_, passed.completed_)


def test_the_search_folds_start_where_the_final_solve_starts(rng, monkeypatch):
    """From AUTO_KNN_MIN_ROWS rows every fold solve of the tuning starts from the nearest rows' fill of
    its own matrix, as the final solve does; below it none does."""
    from nldr.impute import _regularizer as module
    from nldr.impute._defaults import TUNE_FOLDS

    calls = []
    fill = module.neighbour_fill
    monkeypatch.setattr(module, "neighbour_fill", lambda Z, m, *a: calls.append(m.sum()) or fill(Z, m, *a))
    monkeypatch.setattr(module, "AUTO_EXACT_MAX_ROWS", 49)
    monkeypatch.setattr(module, "AUTO_KNN_MIN_ROWS", 50)
    monkeypatch.setattr(module, "AUTO_LANDMARKS", 15)
    monkeypatch.setattr(module, "TUNE_LANDMARKS", 15)
    W, mask = hide(surface(60, rng, noise=0.01), 0.25, rng)
    est = KernelRegularizerImputer(gamma=None).fit(W)
    assert hasattr(est, "cv_results_") and est.method_ == "nystroem"
    assert len(calls) >= TUNE_FOLDS + 1 and calls[0] == mask.sum()  # the fit's start, then the folds'
    assert all(c < mask.sum() for c in calls[1:])  # each fold hides more
    calls.clear()
    KernelRegularizerImputer(gamma=None).fit(W[:49])
    assert calls == []


def test_pandas_in_and_out_and_feature_names(rng):
    W, _ = hide(surface(30, rng), 0.2, rng)
    frame = pd.DataFrame(W, columns=list("abcdef"))
    est = KernelRegularizerImputer().set_output(transform="pandas")
    out = est.fit_transform(frame)
    assert isinstance(out, pd.DataFrame) and list(out.columns) == list("abcdef")
    assert list(est.get_feature_names_out()) == list("abcdef")
    with pytest.raises(ValueError, match="feature names"):
        est.transform(frame[["b", "a", "c", "d", "e", "f"]])


@pytest.mark.parametrize(
    ("X", "match"),
    [
        (np.array([["a", "b"], ["c", "d"], ["e", "f"]]), "could not convert|numeric"),
        (np.ones((5, 3)) * (1 + 1j), "[Cc]omplex"),
        (np.array([[1.0, np.inf], [2.0, 1.0], [3.0, 0.0]]), "infinity"),
        (np.array([[1.0, np.nan], [2.0, np.nan], [3.0, np.nan]]), r"no observed entry in column\(s\) \[1\]"),
        (np.ones((1, 3)), "sample"),
    ],
)
def test_bad_input_is_refused_with_a_clear_message(X, match):
    with pytest.raises(ValueError, match=match):
        KernelRegularizerImputer().fit(X)


@pytest.mark.parametrize(
    ("params", "match"),
    [
        ({"tau": 0.0}, "tau"),
        ({"gamma": -1.0}, "gamma"),
        ({"method": "fast"}, "method"),
        ({"starts": "all"}, "starts"),
        ({"init": "median"}, "init"),
        ({"weights": "inverse"}, "weights"),
        ({"n_neighbors": 0}, "n_neighbors"),
        ({"options": [1]}, "options"),
        ({"method": "exact", "options": {"exact_stages": 1}}, "'exact' takes no option 'exact_stages'"),
        ({"method": "exact", "n_landmarks": 10}, "n_landmarks"),
        ({"options": {"landmarks": 10, "max_inner": 5}}, "pass n_landmarks=, max_iter="),
        ({"rho_growth": 1.0}, "rho_growth"),
        ({"rho0": 10.0, "rho_max": 1.0}, "rho_max"),
        ({"max_iter": 0}, "max_iter"),
        ({"tol": -1e-8}, "'tol'"),
        ({"missing_values": "x"}, "missing_values"),
    ],
)
def test_bad_parameters_are_refused_naming_them(rng, params, match):
    W, _ = hide(surface(20, rng), 0.2, rng)
    with pytest.raises(ValueError, match=match):
        KernelRegularizerImputer(**params).fit(W)


def test_a_number_as_missing_marker(rng):
    X = surface(30, rng)
    W, mask = hide(X, 0.2, rng)
    coded = np.where(mask, X, -999.0)
    a = KernelRegularizerImputer(missing_values=-999.0).fit_transform(coded)
    b = KernelRegularizerImputer().fit_transform(W)
    np.testing.assert_array_equal(a, b)


def labelled(rng, n=60):
    X = surface(n, rng, noise=0.05)
    y = (X[:, 0] > 0.5).astype(int)
    W, _ = hide(X, 0.2, rng)
    return W, y


def test_pipeline_under_cross_val_score_on_data_with_nan(rng):
    W, y = labelled(rng)
    pipe = Pipeline([("impute", KernelRegularizerImputer()), ("model", LogisticRegression())])
    scores = cross_val_score(pipe, W, y, cv=3)
    assert scores.shape == (3,) and np.all(scores > 0.6)


def test_clone_and_grid_search(rng):
    W, y = labelled(rng)
    est = KernelRegularizerImputer(tau=0.5, gamma=0.2)
    twin = clone(est)
    assert twin.get_params() == est.get_params() and twin is not est
    pipe = Pipeline([("impute", KernelRegularizerImputer(gamma=None)), ("model", LogisticRegression())])
    search = GridSearchCV(pipe, {"impute__tau": [0.1, 1.0]}, cv=2).fit(W, y)
    assert search.best_params_["impute__tau"] in (0.1, 1.0)
    assert search.cv_results_["mean_test_score"].shape == (2,)
