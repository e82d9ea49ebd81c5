"""Pre-images against a learned subspace (nldr.preimage, RobustKernelPCA.inverse_transform / complete).

Tolerances come from the maths: central finite differences have O(h^2) error; a training sample's
feature vector lies in the span of a model that keeps every positive eigenpair, so the squared feature
distance r has an isolated zero (its global minimum) there.
"""

import numpy as np
import pytest
from sklearn.exceptions import NotFittedError

from nldr.preimage import subspace_distance
from nldr.robust_kpca import RobustKernelPCA


def data(n=25, d=3, seed=0):
    return np.random.default_rng(seed).normal(size=(n, d))


def full_rank(X, center=True):
    model = RobustKernelPCA(gamma=0.5, tau=1e-9, center=center, eigensolver="full").fit(X)
    assert model.n_components_ == X.shape[0] - int(center)  # every positive eigenpair kept
    return model


@pytest.mark.parametrize("center", [True, False])
@pytest.mark.parametrize("with_target", [False, True])
def test_distance_gradient_matches_finite_differences(center, with_target):
    X = data()
    model = RobustKernelPCA(gamma=0.4, tau=0.5, center=center).fit(X)
    space = model._subspace()
    Y = data(4, 3, seed=1)
    A = np.random.default_rng(2).normal(size=(4, model.n_components_)) if with_target else None
    r, g = subspace_distance(space, Y, A)
    h = 1e-5
    num = np.zeros_like(Y)
    for i in range(Y.shape[0]):
        for j in range(Y.shape[1]):
            E = np.zeros_like(Y)
            E[i, j] = h
            num[i, j] = (
                subspace_distance(space, Y + E, A)[0][i] - subspace_distance(space, Y - E, A)[0][i]
            ) / (2 * h)
    np.testing.assert_allclose(g, num, rtol=1e-6, atol=1e-8)
    assert np.all(r >= -1e-12)


def test_distance_is_the_feature_space_distance_to_the_projection():
    # brute force: explicit projection of the kernel-mapped point, through the Gram matrix
    X = data(12)
    model = RobustKernelPCA(gamma=0.3, tau=0.2).fit(X)
    Y = data(3, 3, seed=5)
    r, _ = subspace_distance(model._subspace(), Y)
    Z = np.vstack([X, Y])
    K = np.exp(-0.3 * ((Z[:, None] - Z[None]) ** 2).sum(-1))
    n = X.shape[0]
    # features as coefficient vectors over phi(z): centred phi(y) = e_y - 1/n (over the training part),
    # axis i = V_i - mean(V_i), V = U / sqrt(lam)
    V = model.eigenvectors_ / np.sqrt(model.eigenvalues_)
    axes = np.zeros((n + 3, V.shape[1]))
    axes[:n] = V - V.mean(axis=0)
    for k in range(3):
        v = np.zeros(n + 3)
        v[n + k] = 1.0
        v[:n] -= 1.0 / n
        coeff = axes.T @ K @ v
        res = v - axes @ coeff
        np.testing.assert_allclose(r[k], res @ K @ res, rtol=1e-8, atol=1e-10)


def test_complete_of_a_training_row_reaches_a_stationary_point_and_the_row_where_r_vanishes():
    # r >= 0 and r = 0 at the training row (an isolated zero): a global minimiser of the hard problem.
    # The problem is not convex, so from the neighbours' mean the solver is only guaranteed a stationary
    # point no worse than the start; where it reaches r = 0 it must have found the row itself.
    from nldr.preimage import neighbour_start

    X = data()
    model = full_rank(X)
    mask = np.ones(X.shape, dtype=bool)
    mask[np.arange(25), np.arange(25) % 3] = False  # one entry missing per row
    W = np.where(mask, X, np.nan)
    X_hat = model.complete(W, mask, n_neighbors=2)
    space = model._subspace()
    r, g = subspace_distance(space, X_hat)
    r0, _ = subspace_distance(space, neighbour_start(X, W, mask, 2))
    np.testing.assert_array_equal(X_hat[mask], X[mask])
    assert np.all(r <= r0 + 1e-12)
    assert np.abs(g[~mask]).max() < 1e-5
    exact = r < 1e-10
    assert exact.sum() >= 1
    np.testing.assert_allclose(X_hat[exact], X[exact], atol=1e-3)


