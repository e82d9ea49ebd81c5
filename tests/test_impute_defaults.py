"""The self-tuning defaults of KernelRegularizerImputer: tau and the width chosen by the hold-out search
on the observed entries inside ``fit`` (``tau="auto"``, ``gamma="auto"``)."""

import numpy as np
import pytest
from test_impute import hide, surface

from nldr._baselines import mean_impute
from nldr.impute import KernelRegularizerImputer, _defaults
from nldr.impute import _regularizer as module
from nldr.impute._base import canonical_row_order
from nldr.model_selection import holdout_folds


def median_rule(est, W, mask):
    S0 = mean_impute(np.where(mask, (W - est.mean_) / est.scale_, 0.0), mask)
    d2 = ((S0[:, None, :] - S0[None, :, :]) ** 2).sum(axis=2)[np.triu_indices(W.shape[0], 1)]
    return 1.0 / np.median(d2)


@pytest.fixture
def problem(rng):
    X = surface(40, rng, noise=0.01)
    W, mask = hide(X, 0.2, rng)
    return X, W, mask


def test_the_default_tunes_tau_and_width_within_the_grid_and_keeps_the_record(problem):
    _, W, mask = problem
    est = KernelRegularizerImputer().fit(W)
    gammas = np.asarray(module.TUNE_GAMMA_MULTIPLES) * median_rule(est, W, mask)
    taus = np.asarray(module.TUNE_TAUS)
    results = est.cv_results_
    assert len(results["params"]) == len(gammas) * len(taus)
    np.testing.assert_allclose(sorted(set(results["param_gamma"])), gammas, rtol=1e-12)
    np.testing.assert_allclose(sorted(set(results["param_tau"])), taus, rtol=0)
    assert est.tau_ in set(taus)
    assert np.min(np.abs(gammas - est.gamma_)) <= 1e-12 * est.gamma_
    # the choice is the candidate with the smallest mean hold-out error
    best = int(np.nanargmin(results["mean_test_error"]))
    assert results["params"][best] == {"gamma": est.gamma_, "tau": est.tau_}
    # the final solve is the chosen candidate's solve on every observed entry
    refit = KernelRegularizerImputer(gamma=est.gamma_, tau=est.tau_).fit(W)
    np.testing.assert_array_equal(refit.completed_, est.completed_)


def test_the_tuning_scores_are_the_hold_out_errors_of_the_documented_folds(problem):
    """Brute force for the cold solve of each fold (the first candidate): the fold's matrix, the solve
    at the fold tolerances, the mean squared error on the hidden entries, in standardised units (the
    search runs on the matrix standardised by the estimator's mean_ and scale_)."""
    _, W, mask = problem
    est = KernelRegularizerImputer(random_state=None).fit(W)
    order = canonical_row_order(W, mask)  # the folds index the rows sorted by their content
    W, mask = W[order], mask[order]
    Z = (W - est.mean_) / est.scale_
    folds = holdout_folds(mask, _defaults.TUNE_FOLDS, 0, holdout=_defaults.TUNE_HOLDOUT)
    first = est.cv_results_["params"][0]
    for k, hidden in enumerate(folds):
        fold = KernelRegularizerImputer(**first, method="exact", **module.TUNE_TOLERANCES)
        Z_hat = fold.fit_transform(np.where(hidden, np.nan, Z))
        error = np.mean((Z_hat - Z)[hidden] ** 2)
        assert est.cv_results_[f"split{k}_test_error"][0] == pytest.approx(error, rel=1e-8)


def test_a_fixed_knob_is_not_searched(problem):
    _, W, mask = problem
    est = KernelRegularizerImputer(tau=0.2).fit(W)
    assert set(est.cv_results_["param_tau"]) == {0.2}
    assert est.tau_ == 0.2
    fixed = KernelRegularizerImputer(tau=0.2, gamma=0.3).fit(W)
    assert not hasattr(fixed, "cv_results_")
    assert (fixed.tau_, fixed.gamma_) == (0.2, 0.3)


def test_below_the_tuning_size_the_defaults_are_the_median_rule_and_tau_0_1(rng):
    X = surface(module.TUNE_MIN_ROWS - 1, rng)
    W, mask = hide(X, 0.2, rng)
    est = KernelRegularizerImputer().fit(W)
    assert not hasattr(est, "cv_results_")
    assert est.tau_ == 0.1
    assert est.gamma_ == pytest.approx(module.MEDIAN_RULE_MULTIPLE * median_rule(est, W, mask), rel=1e-12)


def test_the_tuning_is_seeded(problem):
    _, W, _ = problem
    a = KernelRegularizerImputer(random_state=3).fit(W)
    b = KernelRegularizerImputer(random_state=3).fit(W)
    np.testing.assert_array_equal(a.completed_, b.completed_)
    np.testing.assert_array_equal(a.cv_results_["mean_test_error"], b.cv_results_["mean_test_error"])


@pytest.mark.parametrize("params", [{"tau": "automatic"}, {"gamma": "median"}, {"tau": -1.0}])
def test_a_bad_knob_names_the_choices(problem, params):
    _, W, _ = problem
    with pytest.raises(ValueError, match="auto"):
        KernelRegularizerImputer(**params).fit(W)


