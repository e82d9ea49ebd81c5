"""Hold-out model selection (nldr.model_selection) and the isolation guard of the penalty method."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from conftest import denoising_problem, within_observed_range
from threadpoolctl import threadpool_limits

from nldr._spectral import cubic_threshold
from nldr.baselines import mean_impute, ppca_impute
from nldr.data_terms import MaskedLeastSquares
from nldr.model_selection import (
    DEFAULT_TAUS,
    baseline_grid,
    holdout_folds,
    median_gamma,
    select_imputer,
    select_regularizer,
)
from nldr.regularizer import isolation_safe_rho0, minimize_regularized


@pytest.fixture(autouse=True)
def one_blas_thread():
    """Small matrices: one BLAS thread is faster beside a busy core (docs/DESIGN.md)."""
    with threadpool_limits(1):
        yield


def fold_error(W, mask, hidden, gamma, tau, method="exact", **options):
    """The hold-out error of one candidate on one fold, by hand (``options``: the solver's)."""
    train = mask & ~hidden
    W_train = np.where(train, W, np.nan)
    res = minimize_regularized(
        MaskedLeastSquares(W_train, train), mean_impute(W_train, train), gamma=gamma, tau=tau,
        method=method, options={"isolation_guard": True, **options},
    )
    return np.mean((res.x - W)[hidden] ** 2)


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


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"mask": np.ones((5, 5), dtype=bool)}, "shape"),
        ({"taus": [0.1, -1.0]}, "taus"),
        ({"gammas": []}, "gammas"),
        ({"n_folds": 1}, "n_folds"),
        ({"tau": 1.0}, "tau"),
        ({"holdout": 1.5}, "holdout"),
        ({"rule": "best"}, "rule"),
        ({"stop_factor": 1.0}, "stop_factor"),
    ],
)
def test_select_regularizer_rejects_bad_input_naming_it(kwargs, match):
    _, W, mask = denoising_problem(n=12, d=4)
    args = {"mask": mask, **kwargs}
    with pytest.raises(ValueError, match=match):
        select_regularizer(W, args.pop("mask"), **args)


def test_a_column_without_observed_entries_is_refused():
    _, W, mask = denoising_problem(n=12, d=4)
    mask[:, 1] = False
    with pytest.raises(ValueError, match="column"):
        select_regularizer(W, mask)


# --------------------------------------------------------------------------------------------------
# select_regularizer
# --------------------------------------------------------------------------------------------------


def test_cv_score_is_the_hand_computed_holdout_error_and_the_refit_is_the_solver():
    _, W, mask = denoising_problem(n=25, d=5)
    taus, gamma = [0.1, 1.0], median_gamma(W, mask)
    sel = select_regularizer(
        W, mask, taus=taus, gammas=[gamma], n_folds=2, holdout=None, rule="min", warm_start=False,
        stop_factor=None,
    )
    folds = holdout_folds(mask, 2, random_state=0)
    for tau in taus:
        errors = [fold_error(W, mask, h, gamma, tau, tol=1e-7, gtol=1e-4) for h in folds]
        row = sel.cv_results_[sel.cv_results_["tau"] == tau].iloc[0]
        assert row["mean_test_error"] == pytest.approx(np.mean(errors), rel=1e-12)
        assert row["std_test_error"] == pytest.approx(np.std(errors, ddof=1), rel=1e-9)
    assert list(sel.cv_results_.columns) == ["tau", "gamma", "mean_test_error", "std_test_error", "fit_time"]
    best = sel.cv_results_["mean_test_error"].idxmin()
    assert sel.tau_ == sel.cv_results_["tau"][best]
    refit = minimize_regularized(
        MaskedLeastSquares(W, mask), mean_impute(W, mask), gamma=sel.gamma_, tau=sel.tau_,
        options={"isolation_guard": True},
    )
    np.testing.assert_array_equal(sel.result_.x, refit.x)


