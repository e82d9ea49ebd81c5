"""The baselines as scikit-learn imputers (nldr.impute): each estimator's fit_transform is its solver
function's output (the same computation, so equal bit for bit), transform completes new rows from the
fitted model, and bad options are refused naming them."""

import numpy as np
import pytest
from sklearn.impute import SimpleImputer
from threadpoolctl import threadpool_limits

from nldr._baselines import (
    mean_impute,
    nearest_neighbour_impute,
    pkpca_impute,
    ppca_impute,
    rkpca_impute,
    soft_impute,
)
from nldr._baselines.rpca import rpca_impute
from nldr.impute import (
    NearestNeighbourImputer,
    PKPCAImputer,
    PPCAImputer,
    RKPCAImputer,
    RobustPCAImputer,
    SoftImputer,
)


@pytest.fixture(autouse=True)
def single_threaded_blas():
    with threadpool_limits(limits=1):
        yield


def low_rank(rng, n=40, d=6, r=2, noise=0.05):
    return rng.normal(size=(n, r)) @ rng.normal(size=(r, d)) + noise * rng.normal(size=(n, d))


def hide(X, p, rng):
    mask = rng.random(X.shape) >= p
    mask[np.arange(X.shape[0]), rng.integers(0, X.shape[1], X.shape[0])] = True
    mask[: X.shape[0] // 4] = True  # complete rows, so 1-NN has donors
    return np.where(mask, X, np.nan), mask


# (estimator, the solver call with the same settings), in the data's units: the estimators standardise by
# default, the solver functions do not
CASES = {
    "PPCA": (PPCAImputer(standardize=False, n_components=2), lambda W, m: ppca_impute(W, m, 2).x),
    "PPCA default q": (PPCAImputer(standardize=False), lambda W, m: ppca_impute(W, m, 5).x),
    "PKPCA": (PKPCAImputer(standardize=False, gamma=0.3), lambda W, m: pkpca_impute(W, m, 0.3).x),
    "PKPCA q": (
        PKPCAImputer(standardize=False, gamma=0.3, n_components=3),
        lambda W, m: pkpca_impute(W, m, 0.3, n_components=3).x,
    ),
    "RKPCA": (RKPCAImputer(standardize=False, gamma=0.3), lambda W, m: rkpca_impute(W, m, 0.3).x),
    "RKPCA weight": (
        RKPCAImputer(standardize=False, gamma=0.3, n_components=0.9, weight=2.0),
        lambda W, m: rkpca_impute(W, m, 0.3, n_components=0.9, weight=2.0).x,
    ),
    "1-NN": (NearestNeighbourImputer(standardize=False), lambda W, m: nearest_neighbour_impute(W, m).x),
    "SoftImpute": (SoftImputer(standardize=False, lam=0.5), lambda W, m: soft_impute(W, m, lam=0.5).x),
    "RPCA": (
        RobustPCAImputer(standardize=False, lam_factor=2.0, denoise=True),  # the solver's L on every entry
        lambda W, m: rpca_impute(W, m, lam_factor=2.0).x,
    ),
    "PPCA solver knobs": (
        PPCAImputer(standardize=False, n_components=2, max_iter=3, accelerate=False),
        lambda W, m: ppca_impute(W, m, 2, max_iter=3, accelerate=False).x,
    ),
}


@pytest.mark.parametrize("name", list(CASES))
def test_fit_transform_is_the_solver_function(rng, name):
    est, solve = CASES[name]
    W, mask = hide(low_rank(rng), 0.2, rng)
    np.testing.assert_array_equal(est.fit_transform(W), solve(W, mask))
    np.testing.assert_array_equal(est.transform(W), est.completed_)  # rows seen in fit


def test_simple_imputer_is_the_mean_baseline(rng):
    W, mask = hide(low_rank(rng), 0.3, rng)
    np.testing.assert_allclose(SimpleImputer().fit_transform(W), mean_impute(W, mask), rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize(
    "est",
    [PPCAImputer(n_components=2), PKPCAImputer(gamma=0.2), RKPCAImputer(gamma=0.2, n_components=3),
     NearestNeighbourImputer(), SoftImputer(), RobustPCAImputer()],
    ids=lambda e: type(e).__name__,
)  # fmt: skip
def test_transform_new_rows_keeps_observed_entries_and_beats_the_means(rng, est):
    X = low_rank(rng, n=90, noise=0.02)
    W, mask = hide(X, 0.25, rng)
    est.fit(W[:60])
    new, new_mask = W[60:], mask[60:]
    new_mask[:, 0] = False  # no row of the new ones fully observed, none seen in fit
    new = np.where(new_mask, new, np.nan)
    X_hat = est.transform(new)
    np.testing.assert_array_equal(X_hat[new_mask], new[new_mask])
    err = np.sum((X_hat - X[60:])[~new_mask] ** 2)
    means = np.nanmean(W[:60], axis=0)
    assert err < 0.5 * np.sum((means - X[60:])[~new_mask] ** 2)


def test_ppca_posterior_mean_of_new_rows_is_the_e_step(rng):
    X = low_rank(rng)
    W, mask = hide(X, 0.2, rng)
    est = PPCAImputer(standardize=False, n_components=2).fit(W)
    mu, C, s2 = est.mean_, est.components_, est.noise_variance_
    w, o = W[-1], mask[-1].copy()
    o[:2] = False
    # E[x_m | x_o] for x ~ N(mu, C C^T + s2 I)
    cov = C @ C.T + s2 * np.eye(C.shape[0])
    cond = mu[~o] + cov[np.ix_(~o, o)] @ np.linalg.solve(cov[np.ix_(o, o)], w[o] - mu[o])
    row = np.where(o, w, np.nan)[None, :] + 1e-3  # a new row (not one seen in fit)
    got = est.transform(row)[0]
    expect = mu[~o] + cov[np.ix_(~o, o)] @ np.linalg.solve(cov[np.ix_(o, o)], row[0, o] - mu[o])
    np.testing.assert_allclose(got[~o], expect, rtol=1e-8, atol=1e-10)
    assert cond.shape == expect.shape


def test_one_nn_without_donor_is_refused(rng):
    X = low_rank(rng, n=10)
    W = X.copy()
    W[np.arange(10), np.arange(10) % 6] = np.nan
    with pytest.raises(ValueError, match="no fully observed row"):
        NearestNeighbourImputer().fit(W)


def test_ppca_on_one_row_is_refused():
    with pytest.raises(ValueError, match="1 sample"):
        PPCAImputer(n_components=1).fit(np.ones((1, 3)))


@pytest.mark.parametrize(
    ("est", "name"),
    [(PPCAImputer(max_iter=0), "max_iter"), (PKPCAImputer(gtol=-1.0), "gtol"),
     (SoftImputer(tol=0.0), "tol"), (RobustPCAImputer(mu=-1.0), "mu"),
     (RKPCAImputer(inner_max_iter=2.5), "inner_max_iter")],
    ids=lambda e: type(e).__name__ if not isinstance(e, str) else e,
)  # fmt: skip
def test_bad_solver_knobs_are_refused_naming_them(rng, est, name):
    W, _ = hide(low_rank(rng), 0.2, rng)
    with pytest.raises(ValueError, match=f"'{name}' parameter of {type(est).__name__}"):
        est.fit(W)


@pytest.mark.parametrize("cls", [PPCAImputer, PKPCAImputer, SoftImputer, RobustPCAImputer, RKPCAImputer])
def test_solver_knobs_are_parameters_not_an_options_dict(cls):
    with pytest.raises(TypeError, match="options"):
        cls(options={"max_iter": 3})
