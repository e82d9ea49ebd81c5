"""Pipeline consistency and stability of the imputers: ``transform`` treats the rows ``fit`` saw as
``fit_transform`` did, identical rows get one estimate, an imputer keeps the observed entries (a
denoiser is the named option ``denoise``), the "auto" choices of the kernel regularizer do not depend
on the row order or ``random_state``, at every size.
Tiny data: the whole file runs in seconds."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import curve_rows
from sklearn.base import clone
from sklearn.datasets import load_wine
from sklearn.model_selection import StratifiedKFold
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

from nldr import impute
from nldr.datasets import load_oil
from nldr.impute import KernelRegularizerImputer, RobustPCAImputer
from nldr.impute import _defaults as defaults


@pytest.fixture
def oil(data_dir):
    """The first 40 oil-flow rows with 20 % of the entries hidden (seeded)."""
    X = load_oil("train", data_dir)[0][:40].copy()
    X[np.random.default_rng(0).random(X.shape) < 0.2] = np.nan
    return X


def _imputers():
    """Every estimator of nldr.impute that takes NaN (all but the DecompositionDenoiser), default
    parameters, and with ``denoise=True`` where there is that option."""
    for name in impute.__all__:
        if name == "DecompositionDenoiser":
            continue
        estimator = getattr(impute, name)()
        yield pytest.param(estimator, id=name)
        if "denoise" in estimator.get_params():
            yield pytest.param(clone(estimator).set_params(denoise=True), id=f"{name}-denoise")


@pytest.mark.parametrize("estimator", list(_imputers()))
def test_transform_of_the_fitted_rows_is_fit_transform_and_copies_share_one_estimate(estimator):
    """One computation, so exact: fit_transform(X), fit(X).transform(X) and transform(X) after
    fit_transform are the same array; every copy of a duplicated row (same values, same missing
    entries) gets one estimate, and transform returns it for each copy; observed entries are kept
    unless ``denoise``."""
    X = curve_rows()
    D = np.vstack([X, X])
    observed = ~np.isnan(X)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # convergence notes of the baselines are not the point here
        model = clone(estimator)
        F = model.fit_transform(X)
        np.testing.assert_array_equal(model.transform(X), F)
        np.testing.assert_array_equal(clone(estimator).fit(X).transform(X), F)
        FD = model.fit_transform(D)
        np.testing.assert_array_equal(FD[: len(X)], FD[len(X) :])
        np.testing.assert_array_equal(model.transform(D), FD)
    if not model.get_params().get("denoise", False):
        np.testing.assert_array_equal(F[observed], X[observed])


@pytest.mark.parametrize("estimator", list(_imputers()))
def test_new_rows_keep_their_observed_entries_unless_denoised(estimator):
    """A Pipeline's test rows are new to the imputer: they are treated like its training rows, the
    observed entries kept by an imputer and re-estimated by a denoiser."""
    X = curve_rows(n=30)
    train, test = X[:24], X[24:]
    observed = ~np.isnan(test)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        T = clone(estimator).fit(train).transform(test)
    assert not np.isnan(T).any()
    if estimator.get_params().get("denoise", False):
        assert not np.array_equal(T[observed], test[observed])
    else:
        np.testing.assert_array_equal(T[observed], test[observed])


def test_the_denoised_training_rows_are_the_solves_estimate():
    X = curve_rows()
    rpca = RobustPCAImputer(denoise=True, standardize=False)  # result_ is in the solved units
    np.testing.assert_array_equal(rpca.fit_transform(X), rpca.result_.x)
    ours = KernelRegularizerImputer(gamma=0.5, tau=0.1, denoise=True)
    S = ours.fit_transform(X)
    np.testing.assert_array_equal(S, ours.manifold_rows_ * ours.scale_ + ours.mean_)
    kept = KernelRegularizerImputer(gamma=0.5, tau=0.1).fit_transform(X)
    missing = np.isnan(X)
    np.testing.assert_array_equal(kept[missing], S[missing])  # the same solve either way


def test_robust_pca_in_a_pipeline_treats_training_and_test_rows_alike():
    """The wine classifier of the issue: in every split of a cross-validation, the rows the Pipeline
    trains on and the rows it scores pass through the imputer the same way, observed entries kept."""
    X, y = load_wine(return_X_y=True)
    X = X.copy()
    X[np.random.default_rng(0).random(X.shape) < 0.2] = np.nan
    for train, test in StratifiedKFold(3).split(X, y):
        pipe = make_pipeline(RobustPCAImputer(), StandardScaler()).fit(X[train])
        imputer = pipe[0]  # what the scaler (and a classifier after it) was fitted on: its completed_
        seen, new = ~np.isnan(X[train]), ~np.isnan(X[test])
        np.testing.assert_array_equal(imputer.completed_[seen], X[train][seen])
        np.testing.assert_array_equal(imputer.transform(X[test])[new], X[test][new])


@pytest.mark.parametrize("params", [{"gamma": 0.3, "tau": 0.1}, {}], ids=["fixed", "defaults"])
def test_duplicated_oil_rows_get_one_estimate(oil, params):
    D = np.vstack([oil[:20], oil[:20]])
    model = KernelRegularizerImputer(**params)
    F = model.fit_transform(D)
    np.testing.assert_array_equal(F[:20], F[20:])
    np.testing.assert_array_equal(model.transform(D), F)


def _relative_energy_gap(a, b) -> float:
    return abs(a.result_.fun - b.result_.fun) / abs(a.result_.fun)


def _energy_bound(model) -> float:
    """The two solves minimise one energy (it does not depend on the order of the rows, and a change
    of 1e-15 relative moves it by rounding only), each stage stopping when the energy's relative
    decrease per iteration is below ``tol``: at most ``max_iter`` iterations' worth of decreases
    below ``tol`` separate two such stops. ``tol`` is the one the fit's last stage used (``"auto"``
    resolves by the path: the estimator's own solver arguments)."""
    kwargs = model._solver_arguments(model.completed_.shape[0], warm=False)[1]
    return model.max_iter * kwargs["options"]["tol"]