def test_warm_started_path_is_the_hand_chain_of_last_stage_solves():
    _, W, mask = denoising_problem(n=25, d=5)
    gamma = median_gamma(W, mask)
    sel = select_regularizer(W, mask, taus=[1.0, 0.1], gammas=[gamma], n_folds=2, stop_factor=None)
    hidden = holdout_folds(mask, 2, random_state=0, holdout=0.1)  # the default folds
    errors = {0.1: [], 1.0: []}
    for h in hidden:
        train = mask & ~h
        W_train = np.where(train, W, np.nan)
        term = MaskedLeastSquares(W_train, train)
        opts = {"gamma": gamma, "options": {"isolation_guard": True, "tol": 1e-7, "gtol": 1e-4}}
        first = minimize_regularized(term, mean_impute(W_train, train), tau=0.1, **opts)
        second = minimize_regularized(term, first.x, tau=1.0, rho0=1e4, **opts)
        errors[0.1].append(np.mean((first.x - W)[h] ** 2))
        errors[1.0].append(np.mean((second.x - W)[h] ** 2))
    for tau, errs in errors.items():
        row = sel.cv_results_[sel.cv_results_["tau"] == tau].iloc[0]
        assert row["mean_test_error"] == pytest.approx(np.mean(errs), rel=1e-12)


def test_warm_gamma_chains_the_first_solves_of_the_gammas_by_hand():
    _, W, mask = denoising_problem(n=25, d=5)
    g1, g2 = 0.5 * median_gamma(W, mask), median_gamma(W, mask)
    sel = select_regularizer(W, mask, taus=[0.1], gammas=[g2, g1], n_folds=2, warm_gamma=True)
    opts = {"options": {"isolation_guard": True, "tol": 1e-7, "gtol": 1e-4}, "tau": 0.1}
    errors = {g1: [], g2: []}
    for h in sel.folds_:
        train = mask & ~h
        W_train = np.where(train, W, np.nan)
        term = MaskedLeastSquares(W_train, train)
        first = minimize_regularized(term, mean_impute(W_train, train), gamma=g1, **opts)  # smaller first
        second = minimize_regularized(term, first.x, gamma=g2, rho0=1e4, **opts)
        errors[g1].append(np.mean((first.x - W)[h] ** 2))
        errors[g2].append(np.mean((second.x - W)[h] ** 2))
    for gamma, errs in errors.items():
        row = sel.cv_results_[np.isclose(sel.cv_results_["gamma"], gamma)].iloc[0]
        assert row["mean_test_error"] == pytest.approx(np.mean(errs), rel=1e-12)


def test_one_se_rule_picks_the_smallest_tau_then_the_widest_kernel_within_one_standard_error():
    _, W, mask = denoising_problem(n=25, d=5)
    taus = [0.01, 0.1, 1.0, 10.0]
    one_se = select_regularizer(W, mask, taus=taus, n_folds=3, random_state=1)
    best = select_regularizer(W, mask, taus=taus, n_folds=3, random_state=1, rule="min")
    cv = one_se.cv_results_
    assert cv.equals(best.cv_results_.assign(fit_time=cv["fit_time"]))  # same folds, same scores
    i = cv["mean_test_error"].idxmin()
    assert (best.tau_, best.gamma_) == (cv["tau"][i], cv["gamma"][i])
    bound = cv["mean_test_error"][i] + cv["std_test_error"][i] / np.sqrt(3)
    close = cv[cv["mean_test_error"] <= bound]
    chosen = cv[(cv["tau"] == one_se.tau_) & (cv["gamma"] == one_se.gamma_)].iloc[0]
    assert chosen["mean_test_error"] <= bound
    assert one_se.tau_ == close["tau"].min()
    assert one_se.gamma_ == close[close["tau"] == one_se.tau_]["gamma"].min()


def test_one_se_tie_break_prefers_the_widest_kernel_over_a_lower_error():
    """Within one SE and at the smallest tau, the widest kernel wins even with a higher mean error."""
    from nldr.model_selection.regularizer import _choose

    cv = pd.DataFrame(
        {
            "tau": [0.01, 0.01, 0.01, 0.1],
            "gamma": [0.5, 0.1, 2.0, 0.1],
            "mean_test_error": [1.00, 1.02, 1.01, 0.99],
            "std_test_error": [0.1, 0.1, 0.1, 0.1],  # bound 0.99 + 0.1 / sqrt(4) = 1.04: all close
        }
    )
    assert _choose(cv, "one_se", n_folds=4) == 1  # tau 0.01, gamma 0.1
    assert _choose(cv, "min", n_folds=4) == 3
    cv.loc[1, "mean_test_error"] = 1.05  # now outside the bound: the widest close one is gamma 0.5
    assert _choose(cv, "one_se", n_folds=4) == 0


