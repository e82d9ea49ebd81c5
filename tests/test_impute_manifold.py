"""RobustKernelPCAImputer and DecompositionDenoiser (nldr.impute._manifold): the estimator contract, the
completion they wrap reproduced bit for bit, and the warm start a search over the neighbours uses."""

import numpy as np
import pytest
from sklearn.decomposition import PCA, KernelPCA
from sklearn.utils.estimator_checks import parametrize_with_checks
from test_impute import surface

from nldr._preimage import average_solutions
from nldr.impute import DecompositionDenoiser, RobustKernelPCAImputer
from nldr.model_selection import HoldoutSearch
from nldr.robust_kpca import RobustKernelPCA


@parametrize_with_checks([RobustKernelPCAImputer(), DecompositionDenoiser(PCA(n_components=1))])
def test_scikit_learn_estimator_checks(estimator, check):
    check(estimator)


@pytest.fixture
def data():
    rng = np.random.default_rng(7)
    X_train, X_new = surface(150, rng, noise=0.01), surface(30, rng, noise=0.01)
    mask = rng.random(X_new.shape) > 0.25
    mask[:, 0] |= ~mask.any(axis=1)
    return X_train, X_new, mask


KNOBS = [
    {"starts": "mean", "n_neighbors": 4},
    {"starts": "each", "n_neighbors": 4, "weights": "distance"},
    {"starts": "each", "n_neighbors": 3, "rho": 10.0, "loss": "huber", "delta": 0.1},
]


@pytest.mark.parametrize("knobs", KNOBS)
def test_transform_is_robust_kernel_pcas_complete_bit_for_bit(data, knobs):
    X_train, X_new, mask = data
    imputer = RobustKernelPCAImputer(standardize=False, gamma=1.0, tau=0.05, **knobs).fit(X_train)
    model = RobustKernelPCA(gamma=1.0, tau=0.05).fit(X_train)
    np.testing.assert_array_equal(imputer.model_.eigenvectors_, model.eigenvectors_)
    expected = model.complete(np.where(mask, X_new, np.nan), mask, **knobs)
    np.testing.assert_array_equal(imputer.transform(np.where(mask, X_new, np.nan)), expected)


def test_completion_keeps_observed_entries_and_beats_the_column_means(data):
    X_train, X_new, mask = data
    imputer = RobustKernelPCAImputer(standardize=False, gamma=1.0, tau=0.05, starts="each")
    X_hat = imputer.fit(X_train).transform(np.where(mask, X_new, np.nan))
    # kept: the mean of k copies of an observed entry, exact up to the rounding of that mean
    np.testing.assert_allclose(X_hat[mask], X_new[mask], rtol=8 * np.finfo(float).eps)
    means = np.broadcast_to(X_train.mean(axis=0), X_new.shape)
    assert np.sum((X_hat - X_new)[~mask] ** 2) < 0.5 * np.sum((means - X_new)[~mask] ** 2)


def test_incomplete_training_rows_stay_out_of_the_manifold(data):
    X_train, _, _ = data
    W = X_train.copy()
    W[::3, 1] = np.nan
    imputer = RobustKernelPCAImputer(standardize=False, gamma=1.0, tau=0.05).fit(W)
    np.testing.assert_array_equal(imputer.model_.X_fit_, X_train[np.isfinite(W).all(axis=1)])
    out = imputer.fit_transform(W)  # fit(W).transform(W): complete rows unchanged with rho None
    np.testing.assert_array_equal(out[1::3], X_train[1::3])
    assert np.isfinite(out).all()
    W[1:, 0] = np.nan
    with pytest.raises(ValueError, match="0 fully observed row"):
        RobustKernelPCAImputer().fit(W)


@pytest.mark.parametrize(
    "params, match",
    [({"loss": "huber"}, "delta"), ({"starts": "all"}, "starts"), ({"rho": -1.0}, "rho"),
     ({"tau": 0}, "tau")],  # fmt: skip
)
def test_bad_parameters_are_refused_naming_them(data, params, match):
    with pytest.raises(ValueError, match=match):
        RobustKernelPCAImputer(**params).fit(data[0])


def test_warm_start_reuses_the_manifold_and_the_largest_neighbour_solves(data):
    """A warm transform with fewer neighbours averages the previous transform's first local minima:
    the same as averaging complete_each's solutions by hand; and within the solver's tolerance of a
    cold transform (the L-BFGS blocks hold other rows)."""
    X_train, X_new, mask = data
    W = np.where(mask, X_new, np.nan)
    knobs = {"standardize": False, "gamma": 1.0, "tau": 0.05, "starts": "each"}
    imputer = RobustKernelPCAImputer(**knobs, n_neighbors=6, warm_start=True)
    imputer.fit(X_train).transform(W)
    model = imputer.model_
    imputer.set_params(n_neighbors=3, weights="distance").fit(X_train)
    assert imputer.model_ is model  # same rows and manifold parameters: not refitted
    warm = imputer.transform(W)
    sol, dist = model.complete_each(W, mask, n_neighbors=6)
    np.testing.assert_array_equal(warm, average_solutions(sol[:, :3], dist[:, :3], "distance"))
    cold = RobustKernelPCAImputer(**knobs, n_neighbors=3, weights="distance")
    np.testing.assert_allclose(warm, cold.fit(X_train).transform(W), atol=1e-4)
    imputer.set_params(tau=0.1).fit(X_train)
    assert imputer.model_ is not model  # another tau: refitted


def test_a_neighbour_search_on_the_warm_path_scores_the_truncated_solves(data):
    X_train, _, _ = data
    n = X_train.shape[0]
    fit_rows = np.arange(n) >= 20
    hidden = np.zeros(X_train.shape, dtype=bool)
    hidden[:20] = np.random.default_rng(1).random((20, X_train.shape[1])) < 0.3
    hidden[:20, 0] |= ~hidden[:20].any(axis=1)
    grid = {"n_neighbors": [6, 3], "starts": ["each"]}

    def sse(X, X_hat, h):
        return float(np.sum((X_hat - X)[h] ** 2))

    est = RobustKernelPCAImputer(standardize=False, gamma=1.0, tau=0.05, warm_start=True)
    folds = [(fit_rows, hidden)]
    search = HoldoutSearch(est, grid, folds=folds, scoring=sse, path="n_neighbors", refit=False)
    errors = search.fit(X_train).cv_results_["mean_test_error"]
    W = np.where(hidden[:20], np.nan, X_train[:20])
    model = RobustKernelPCA(gamma=1.0, tau=0.05).fit(X_train[fit_rows])
    sol, dist = model.complete_each(W, ~hidden[:20], n_neighbors=6)
    expected = [sse(X_train[:20], average_solutions(sol[:, :k], dist[:, :k]), hidden[:20]) for k in (6, 3)]
    np.testing.assert_array_equal(errors, expected)


@pytest.mark.parametrize(
    "decomposition",
    [PCA(n_components=2), KernelPCA(n_components=5, kernel="rbf", gamma=1.0, fit_inverse_transform=True)],
)
def test_reconstruction_is_inverse_transform_of_transform(data, decomposition):
    X_train, X_new, _ = data
    model = decomposition.fit(X_train)
    expected = model.inverse_transform(model.transform(X_new))
    denoised = DecompositionDenoiser(decomposition).fit(X_train).transform(X_new)
    np.testing.assert_array_equal(denoised, expected)
    with pytest.raises(ValueError, match="inverse_transform"):
        DecompositionDenoiser(RobustKernelPCAImputer()).fit(X_train)
