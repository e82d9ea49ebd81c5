"""The peers: SoftImpute (nldr._baselines.peers) against its optimality condition and cvxpy; the
scikit-learn imputers as nldr.impute._grids.baseline_grid configures them (synthetic data, fast)."""

import numpy as np
import pytest
from sklearn.impute import KNNImputer
from threadpoolctl import threadpool_limits

from nldr._baselines import mean_impute, singular_value_threshold, soft_impute, soft_impute_objective
from nldr.impute._grids import baseline_grid, iterative_imputer, missforest_imputer
from nldr.model_selection import HoldoutSearch


@pytest.fixture(autouse=True)
def single_threaded_blas():
    with threadpool_limits(limits=1):
        yield


def low_rank_problem(n=30, d=8, rank=3, noise=0.1, p_missing=0.3, seed=0):
    """A rank-3 matrix plus noise, entries missing with probability p (every row and column keeps some)."""
    rng = np.random.default_rng(seed)
    X = rng.normal(size=(n, rank)) @ rng.normal(size=(rank, d)) + noise * rng.normal(size=(n, d)) + 2.0
    while True:
        mask = rng.random(X.shape) >= p_missing
        if mask.any(axis=0).all() and mask.any(axis=1).all():
            return X, np.where(mask, X, np.nan), mask


def optimality_violation(Z, W, mask, lam):
    """How far P_O(W - Z) is from lam * (subdifferential of the nuclear norm at Z).

    The subdifferential is {U V^T + N : U^T N = 0, N V = 0, ||N||_2 <= 1} with Z = U S V^T (thin SVD,
    rank r). Returns the largest of ||U^T G V - lam I||_F, ||(I - U U^T) G V||_F, ||U^T G (I - V V^T)||_F
    and max(0, ||(I - U U^T) G (I - V V^T)||_2 - lam), for G = P_O(W - Z).
    """
    G = np.where(mask, np.where(mask, W, 0.0) - Z, 0.0)
    U, s, Vt = np.linalg.svd(Z, full_matrices=False)
    r = int(np.sum(s > 1e-9 * max(s[0], 1e-300))) if s.size else 0
    U, V = U[:, :r], Vt[:r].T
    PU = np.eye(Z.shape[0]) - U @ U.T
    PV = np.eye(Z.shape[1]) - V @ V.T
    parts = [
        np.linalg.norm(U.T @ G @ V - lam * np.eye(r)),
        np.linalg.norm(PU @ G @ V),
        np.linalg.norm(U.T @ G @ PV),
        max(0.0, np.linalg.norm(PU @ G @ PV, 2) - lam),
    ]
    return max(parts)


# ------------------------------------------------------------------------------------- SoftImpute


def test_singular_value_threshold_is_the_prox_of_the_nuclear_norm():
    rng = np.random.default_rng(1)
    Y = rng.normal(size=(7, 5))
    lam = 1.3
    Z, rank = singular_value_threshold(Y, lam)
    s = np.linalg.svd(Y, compute_uv=False)
    np.testing.assert_allclose(np.linalg.svd(Z, compute_uv=False)[:rank], s[:rank] - lam, rtol=1e-12)
    assert rank == np.sum(s > lam)
    # prox optimality: Y - Z in lam * d||Z||_*, i.e. the same condition with every entry observed
    assert optimality_violation(Z, Y, np.ones_like(Y, dtype=bool), lam) <= 1e-12 * np.abs(Y).max()


@pytest.mark.parametrize("lam", [0.3, 2.0, 8.0])
def test_soft_impute_meets_the_optimality_condition_to_its_last_step(lam):
    _, W, mask = low_rank_problem()
    res = soft_impute(W, mask, lam=lam, center=False, tol=1e-24, max_iter=20000)
    # P_O(W - Z) is within ||Z_k - Z_{k-1}||_F of lam * d||Z||_* (module docstring): step is the bound,
    # 1e-10 the rounding of the SVDs at entries of size ~10
    bound = res.step + 1e-10
    assert res.step < 1e-8, res.message  # converged far enough for the check to mean something
    assert optimality_violation(res.Z, W, mask, lam) <= bound
    # ... and the check can fail: the same Z is not optimal for another lam
    assert optimality_violation(res.Z, W, mask, 1.2 * lam) > 100 * bound
    assert res.fun == pytest.approx(soft_impute_objective(res.Z, W, mask, lam), rel=1e-12)
    np.testing.assert_array_equal(res.x[mask], W[mask])
    np.testing.assert_array_equal(res.x[~mask], res.Z[~mask])


