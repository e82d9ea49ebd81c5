"""The self-tuning defaults of KernelRegularizerImputer: tau and the width chosen by the hold-out search
on the observed entries inside ``fit`` (``tau="auto"``, ``gamma="auto"``)."""

import numpy as np
import pytest
from test_impute import hide, surface

from nldr.baselines import mean_impute
from nldr.impute import KernelRegularizerImputer
from nldr.impute import regularizer as module
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
    at the fold tolerances, the mean squared error on the hidden entries."""
    _, W, mask = problem
    est = KernelRegularizerImputer(random_state=None).fit(W)
    folds = holdout_folds(mask, module.TUNE_FOLDS, 0, holdout=module.TUNE_HOLDOUT)
    first = est.cv_results_["params"][0]
    for k, hidden in enumerate(folds):
        fold = KernelRegularizerImputer(**first, method="exact", options=dict(module._TUNE_TOLERANCES))
        X_hat = fold.fit_transform(np.where(hidden, np.nan, W))
        error = np.mean((X_hat - W)[hidden] ** 2)
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
    assert set(est.transform_results_) == set(module.TUNE_TRANSFORM)
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
    from nldr.experiments.notebook import load_config
    from nldr.experiments.table2 import paper_methods

    config = load_config(Path(__file__).resolve().parents[1], configfile)
    ours = paper_methods(experiments.get(name).settings(config))["Ours"]
    params = ours.get_params()
    assert isinstance(params["gamma"], float) and isinstance(params["tau"], float)
    assert params["standardize"] is False and params["method"] in ("exact", "nystroem-warm", "nystroem")
