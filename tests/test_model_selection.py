"""Hold-out model selection (nldr.model_selection) and the isolation guard of the penalty method."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import denoising_problem, within_observed_range
from sklearn.base import BaseEstimator, TransformerMixin
from threadpoolctl import threadpool_limits

from nldr._baselines import mean_impute
from nldr._schedule import isolation_safe_rho0
from nldr._spectral import cubic_threshold
from nldr.data_terms import MaskedLeastSquares
from nldr.model_selection import HoldoutSearch, holdout_folds, median_gamma
from nldr.model_selection._folds import DEFAULT_TAUS
from nldr.regularizer import minimize_regularized


@pytest.fixture(autouse=True)
def one_blas_thread():
    """Small matrices: one BLAS thread is faster beside a busy core (docs/DESIGN.md)."""
    with threadpool_limits(1):
        yield


def solve(W, mask, start, gamma, tau, **options):
    """The regularizer on the observed entries of W from ``start`` (the isolation guard on)."""
    term = MaskedLeastSquares(np.where(mask, W, np.nan), mask)
    rho0 = options.pop("rho0", 1.0)
    opts = {"isolation_guard": True, **options}
    return minimize_regularized(term, start, gamma=gamma, tau=tau, rho0=rho0, options=opts).x


def share_identical_rows(x, W, train):
    """x (n, d) with each group of rows identical in the fold's input (the same kept values, the same
    hidden entries; e.g. rows with nothing kept) given the group's mean: the imputers' rule for
    identical rows, written out independently."""
    keys = [row.tobytes() for row in np.where(train, W, np.nan)]
    out = x.copy()
    for key in set(keys):
        rows = [i for i, k in enumerate(keys) if k == key]
        if len(rows) > 1:
            out[rows] = x[rows].mean(axis=0)
    return out


# --------------------------------------------------------------------------------------------------
# Folds
# --------------------------------------------------------------------------------------------------


def test_folds_partition_the_observed_entries_and_repeat_with_the_seed():
    _, _, mask = denoising_problem(n=30, d=6)
    folds = holdout_folds(mask, 4, random_state=3)
    total = np.sum(folds, axis=0)
    assert total.max() == 1 and np.all(total[~mask] == 0)  # disjoint, only observed entries
    assert total.sum() == mask.sum()  # every column has plenty of entries: nothing kept back
    again = holdout_folds(mask, 4, random_state=3)
    assert all(np.array_equal(a, b) for a, b in zip(folds, again, strict=True))
    other = holdout_folds(mask, 4, random_state=4)
    assert not all(np.array_equal(a, b) for a, b in zip(folds, other, strict=True))


def test_a_sparse_column_keeps_a_training_entry_in_every_fold():
    mask = np.ones((8, 3), dtype=bool)
    mask[1:, 2] = False  # column 2 has one observed entry
    for hidden in holdout_folds(mask, 2, random_state=0):
        assert np.all((mask & ~hidden).any(axis=0))


def test_holdout_folds_hide_the_given_share_afresh_and_repeat_with_the_seed():
    _, _, mask = denoising_problem(n=30, d=6)
    folds = holdout_folds(mask, 3, random_state=5, holdout=0.1)
    size = round(0.1 * mask.sum())
    for hidden in folds:
        assert hidden.sum() == size and not np.any(hidden & ~mask)  # every column keeps many entries
    assert not np.array_equal(folds[0], folds[1])  # drawn afresh, not one draw reused
    again = holdout_folds(mask, 3, random_state=5, holdout=0.1)
    assert all(np.array_equal(a, b) for a, b in zip(folds, again, strict=True))
    sparse = np.ones((8, 3), dtype=bool)
    sparse[1:, 2] = False
    for hidden in holdout_folds(sparse, 4, random_state=0, holdout=0.5):
        assert np.all((sparse & ~hidden).any(axis=0))


@pytest.mark.parametrize("holdout", [0.0, 1.0, -0.1, "0.1"])
def test_holdout_outside_the_unit_interval_is_refused(holdout):
    with pytest.raises(ValueError, match="holdout"):
        holdout_folds(np.ones((5, 5), dtype=bool), 2, holdout=holdout)


# --------------------------------------------------------------------------------------------------
# The regularizer's search: warm-started tau paths
# --------------------------------------------------------------------------------------------------


class WarmRegularizer(TransformerMixin, BaseEstimator):
    """The regularizer with scikit-learn's warm_start: a refit starts from the previous answer with
    the last penalty stage only (what a tau path needs of an estimator)."""

    def __init__(self, gamma=1.0, tau=0.1, tol=1e-10, gtol=1e-6, warm_start=False):
        self.gamma, self.tau, self.tol, self.gtol, self.warm_start = gamma, tau, tol, gtol, warm_start

    def fit_transform(self, X, y=None):
        mask = ~np.isnan(X)
        warm = self.warm_start and hasattr(self, "x_")
        start, rho0 = (self.x_, 1e4) if warm else (mean_impute(X, mask), 1.0)
        # the last stage in the units of the full schedule (scale sqrt(rho0 = 1)), as a tau path runs it
        options = {"tol": self.tol, "gtol": self.gtol, "scale": 1.0}
        self.x_ = solve(X, mask, start, self.gamma, self.tau, rho0=rho0, **options)
        return self.x_

    def fit(self, X, y=None):
        self.fit_transform(X)
        return self


def test_a_tau_path_is_the_hand_chain_of_last_stage_solves_and_widths_chain_from_their_first():
    _, W, mask = denoising_problem(n=25, d=5)
    W = np.where(mask, W, np.nan)
    g1, g2 = 0.5 * median_gamma(W, mask), median_gamma(W, mask)
    search = HoldoutSearch(
        WarmRegularizer(), {"gamma": [g1, g2], "tau": [0.1, 1.0]}, n_folds=2, holdout=0.1, path="tau",
        fold_params={"tol": 1e-7, "gtol": 1e-4},
    ).fit(W)
    errors = {key: [] for key in [(g1, 0.1), (g1, 1.0), (g2, 0.1), (g2, 1.0)]}
    for h in holdout_folds(mask, 2, random_state=0, holdout=0.1):
        train = mask & ~h
        W_train = np.where(train, W, np.nan)
        opts = {"tol": 1e-7, "gtol": 1e-4, "scale": 1.0}  # the full schedule's units (sqrt(rho0 = 1))
        first = solve(W_train, train, mean_impute(W_train, train), g1, 0.1, **opts)  # the one cold solve
        chain = {
            (g1, 0.1): first,
            (g1, 1.0): solve(W_train, train, first, g1, 1.0, rho0=1e4, **opts),
        }
        chain[(g2, 0.1)] = solve(W_train, train, first, g2, 0.1, rho0=1e4, **opts)
        chain[(g2, 1.0)] = solve(W_train, train, chain[(g2, 0.1)], g2, 1.0, rho0=1e4, **opts)
        for key, x in chain.items():
            errors[key].append(np.mean((x - W)[h] ** 2))
    for k, params in enumerate(search.cv_results_["params"]):
        expected = np.mean(errors[(params["gamma"], params["tau"])])
        assert search.cv_results_["mean_test_error"][k] == pytest.approx(expected, rel=1e-12)
    # the refit is the cold solve on every observed entry at the chosen candidate
    best = search.best_params_
    refit = solve(W, mask, mean_impute(W, mask), best["gamma"], best["tau"])
    np.testing.assert_array_equal(search.best_estimator_.x_, refit)


def test_the_regularizer_imputer_s_fold_errors_are_the_hand_computed_ones_and_the_refit_is_its_solve():
    from nldr.impute import KernelRegularizerImputer

    _, W, mask = denoising_problem(n=25, d=5)
    W = np.where(mask, W, np.nan)
    gamma, taus = median_gamma(W), [0.1, 1.0]
    ours = KernelRegularizerImputer(standardize=False, gamma=gamma, method="exact", denoise=True)  # S
    loose = {"tol": 1e-7, "gtol": 1e-4}
    search = HoldoutSearch(ours, {"tau": taus}, n_folds=2, fold_params=loose).fit(W)
    folds = holdout_folds(mask, 2, random_state=0)
    for k, tau in enumerate(taus):
        errors = []
        for h in folds:
            train = mask & ~h
            start = mean_impute(np.where(train, W, np.nan), train)
            x = share_identical_rows(solve(W, train, start, gamma, tau, tol=1e-7, gtol=1e-4), W, train)
            errors.append(np.mean((x - W)[h] ** 2))
        assert search.cv_results_["mean_test_error"][k] == pytest.approx(np.mean(errors), rel=1e-12)
        assert search.cv_results_["std_test_error"][k] == pytest.approx(np.std(errors, ddof=1), rel=1e-9)
    refit = solve(W, mask, mean_impute(W, mask), gamma, search.best_params_["tau"])
    np.testing.assert_array_equal(search.transform(W), refit)


def test_the_regularizer_imputer_s_tau_path_is_the_hand_chain_of_warm_last_stage_solves():
    from nldr.impute import KernelRegularizerImputer

    _, W, mask = denoising_problem(n=25, d=5)
    W = np.where(mask, W, np.nan)
    g1, g2 = 0.5 * median_gamma(W, mask), median_gamma(W, mask)
    ours = KernelRegularizerImputer(standardize=False, method="exact", denoise=True)  # S
    search = HoldoutSearch(
        ours, {"gamma": [g1, g2], "tau": [0.1, 1.0]}, n_folds=2, holdout=0.1, path="tau",
        fold_params={"tol": 1e-7, "gtol": 1e-4},
    ).fit(W)
    errors = {key: [] for key in [(g1, 0.1), (g1, 1.0), (g2, 0.1), (g2, 1.0)]}
    cold = {"tol": 1e-7, "gtol": 1e-4}
    warm = {**cold, "rho0": 1e4, "scale": 1.0}  # the last stage, in the full schedule's units
    for h in holdout_folds(mask, 2, random_state=0, holdout=0.1):
        train = mask & ~h
        first = solve(W, train, mean_impute(np.where(train, W, np.nan), train), g1, 0.1, **cold)
        chain = {(g1, 0.1): first, (g1, 1.0): solve(W, train, first, g1, 1.0, **warm)}
        chain[(g2, 0.1)] = solve(W, train, first, g2, 0.1, **warm)  # the next width from the first
        chain[(g2, 1.0)] = solve(W, train, chain[(g2, 0.1)], g2, 1.0, **warm)
        for key, x in chain.items():  # the chain starts from S; the imputer's answer shares copies' rows
            errors[key].append(np.mean((share_identical_rows(x, W, train) - W)[h] ** 2))
    for k, params in enumerate(search.cv_results_["params"]):
        expected = np.mean(errors[(params["gamma"], params["tau"])])
        assert search.cv_results_["mean_test_error"][k] == pytest.approx(expected, rel=1e-12)
    best = search.best_params_  # the refit is cold: the full schedule from mean imputation
    refit = solve(W, mask, mean_impute(W, mask), best["gamma"], best["tau"])
    np.testing.assert_array_equal(search.transform(W), refit)
    assert search.best_estimator_.warm_start is False


def test_a_warm_regularizer_imputer_refit_on_another_shape_or_standardised_starts_from_its_estimate():
    from nldr.impute import KernelRegularizerImputer

    _, W, mask = denoising_problem(n=25, d=5)
    W = np.where(mask, W, np.nan)
    imputer = KernelRegularizerImputer(tau=0.1, warm_start=True).fit(W)  # no previous fit: cold
    cold = KernelRegularizerImputer(tau=0.1).fit(W)
    np.testing.assert_array_equal(imputer.completed_, cold.completed_)
    previous = imputer.manifold_rows_ * imputer.scale_ + imputer.mean_  # its S, in the data's units
    imputer.set_params(tau=1.0).fit(W)
    Z = (previous - imputer.mean_) / imputer.scale_
    gamma = imputer.gamma_
    term = MaskedLeastSquares(np.where(mask, (W - imputer.mean_) / imputer.scale_, np.nan), mask)
    expected = minimize_regularized(term, Z, gamma=gamma, tau=1.0, rho0=1e4, options={"scale": 1.0})
    np.testing.assert_allclose(imputer.result_.x, expected.x, rtol=0, atol=1e-12)
    imputer.fit(W[:20])  # another shape: the full schedule again
    fresh = KernelRegularizerImputer(tau=1.0).fit(W[:20])
    np.testing.assert_array_equal(imputer.completed_, fresh.completed_)


@pytest.mark.parametrize(
    "params",
    [
        {"options": {"stage_tol": 1e-7, "gtoll": 1e-4}},
        {"method": "exact", "n_landmarks": 50},
        {"method": "nystroem", "options": {"exact_stages": 2}},  # an option of "nystroem-warm" only
        {"method": "auto", "options": {"max_iner": 10}},
        {"options": {"tol": 1e-7}},  # a parameter, not an option
        {"rho0": 10.0, "rho_max": 1.0},
        {"warm_start": "yes"},
    ],
)
def test_a_bad_regularizer_imputer_option_is_refused_before_the_first_fold(params, monkeypatch):
    from nldr.impute import KernelRegularizerImputer
    from nldr.impute import _regularizer as module

    def never(*args, **kwargs):
        raise AssertionError("a solve ran before the options were checked")

    monkeypatch.setattr(module, "minimize_regularized", never)
    _, W, mask = denoising_problem(n=25, d=5)
    W = np.where(mask, W, np.nan)
    grid = {"tau": [0.1, 1.0]}
    with pytest.raises(ValueError, match="option|rho_max|warm_start|landmarks"):
        HoldoutSearch(KernelRegularizerImputer(**params), grid, n_folds=2, path="tau").fit(W)
    typo = {"tol": 1e-7, "options": {"gtoll": 1e-4}}
    with pytest.raises(ValueError, match="gtoll"):
        HoldoutSearch(KernelRegularizerImputer(), grid, n_folds=2, fold_params=typo).fit(W)


def test_method_auto_takes_the_nystroem_warm_options_and_drops_them_where_it_solves_exactly():
    from nldr.impute import KernelRegularizerImputer

    _, W, mask = denoising_problem(n=25, d=5)
    W = np.where(mask, W, np.nan)
    auto = KernelRegularizerImputer(n_landmarks=10, options={"exact_stages": 2}, tol=1e-8).fit(W)
    exact = KernelRegularizerImputer(method="exact", tol=1e-8).fit(W)
    assert auto.method_ == "exact"
    np.testing.assert_array_equal(auto.completed_, exact.completed_)


def test_early_stop_leaves_the_solved_scores_unchanged_and_skips_only_the_end_of_a_path():
    _, W, mask = denoising_problem(n=25, d=5)
    W = np.where(mask, W, np.nan)
    grid = {"gamma": [0.5 * median_gamma(W), median_gamma(W)], "tau": [0.01, 0.1, 1.0, 10.0, 100.0]}
    common = {"n_folds": 2, "holdout": 0.1, "path": "tau", "fold_params": {"tol": 1e-7, "gtol": 1e-4}}
    full = HoldoutSearch(WarmRegularizer(), grid, **common).fit(W).cv_results_
    cut = HoldoutSearch(WarmRegularizer(), grid, stop_factor=1.05, **common).fit(W)
    assert np.isfinite(full["mean_test_error"]).all()
    skipped = np.isnan(cut.cv_results_["mean_test_error"])
    assert skipped.any()  # 1.05 is aggressive: some path must stop on this problem, or the test is void
    solved = cut.cv_results_["mean_test_error"][~skipped]
    np.testing.assert_array_equal(solved, full["mean_test_error"][~skipped])
    for g in grid["gamma"]:
        flags = skipped[cut.cv_results_["param_gamma"] == g]
        assert not flags[0] and np.all(np.diff(flags.astype(int)) >= 0)  # a suffix of the taus
    assert not skipped[cut.best_index_]


def test_one_se_rule_picks_the_smallest_tau_then_the_widest_kernel_within_one_standard_error():
    _, W, mask = denoising_problem(n=25, d=5)
    W = np.where(mask, W, np.nan)
    grid = {"gamma": [0.5 * median_gamma(W), median_gamma(W)], "tau": [0.01, 0.1, 1.0, 10.0]}
    common = {"n_folds": 3, "random_state": 1, "holdout": 0.1, "path": "tau", "refit": False}
    one_se = HoldoutSearch(WarmRegularizer(), grid, rule="one_se", prefer=("tau", "gamma"), **common).fit(W)
    best = HoldoutSearch(WarmRegularizer(), grid, rule="min", **common).fit(W)
    mean, std = one_se.cv_results_["mean_test_error"], one_se.cv_results_["std_test_error"]
    np.testing.assert_array_equal(mean, best.cv_results_["mean_test_error"])  # same folds, same scores
    i = int(np.argmin(mean))
    assert best.best_index_ == i
    close = np.flatnonzero(mean <= mean[i] + std[i] / np.sqrt(3))
    taus = one_se.cv_results_["param_tau"].astype(float)
    gammas = one_se.cv_results_["param_gamma"].astype(float)
    assert one_se.best_index_ in close and one_se.best_params_["tau"] == taus[close].min()
    assert one_se.best_params_["gamma"] == gammas[close][taus[close] == taus[close].min()].min()


def test_verbose_reports_every_candidate_fit_and_changes_nothing(capsys):
    _, W, mask = denoising_problem(n=25, d=5)
    W = np.where(mask, W, np.nan)
    grid = {"gamma": [0.5, 1.0], "tau": [0.1, 1.0]}
    quiet = HoldoutSearch(WarmRegularizer(), grid, n_folds=2, path="tau").fit(W)
    assert capsys.readouterr().out == ""
    loud = HoldoutSearch(WarmRegularizer(), grid, n_folds=2, path="tau", verbose=True).fit(W)
    lines = capsys.readouterr().out.splitlines()
    fits = [line for line in lines if ": error " in line]
    assert len(fits) == 2 * 2 * 2  # folds x gammas x taus, each once
    for fold in (1, 2):
        for gamma in (0.5, 1.0):
            for tau in (0.1, 1.0):
                assert sum(f"fold {fold}/2 {{'gamma': {gamma}, 'tau': {tau}}}:" in f for f in fits) == 1
    assert any("folds done: 2/2" in line for line in lines)
    assert any(f"chose {loud.best_params_}" in line for line in lines)
    assert all(line.startswith("[HoldoutSearch] ") for line in lines)
    np.testing.assert_array_equal(loud.best_estimator_.x_, quiet.best_estimator_.x_)
    np.testing.assert_array_equal(loud.cv_results_["mean_test_error"], quiet.cv_results_["mean_test_error"])


# --------------------------------------------------------------------------------------------------
# No escape (the isolation guard)
# --------------------------------------------------------------------------------------------------


def test_isolation_safe_rho0_puts_the_threshold_at_one():
    for tau in (1e-3, 0.1, 10.0, 1e3):
        assert cubic_threshold(tau, isolation_safe_rho0(tau)) == pytest.approx(1.0, rel=1e-12)


def test_guard_changes_nothing_when_rho0_is_already_safe():
    _, W, mask = denoising_problem(n=25, d=5)
    term, S0 = MaskedLeastSquares(W, mask), mean_impute(W, mask)
    # rho0 = 1 >= tau sqrt(27/8) = 0.184: the guard has nothing to raise
    plain = minimize_regularized(term, S0, gamma=0.5, tau=0.1, options={"isolation_guard": False})
    guarded = minimize_regularized(term, S0, gamma=0.5, tau=0.1, options={"isolation_guard": True})
    np.testing.assert_array_equal(plain.x, guarded.x)


def test_hidden_entries_never_escape_along_the_default_tau_grid():
    _, W, mask = denoising_problem()
    term, S0, gamma = MaskedLeastSquares(W, mask), mean_impute(W, mask), median_gamma(W, mask)
    for tau in DEFAULT_TAUS:
        res = minimize_regularized(term, S0, gamma=gamma, tau=tau, options={"isolation_guard": True})
        assert within_observed_range(res.x, W, mask), f"hidden entries escaped at tau={tau}"
    # The test can fail: without the guard the paper's schedule (rho0 = 1) disperses them at tau = 100.
    escaped = minimize_regularized(
        term, S0, gamma=gamma, tau=DEFAULT_TAUS[-1], options={"isolation_guard": False}
    )
    assert not within_observed_range(escaped.x, W, mask)