def test_soft_impute_agrees_with_cvxpy_on_a_tiny_problem():
    cp = pytest.importorskip("cvxpy")
    _, W, mask = low_rank_problem(n=7, d=5, rank=2, seed=3)
    lam = 0.8
    res = soft_impute(W, mask, lam=lam, center=False, tol=1e-24, max_iter=20000)
    Z = cp.Variable(W.shape)
    M = mask.astype(float)
    objective = 0.5 * cp.sum_squares(cp.multiply(M, Z - np.where(mask, W, 0.0))) + lam * cp.normNuc(Z)
    problem = cp.Problem(cp.Minimize(objective))
    problem.solve(solver=cp.SCS, eps=1e-9, max_iters=200000)
    f_cvx = soft_impute_objective(Z.value, W, mask, lam)  # our evaluation of cvxpy's point
    # ours is a minimiser to its step; SCS's point is feasible, so it cannot be lower than the minimum
    # beyond our own accuracy, and SCS at eps 1e-9 reaches the minimum to ~1e-6 relative
    assert res.fun <= f_cvx + 1e-9 * abs(f_cvx)
    assert res.fun == pytest.approx(f_cvx, rel=1e-6)
    assert res.fun == pytest.approx(problem.value, rel=1e-6)


def test_soft_impute_centres_on_observed_column_means():
    _, W, mask = low_rank_problem(seed=5)
    lam = 1.0
    res = soft_impute(W, mask, lam=lam, tol=1e-20, max_iter=20000)
    mu = np.array([W[mask[:, j], j].mean() for j in range(W.shape[1])])
    plain = soft_impute(W - mu, mask, lam=lam, center=False, tol=1e-20, max_iter=20000)
    np.testing.assert_allclose(res.column_means, mu, rtol=1e-14)
    np.testing.assert_allclose(res.x, plain.x + mu, atol=1e-9)


def test_soft_impute_with_lam_at_the_top_singular_value_is_mean_imputation():
    _, W, mask = low_rank_problem(seed=2)
    mu = np.array([W[mask[:, j], j].mean() for j in range(W.shape[1])])
    top = np.linalg.svd(np.where(mask, W - mu, 0.0), compute_uv=False)[0]
    res = soft_impute(W, mask, lam=top * (1 + 1e-12))
    assert res.rank == 0 and res.success and res.nit == 1
    np.testing.assert_allclose(res.x, mean_impute(W, mask), rtol=1e-14)
    # just below the top singular value the first iterate keeps one direction
    assert soft_impute(W, mask, lam=0.99 * top, max_iter=1).rank == 1


def test_soft_impute_reports_an_iteration_limit_and_rejects_bad_parameters():
    _, W, mask = low_rank_problem()
    res = soft_impute(W, mask, lam=0.1, tol=1e-30, max_iter=3)
    assert not res.success and res.nit == 3 and "max_iter" in res.message
    for kwargs, match in [
        ({"lam": -1.0}, "lam"),
        ({"lam": np.nan}, "lam"),
        ({"lam": 1.0, "tol": 0.0}, "tol"),
        ({"lam": 1.0, "max_iter": 0}, "max_iter"),
        ({"lam": 1.0, "Z0": np.zeros((2, 2))}, "Z0"),
    ]:
        with pytest.raises(ValueError, match=match):
            soft_impute(W, mask, **kwargs)


def test_soft_impute_warm_start_reaches_the_same_minimiser():
    _, W, mask = low_rank_problem(seed=4)
    cold = soft_impute(W, mask, lam=0.5, center=False, tol=1e-24, max_iter=20000)
    warm_from = soft_impute(W, mask, lam=1.0, center=False, tol=1e-24, max_iter=20000)
    warm = soft_impute(W, mask, lam=0.5, center=False, tol=1e-24, max_iter=20000, Z0=warm_from.Z)
    assert warm.fun == pytest.approx(cold.fun, rel=1e-9)


# -------------------------------------------------------------------------- scikit-learn's imputers