def test_transform_chooses_its_starts_at_the_first_new_row_by_the_row_folds(problem):
    X, W, _ = problem
    est = KernelRegularizerImputer().fit(W[:30])
    assert not hasattr(est, "n_neighbors_")  # nothing chosen until a new row comes
    np.testing.assert_array_equal(est.transform(W[:30]), est.completed_)  # seen rows: no choice needed
    assert not hasattr(est, "n_neighbors_")
    X_new = est.transform(W[30:])
    assert set(est.transform_results_) == set(_defaults.TUNE_TRANSFORM)
    best = min(est.transform_results_, key=est.transform_results_.get)
    assert (est.n_neighbors_, est.starts_) == best
    fixed = KernelRegularizerImputer(gamma=est.gamma_, tau=est.tau_, n_neighbors=best[0], starts=best[1])
    np.testing.assert_array_equal(fixed.fit(W[:30]).transform(W[30:]), X_new)
    assert not hasattr(fixed, "transform_results_")


@pytest.mark.parametrize("configfile", ["", "config/quick.yaml"])
@pytest.mark.parametrize("name", ["table2", "table2_full", "table2_all"])
def test_the_paper_tables_pass_every_knob_the_defaults_would_tune(name, configfile):
    """Table 2's Ours keeps the paper's settings: no "auto" default reaches its solve (transform is
    never called there)."""
    from pathlib import Path

    from nldr import experiments
    from nldr.experiments._table2 import paper_methods
    from nldr.experiments.notebook import load_config

    config = load_config(Path(__file__).resolve().parents[1], configfile)
    ours = paper_methods(experiments.get(name).settings(config))["Ours"]
    params = ours.get_params()
    assert isinstance(params["gamma"], float) and isinstance(params["tau"], float)
    assert params["standardize"] is False and params["method"] in ("exact", "nystroem-warm", "nystroem")


def brute_force_row_fold_errors(W, mask, gamma, tau, candidates):
    """The documented row folds drawn here afresh (seed 0: random_state None), one cold fit per fold and
    candidate at the fold solver, and the mean squared error on the hidden entries, averaged over folds."""
    n = W.shape[0]
    rng = np.random.default_rng(0)
    share = max(_defaults.TUNE_ROW_HIDDEN, 1.0 - mask.mean())
    errors = {c: [] for c in candidates}
    for _ in range(_defaults.TUNE_FOLDS):
        held = np.zeros(n, dtype=bool)
        held[rng.choice(n, max(1, int(round(_defaults.TUNE_ROW_SHARE * n))), replace=False)] = True
        observed = mask[held]
        hidden = observed & (rng.random(observed.shape) < share)
        for i in range(hidden.shape[0]):
            if observed[i].any() and not (observed[i] & ~hidden[i]).any():
                hidden[i, rng.choice(np.flatnonzero(observed[i]))] = False
        if not hidden.any():
            continue
        rows = np.where(observed & ~hidden, W[held], np.nan)
        for k, starts in candidates:
            fold = KernelRegularizerImputer(
                gamma=gamma, tau=tau, method="exact", **module.TUNE_TOLERANCES,
                n_neighbors=k, starts=starts, random_state=None,
            )  # fmt: skip
            X_hat = fold.fit(np.where(mask[~held], W[~held], np.nan)).transform(rows)
            errors[(k, starts)].append(np.mean((X_hat - W[held])[hidden] ** 2))
    return {c: float(np.mean(e)) for c, e in errors.items()}


@pytest.mark.parametrize("seed, p", [(0, 0.1), (1, 0.3), (2, 0.5)])
def test_the_row_fold_scores_are_the_brute_force_errors_and_cost_one_solve_per_fold(seed, p, monkeypatch):
    rng = np.random.default_rng(seed)
    X = surface(36, rng, noise=0.01)
    W, mask = hide(X, p, rng)
    W, mask, X_new = W[:30], mask[:30], W[30:]
    est = KernelRegularizerImputer(gamma=None, tau=0.1, random_state=None).fit(W)  # only transform's knobs
    solves = []
    real = module.minimize_regularized
    monkeypatch.setattr(module, "minimize_regularized", lambda *a, **kw: solves.append(1) or real(*a, **kw))
    est.transform(X_new)
    assert len(solves) == _defaults.TUNE_FOLDS  # the candidates of a fold share its one fit
    candidates = _defaults.TUNE_TRANSFORM
    order = canonical_row_order(W, mask)  # the row folds index the rows sorted by their content
    W_sorted, mask_sorted = np.nan_to_num(W)[order], mask[order]
    # the folds score standardised units
    Z = np.where(mask_sorted, (W_sorted - est.mean_) / est.scale_, 0.0)
    expected = brute_force_row_fold_errors(Z, mask_sorted, est.gamma_, est.tau_, candidates)
    assert list(est.transform_results_) == list(_defaults.TUNE_TRANSFORM)
    for candidate, error in expected.items():
        assert est.transform_results_[candidate] == pytest.approx(error, rel=1e-10)
    assert (est.n_neighbors_, est.starts_) == min(expected, key=expected.get)


def test_a_warm_refit_that_changes_only_transform_knobs_keeps_the_solve(problem):
    _, W, _ = problem
    est = KernelRegularizerImputer(gamma=None, tau=0.1, n_neighbors=5, starts="mean", warm_start=True).fit(W)
    result = est.result_
    est.set_params(n_neighbors=1, starts="each").fit(W)
    assert est.result_ is result and (est.n_neighbors_, est.starts_) == (1, "each")
    est.set_params(tau=0.2).fit(W)  # a knob of the solve: solved again (warm, from the previous answer)
    assert est.result_ is not result and est.tau_ == 0.2
    result = est.result_
    est.fit(W[:-1])  # another matrix: solved again
    assert est.result_ is not result