def test_early_stop_leaves_the_solved_scores_unchanged_and_skips_only_the_end_of_a_path():
    _, W, mask = denoising_problem(n=25, d=5)
    taus = [0.01, 0.1, 1.0, 10.0, 100.0]
    full = select_regularizer(W, mask, taus=taus, n_folds=2, stop_factor=None)
    cut = select_regularizer(W, mask, taus=taus, n_folds=2, stop_factor=1.05)
    assert full.cv_results_["mean_test_error"].notna().all()
    skipped = cut.cv_results_["mean_test_error"].isna()
    assert skipped.any()  # 1.05 is aggressive: some path must stop on this problem, or the test is void
    solved = ~skipped
    np.testing.assert_array_equal(
        cut.cv_results_["mean_test_error"][solved], full.cv_results_["mean_test_error"][solved]
    )
    for _, path in cut.cv_results_.groupby("gamma"):
        flags = path.sort_values("tau")["mean_test_error"].isna().to_numpy()
        assert not flags[0] and np.all(np.diff(flags.astype(int)) >= 0)  # a suffix of the taus
    assert not np.isnan(cut.cv_results_.set_index(["tau", "gamma"]).loc[(cut.tau_, cut.gamma_)].iloc[0])


def test_same_seed_same_answer():
    _, W, mask = denoising_problem(n=25, d=5)
    a = select_regularizer(W, mask, taus=[0.1, 1.0, 10.0], n_folds=3, random_state=7)
    b = select_regularizer(W, mask, taus=[0.1, 1.0, 10.0], n_folds=3, random_state=7)
    assert (a.tau_, a.gamma_) == (b.tau_, b.gamma_)
    cols = ["tau", "gamma", "mean_test_error", "std_test_error"]
    assert a.cv_results_[cols].equals(b.cv_results_[cols])
    assert len(a.cv_results_) == 3 * 3  # default gammas: three multiples of the median rule


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


# --------------------------------------------------------------------------------------------------
# Baselines
# --------------------------------------------------------------------------------------------------


def test_select_imputer_scores_ppca_by_hand_and_refits():
    _, W, mask = denoising_problem(n=30, d=6)
    impute, grid = baseline_grid("PPCA", W, mask)
    assert grid == {"n_components": [1, 2, 3, 4, 5]}
    sel = select_imputer(impute, W, mask, {"n_components": [1, 3]}, n_folds=3, random_state=2)
    folds = holdout_folds(mask, 3, random_state=2)
    for q in (1, 3):
        errs = []
        for h in folds:
            train = mask & ~h
            X_hat = ppca_impute(np.where(train, W, np.nan), train, n_components=q).x
            errs.append(np.mean((X_hat - W)[h] ** 2))
        row = sel.cv_results_[sel.cv_results_["n_components"] == q].iloc[0]
        assert row["mean_test_error"] == pytest.approx(np.mean(errs), rel=1e-12)
    refit = ppca_impute(np.where(mask, W, np.nan), mask, **sel.best_params_)
    np.testing.assert_array_equal(sel.result_.x, refit.x)


def test_baseline_grid_rejects_an_unknown_method():
    _, W, mask = denoising_problem(n=12, d=4)
    with pytest.raises(ValueError, match="method"):
        baseline_grid("Ours", W, mask)