def test_chained_imputers_keep_observed_entries_repeat_with_the_seed_and_beat_the_mean():
    X, W, mask = low_rank_problem(n=60, d=6, rank=2, noise=0.05, seed=8)
    sse_mean = np.sum((mean_impute(W, mask) - X) ** 2)
    for make in (iterative_imputer, missforest_imputer):
        Y = make().fit_transform(W)
        assert Y.shape == X.shape and np.all(np.isfinite(Y))
        np.testing.assert_array_equal(Y[mask], W[mask])
        np.testing.assert_array_equal(Y, make().fit_transform(W))  # seeded: same answer
        # rank-2 data with 5 % noise: regression on the other columns must do better than column means
        assert np.sum((Y - X) ** 2) < 0.5 * sse_mean
    other_seed = missforest_imputer(random_state=1).fit_transform(W)
    assert not np.array_equal(other_seed, missforest_imputer().fit_transform(W))


def test_soft_impute_refuses_bad_inputs_naming_the_argument():
    X = np.random.default_rng(0).normal(size=(10, 3))
    mask = np.ones_like(X, dtype=bool)
    mask[0, 0] = False
    with pytest.raises(ValueError, match="mask"):
        soft_impute(X, mask[:, :2], lam=0.1)
    with pytest.raises(ValueError, match="mask"):
        soft_impute(X, np.where(mask, 1, 2), lam=0.1)
    W = X.copy()
    W[1, 1] = np.nan
    with pytest.raises(ValueError, match="observed entries"):
        soft_impute(W, mask, lam=0.1)
    with pytest.raises(ValueError, match="W"):
        soft_impute(X[0], mask[0], lam=0.1)
    empty = mask.copy()
    empty[:, 1] = False
    with pytest.raises(ValueError, match="column"):
        soft_impute(X, empty, lam=0.1)


# ---------------------------------------------------------------------------------------- grids


def test_peer_grids_and_selection_with_and_without_a_knob():
    X, W, mask = low_rank_problem(n=25, d=5, seed=9)
    estimator, grid = baseline_grid("KNNImputer", W)
    assert isinstance(estimator, KNNImputer) and grid == {
        "n_neighbors": [1, 2, 3, 5, 10, 20],
        "weights": ["uniform", "distance"],
    }
    search = HoldoutSearch(estimator, grid, n_folds=3).fit(W)
    assert search.best_params_["n_neighbors"] in grid["n_neighbors"]
    estimator, grid = baseline_grid("IterativeImputer", W)
    assert grid == {}
    search = HoldoutSearch(estimator, grid, n_folds=3, random_state=0)
    assert search.fit(W).best_params_ == {} and len(search.cv_results_["params"]) == 1
    np.testing.assert_array_equal(search.transform(W), iterative_imputer().fit_transform(W))
    forest, grid = baseline_grid("missForest", W)
    assert grid == {"estimator__max_features": [1 / 3, 1.0]}
    assert forest.estimator.n_estimators == 100  # missForest's authors' and scikit-learn's default
    assert baseline_grid("missForest", W, n_trees=10)[0].estimator.n_estimators == 10
    with pytest.raises(ValueError, match="n_trees"):
        baseline_grid("missForest", W, n_trees=0)
    # the largest lam is 0.3 of the value at which the completion is mean imputation, in the units
    # the imputer solves in: the columns standardised by their observed entries (default), or X's own
    mu = np.array([W[mask[:, j], j].mean() for j in range(W.shape[1])])
    sd = np.array([W[mask[:, j], j].std() for j in range(W.shape[1])])
    top = np.linalg.svd((np.where(mask, W, mu) - mu) / sd, compute_uv=False)[0]
    assert max(baseline_grid("SoftImpute", W)[1]["lam"]) == pytest.approx(0.3 * top, rel=1e-10)
    estimator, grid = baseline_grid("SoftImpute", W, standardize=False)
    top = np.linalg.svd(np.where(mask, W, mu) - mu, compute_uv=False)[0]
    assert max(grid["lam"]) == pytest.approx(0.3 * top, rel=1e-12)
    search = HoldoutSearch(estimator, grid, n_folds=3).fit(W)
    assert search.best_params_["lam"] in grid["lam"]
    np.testing.assert_array_equal(
        search.transform(W), soft_impute(W, mask, lam=search.best_params_["lam"]).x
    )
    with pytest.raises(ValueError, match="method"):
        baseline_grid("PCA", W)