def test_the_default_choices_do_not_depend_on_the_row_order(oil):
    order = np.random.default_rng(2).permutation(len(oil))
    a = KernelRegularizerImputer().fit(oil)
    b = KernelRegularizerImputer().fit(oil[order])
    assert b.tau_ == a.tau_
    assert b.gamma_ == pytest.approx(a.gamma_, rel=1e-12)  # the median rule, summed in another order
    assert _relative_energy_gap(a, b) <= _energy_bound(a)


def test_the_default_choices_do_not_depend_on_random_state(oil):
    """Up to AUTO_EXACT_MAX_ROWS rows nothing else is drawn: the fits are the same array."""
    fits = [KernelRegularizerImputer(random_state=seed).fit(oil) for seed in range(4)]
    for fit in fits[1:]:
        assert (fit.gamma_, fit.tau_) == (fits[0].gamma_, fits[0].tau_)
        np.testing.assert_array_equal(fit.completed_, fits[0].completed_)


def test_a_rounding_level_change_keeps_the_choices_and_the_energy(oil):
    noise = 1.0 + 1e-15 * np.random.default_rng(1).standard_normal(oil.shape)
    a = KernelRegularizerImputer().fit(oil)
    b = KernelRegularizerImputer().fit(oil * noise)
    assert b.tau_ == a.tau_
    assert b.gamma_ == pytest.approx(a.gamma_, rel=1e-12)
    assert _relative_energy_gap(a, b) <= _energy_bound(a)


def test_above_the_exact_rows_the_default_solve_does_not_depend_on_random_state_or_the_order(
    oil, monkeypatch
):
    """Above AUTO_EXACT_MAX_ROWS "auto" runs the Nystroem kernel on pivoted landmarks, a function of the
    data: other seeds give the same array, and the rows in another order the same landmarks (so the
    same energy, to the stopping tolerance: one computation on permuted rows)."""
    from nldr.impute import _regularizer as module

    monkeypatch.setattr(module, "AUTO_EXACT_MAX_ROWS", 20)
    monkeypatch.setattr(module, "AUTO_LANDMARKS", 12)
    monkeypatch.setattr(module, "AUTO_KNN_MIN_ROWS", 20)  # from the nearest rows' fill, a function of the set
    fits = [KernelRegularizerImputer(gamma=None, tau=0.1, random_state=seed).fit(oil) for seed in (0, 7)]
    assert fits[0].method_ == "nystroem"
    np.testing.assert_array_equal(fits[1].completed_, fits[0].completed_)
    order = np.random.default_rng(2).permutation(oil.shape[0])
    shuffled = KernelRegularizerImputer(gamma=None, tau=0.1).fit(oil[order])
    assert _relative_energy_gap(fits[0], shuffled) <= _energy_bound(fits[0])


def test_from_the_search_rows_the_default_is_the_median_rule(oil, monkeypatch):
    """From TUNE_MAX_ROWS rows "auto" runs no search: the median rule's width and UNTUNED_TAU, the fit
    of those values written out."""
    from nldr.impute import _regularizer as module

    monkeypatch.setattr(module, "TUNE_MAX_ROWS", 30)
    auto = KernelRegularizerImputer().fit(oil)
    assert not hasattr(auto, "cv_results_") and auto.tau_ == defaults.UNTUNED_TAU
    fixed = KernelRegularizerImputer(gamma=None, tau=defaults.UNTUNED_TAU).fit(oil)
    assert auto.gamma_ == fixed.gamma_
    np.testing.assert_array_equal(auto.completed_, fixed.completed_)
    assert hasattr(KernelRegularizerImputer().fit(oil[:29]), "cv_results_")