def test_complete_with_every_entry_observed_returns_a_training_row_unchanged():
    X = data()
    model = full_rank(X)
    np.testing.assert_allclose(model.complete(X[:5], np.ones((5, 3), bool), rho=1.0), X[:5], atol=1e-6)


def test_denoising_moves_noisy_points_towards_the_manifold():
    X = data(40)
    model = RobustKernelPCA(gamma=0.5, tau=1.0).fit(X)
    noisy = X[:8] + 0.3 * np.random.default_rng(3).normal(size=(8, 3))
    space = model._subspace()
    out = model.complete(noisy, np.ones(noisy.shape, bool), rho=5.0)
    before = 5.0 * subspace_distance(space, noisy)[0]
    after = ((out - noisy) ** 2).sum(1) + 5.0 * subspace_distance(space, out)[0]
    assert np.all(after <= before + 1e-12)  # descent from the start (the noisy point itself)


def test_inverse_transform_round_trip_on_training_points():
    X = data()
    model = full_rank(X)
    np.testing.assert_allclose(model.inverse_transform(model.transform(X)), X, atol=1e-4)


def test_inverse_transform_with_truncated_rank_is_a_stationary_point_no_worse_than_the_sample():
    X = data(40)
    model = RobustKernelPCA(gamma=0.5, tau=2.0).fit(X)
    assert 0 < model.n_components_ < 39
    Z = model.transform(X[:10])
    X_pre = model.inverse_transform(Z)
    A = Z * (np.sqrt(model.eigenvalues_) / model.singular_values_)
    space = model._subspace()
    r_pre, g_pre = subspace_distance(space, X_pre, A)
    r_own, _ = subspace_distance(space, X[:10], A)
    assert np.all(r_pre <= r_own + 1e-12)
    assert np.abs(g_pre).max() < 1e-5
    assert np.mean(np.linalg.norm(X_pre - X[:10], axis=1)) < np.mean(
        np.linalg.norm(X[:10] - X.mean(0), axis=1)
    )


def test_each_start_with_one_neighbour_is_the_mean_start():
    X = data()
    model = RobustKernelPCA(gamma=0.5, tau=0.5).fit(X)
    W = data(5, 3, seed=9)
    mask = np.ones(W.shape, bool)
    mask[:, 0] = False
    a = model.complete(W, mask, n_neighbors=1, starts="each")
    b = model.complete(W, mask, n_neighbors=1, starts="mean")
    np.testing.assert_allclose(a, b)


def test_clear_errors():
    X = data()
    model = RobustKernelPCA(gamma=0.5, tau=0.5)
    with pytest.raises(NotFittedError):
        model.complete(X, np.ones(X.shape, bool))
    with pytest.raises(NotFittedError):
        model.inverse_transform(np.zeros((2, 2)))
    model.fit(X)
    with pytest.raises(ValueError, match="X must have shape"):
        model.complete(X[:, :2], np.ones((25, 2), bool))
    with pytest.raises(ValueError, match="mask must be a boolean"):
        model.complete(X, np.ones(X.shape))
    with pytest.raises(ValueError, match="mask must have"):
        model.complete(X, np.ones((3, 3), bool))
    bad = X.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="observed entries"):
        model.complete(bad, np.ones(X.shape, bool))
    with pytest.raises(ValueError, match="starts"):
        model.complete(X, np.ones(X.shape, bool), starts="all")
    with pytest.raises(ValueError, match="rho"):
        model.complete(X, np.ones(X.shape, bool), rho=-1.0)
    with pytest.raises(ValueError, match="Z must have shape"):
        model.inverse_transform(np.zeros((2, model.n_components_ + 1)))