def test_verbose_reports_every_candidate_solve_and_changes_nothing(capsys):
    _, W, mask = denoising_problem(n=25, d=5)
    kwargs = dict(taus=[0.1, 1.0], gammas=[0.5, 1.0], n_folds=2, stop_factor=None)
    quiet = select_regularizer(W, mask, **kwargs)
    assert capsys.readouterr().out == ""
    loud = select_regularizer(W, mask, verbose=True, **kwargs)
    lines = capsys.readouterr().out.splitlines()
    solves = [line for line in lines if "hold-out error" in line]
    assert len(solves) == 2 * 2 * 2  # folds x gammas x taus, each once
    for fold in (1, 2):
        for gamma in (0.5, 1.0):
            for tau in (0.1, 1.0):
                assert sum(f"fold {fold}/2 gamma={gamma:.4g} tau={tau:.4g}:" in s for s in solves) == 1
    assert any("fold jobs done: 2/2" in line for line in lines)
    assert any(f"chose tau={loud.tau_:.4g}, gamma={loud.gamma_:.4g}" in line for line in lines)
    assert all(line.startswith("[select_regularizer] ") for line in lines)
    np.testing.assert_array_equal(loud.result_.x, quiet.result_.x)
    np.testing.assert_array_equal(
        loud.cv_results_["mean_test_error"].to_numpy(), quiet.cv_results_["mean_test_error"].to_numpy()
    )

    impute, _ = baseline_grid("PPCA", W, mask)
    sel = select_imputer(impute, W, mask, {"n_components": [1, 2]}, n_folds=3, verbose=True)
    lines = capsys.readouterr().out.splitlines()
    assert sum("hold-out error" in line for line in lines) == 2 * 3
    assert any(f"chose {sel.best_params_}" in line for line in lines)


def test_fold_landmarks_score_the_nystroem_fold_solves_by_hand_and_keep_the_refit_exact():
    _, W, mask = denoising_problem(n=25, d=5)
    taus, gamma = [0.1, 1.0], median_gamma(W, mask)
    common = {"taus": taus, "gammas": [gamma], "n_folds": 2, "holdout": None, "rule": "min",
              "warm_start": False, "stop_factor": None}
    sel = select_regularizer(W, mask, fold_landmarks=10, **common)
    folds = holdout_folds(mask, 2, random_state=0)
    for tau in taus:
        fold = {"tol": 1e-7, "gtol": 1e-4}
        errors = [fold_error(W, mask, h, gamma, tau, "nystroem", landmarks=10, **fold) for h in folds]
        exact = [fold_error(W, mask, h, gamma, tau, tol=1e-7, gtol=1e-4) for h in folds]
        row = sel.cv_results_[sel.cv_results_["tau"] == tau].iloc[0]
        assert row["mean_test_error"] == pytest.approx(np.mean(errors), rel=1e-12)
        assert np.mean(errors) != np.mean(exact)  # the option reaches the fold solves
    refit = minimize_regularized(
        MaskedLeastSquares(W, mask), mean_impute(W, mask), gamma=sel.gamma_, tau=sel.tau_,
        options={"isolation_guard": True},
    )
    np.testing.assert_array_equal(sel.result_.x, refit.x)  # the refit is the exact solve
    # landmarks >= n is the exact kernel (minimize_regularized), so the selection is the exact one
    every = select_regularizer(W, mask, fold_landmarks=25, **common)
    plain = select_regularizer(W, mask, **common)
    cols = ["tau", "gamma", "mean_test_error", "std_test_error"]
    assert every.cv_results_[cols].equals(plain.cv_results_[cols])
    again = select_regularizer(W, mask, fold_landmarks=10, **common)
    assert again.cv_results_[cols].equals(sel.cv_results_[cols])  # same seed, same answer
    with pytest.raises(ValueError, match="fold_landmarks"):
        select_regularizer(W, mask, fold_landmarks=0, **common)
    # refit_options reach the refit alone: the fold scores are unchanged, the refit is that call
    path = {"method": "nystroem-warm", "options": {"landmarks": 8, "exact_stages": 2}}
    warm = select_regularizer(W, mask, fold_landmarks=10, refit_options=path, **common)
    assert warm.cv_results_[cols].equals(sel.cv_results_[cols])
    refit = minimize_regularized(
        MaskedLeastSquares(W, mask), mean_impute(W, mask), gamma=warm.gamma_, tau=warm.tau_,
        method="nystroem-warm", options={"landmarks": 8, "exact_stages": 2, "isolation_guard": True},
    )
    np.testing.assert_array_equal(warm.result_.x, refit.x)
    assert warm.result_.n_stages == refit.n_stages > sel.result_.n_stages  # one Nystroem stage more
    with pytest.raises(ValueError, match="refit option 'tau'"):
        select_regularizer(W, mask, refit_options={"tau": 1.0}, **common)
    with pytest.raises(ValueError, match="refit option 'isolation_guard'"):
        select_regularizer(W, mask, refit_options={"options": {"isolation_guard": False}}, **common)
