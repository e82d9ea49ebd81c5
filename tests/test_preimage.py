"""Pre-images against a learned subspace (nldr._preimage, RobustKernelPCA.inverse_transform / complete).

Tolerances come from the maths: central finite differences have O(h^2) error; a training sample's
feature vector lies in the span of a model that keeps every positive eigenpair, so the squared feature
distance r has an isolated zero (its global minimum) there.
"""

import numpy as np
import pytest
from sklearn.exceptions import NotFittedError

from nldr._preimage import subspace_distance
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


@pytest.mark.parametrize("outer_products_max", [2**22, 0])  # both ways of forming X^T diag(M) X
@pytest.mark.parametrize("center", [True, False])
def test_the_newton_hessian_is_the_finite_difference_of_the_gradient(center, outer_products_max, monkeypatch):
    from nldr import _preimage as preimage
    from nldr._preimage import _distance_hessian

    monkeypatch.setattr(preimage, "OUTER_PRODUCTS_MAX", outer_products_max)

    X = data()
    space = RobustKernelPCA(gamma=0.4, tau=0.5, center=center).fit(X)._subspace()
    Y = data(4, 3, seed=3)
    Vt = space.V - space.V.mean(axis=0) if center else space.V
    r, g, H = _distance_hessian(space, Y, Vt)
    r_ref, g_ref = subspace_distance(space, Y)
    np.testing.assert_array_equal(r, r_ref)
    np.testing.assert_allclose(g, g_ref, rtol=1e-12, atol=1e-15)
    h = 1e-5
    for j in range(3):
        E = np.zeros_like(Y)
        E[:, j] = h
        column = (subspace_distance(space, Y + E)[1] - subspace_distance(space, Y - E)[1]) / (2 * h)
        np.testing.assert_allclose(H[:, :, j], column, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(H, H.transpose(0, 2, 1), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("center", [True, False])
def test_completion_ends_at_local_minima_of_the_distance_on_the_missing_entries(center):
    """First- and second-order optimality per row: gradient on the missing entries at most the solver's
    gtol (1e-7), and r no lower at any of 20 random perturbations of size 1e-3 of those entries."""
    X = data(60, 4)
    model = RobustKernelPCA(gamma=0.4, tau=0.05, center=center).fit(X)
    space = model._subspace()
    rng = np.random.default_rng(4)
    W = data(15, 4, seed=6)
    mask = rng.random(W.shape) < 0.5
    mask[:, 0] = True
    X_hat = model.complete(W, mask)
    np.testing.assert_array_equal(X_hat[mask], W[mask])
    r, g = subspace_distance(space, X_hat)
    assert np.abs(g[~mask]).max() <= 1e-7
    for _ in range(20):
        Y = X_hat + np.where(mask, 0.0, 1e-3 * rng.standard_normal(W.shape))
        assert np.all(subspace_distance(space, Y)[0] >= r - 1e-12)


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
    from nldr._preimage import nearest_rows

    X = data()
    model = full_rank(X)
    mask = np.ones(X.shape, dtype=bool)
    mask[np.arange(25), np.arange(25) % 3] = False  # one entry missing per row
    W = np.where(mask, X, np.nan)
    X_hat = model.complete(W, mask, n_neighbors=2)
    space = model._subspace()
    r, g = subspace_distance(space, X_hat)
    nearest, _ = nearest_rows(X, np.where(mask, W, 0.0), mask, 2)
    r0, _ = subspace_distance(space, np.where(mask, W, X[nearest].mean(axis=1)))  # complete's start
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
    with pytest.raises(ValueError, match="3 features"):
        model.complete(X[:, :2], np.ones((25, 2), bool))
    with pytest.raises(ValueError, match="mask must be boolean"):
        model.complete(X, np.full(X.shape, 2))
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


# --- Huber data loss, per-neighbour starts and their average (issue 18) ---------------------------


def test_huber_objective_gradient_matches_finite_differences():
    from nldr._preimage import completion_objective

    X = data()
    space = RobustKernelPCA(gamma=0.4, tau=0.5).fit(X)._subspace()
    rng = np.random.default_rng(4)
    W = data(4, 3, seed=6)
    mask = rng.random(W.shape) < 0.7
    Y = W + rng.choice([-1.0, 1.0], size=W.shape) * rng.uniform(0.05, 1.0, size=W.shape)
    delta = 0.3  # residuals 0.05-1.0 in size: some inside, some outside, none within 1e-5 of the kink
    assert np.any(np.abs(Y - W)[mask] < delta) and np.any(np.abs(Y - W)[mask] > delta)
    f, g = completion_objective(space, W, mask, Y, rho=2.0, loss="huber", delta=delta)
    h = 1e-5
    num = np.zeros_like(Y)
    for i in range(Y.shape[0]):
        for j in range(Y.shape[1]):
            E = np.zeros_like(Y)
            E[i, j] = h
            plus = completion_objective(space, W, mask, Y + E, rho=2.0, loss="huber", delta=delta)[0][i]
            minus = completion_objective(space, W, mask, Y - E, rho=2.0, loss="huber", delta=delta)[0][i]
            num[i, j] = (plus - minus) / (2 * h)
    np.testing.assert_allclose(g, num, rtol=1e-6, atol=1e-8)


def test_huber_with_a_delta_above_every_residual_is_least_squares():
    # h_delta(t) = t^2 for |t| <= delta: same objective, same gradient, so the same L-BFGS path
    from nldr._preimage import complete_rows, completion_objective

    X = data()
    space = RobustKernelPCA(gamma=0.4, tau=0.5).fit(X)._subspace()
    W = data(6, 3, seed=7)
    mask = np.ones(W.shape, bool)
    mask[:, 1] = False
    X0 = np.where(mask, W, 0.0)
    big = 1e3  # residuals stay below |W| + |X| ~ 10
    f_h, g_h = completion_objective(space, W, mask, X0 + 0.5, rho=3.0, loss="huber", delta=big)
    f_s, g_s = completion_objective(space, W, mask, X0 + 0.5, rho=3.0)
    np.testing.assert_array_equal(f_h, f_s)
    np.testing.assert_array_equal(g_h, g_s)
    a, _ = complete_rows(space, W, mask, X0, rho=3.0, loss="huber", delta=big)
    b, _ = complete_rows(space, W, mask, X0, rho=3.0)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("starts", ["mean", "each"])
def test_huber_complete_of_a_training_row_returns_it(starts):
    # the objective is >= 0 and 0 at the row itself (residual 0, r = 0 in a full-rank model); with
    # Huber and finite rho the start is the nearest training row on the observed entries: the row
    X = data()
    model = full_rank(X)
    mask = np.ones((5, 3), bool)
    mask[:, 2] = False
    out = model.complete(X[:5], mask, rho=1.0, loss="huber", delta=0.1, n_neighbors=1, starts=starts)
    np.testing.assert_allclose(out, X[:5], atol=1e-6)


def test_huber_pulls_a_gross_error_back_where_least_squares_follows_it():
    # A training row with one entry off by 8: at the clean row the Huber objective is
    # 2 delta 8 - delta^2 (r = 0), and the solver descends from the clean row (its nearest training row
    # under the Huber distance), so its answer costs no more. Least squares pays 64 at the clean row
    # and starts at the corrupted one, so its answer stays further from the clean row.
    from nldr._preimage import completion_objective

    X = data(40)
    model = full_rank(X)
    space = model._subspace()
    W = X[:3].copy()
    W[:, 0] += 8.0
    mask = np.ones(W.shape, bool)
    delta, rho = 0.1, 10.0
    out = model.complete(W, mask, rho=rho, loss="huber", delta=delta, n_neighbors=1)
    f_out, _ = completion_objective(space, W, mask, out, rho=rho, loss="huber", delta=delta)
    assert np.all(f_out <= 2 * delta * 8.0 - delta**2 + 1e-9)
    ls = model.complete(W, mask, rho=rho)
    assert np.all(np.abs(out - X[:3]).max(axis=1) < np.abs(ls - X[:3]).max(axis=1))


def test_each_start_average_and_its_weights():
    from nldr._preimage import average_solutions, nearest_rows

    X = data(30)
    model = RobustKernelPCA(gamma=0.5, tau=0.5).fit(X)
    W = data(4, 3, seed=8)
    mask = np.ones(W.shape, bool)
    mask[:, 0] = False
    sol, dist = model.complete_each(W, mask, n_neighbors=4)
    assert sol.shape == (4, 4, 3) and np.all(np.diff(dist, axis=1) >= 0)
    # brute force: mean squared difference over the observed columns, nearest first
    D = ((W[:, None, 1:] - X[None, :, 1:]) ** 2).mean(axis=2)
    np.testing.assert_allclose(dist, np.sort(D, axis=1)[:, :4], rtol=1e-10, atol=1e-12)
    # nearest_rows expands |w|^2 - 2 w.x + |x|^2 (BLAS), the brute force squares differences: they agree
    # to about 2 (d + 2) eps (|w|^2 + |x|^2), so a neighbour can only trade places with a row that close
    index = nearest_rows(X, W, mask, 4)[0]
    size = (W[:, 1:] ** 2).sum(axis=1).max() + (X[:, 1:] ** 2).sum(axis=1).max()
    tol = 2 * (W.shape[1] + 2) * np.finfo(float).eps * size
    near = np.take_along_axis(D, index, axis=1)
    np.testing.assert_allclose(near, np.sort(D, axis=1)[:, :4], rtol=0, atol=tol)
    np.testing.assert_allclose(model.complete(W, mask, n_neighbors=4, starts="each"), sol.mean(axis=1))
    w = 1.0 / np.sqrt(dist)
    expected = (w[:, :, None] * sol).sum(axis=1) / w.sum(axis=1)[:, None]
    np.testing.assert_allclose(average_solutions(sol, dist, "distance"), expected, rtol=1e-12)
    zero = dist.copy()
    zero[0, 1] = 0.0
    np.testing.assert_allclose(average_solutions(sol, zero, "distance")[0], sol[0, 1])


def test_huber_neighbour_distance_is_the_mean_huber_loss():
    from nldr._preimage import nearest_rows
    from nldr.data_terms import huber_loss

    X = data(30)
    W = data(5, 3, seed=10)
    mask = np.random.default_rng(11).random(W.shape) < 0.7
    mask[:, 0] = True
    idx, dist = nearest_rows(X, W, mask, 30, loss="huber", delta=0.2, chunk=2)
    D = np.array(
        [[huber_loss(W[i, mask[i]] - X[j, mask[i]], 0.2).mean() for j in range(30)] for i in range(5)]
    )
    np.testing.assert_allclose(dist, np.sort(D, axis=1), rtol=1e-10, atol=1e-14)


def test_clear_errors_of_the_loss_options():
    X = data()
    model = RobustKernelPCA(gamma=0.5, tau=0.5).fit(X)
    every = np.ones(X.shape, bool)
    with pytest.raises(ValueError, match="loss must be"):
        model.complete(X, every, loss="l1")
    with pytest.raises(ValueError, match="delta"):
        model.complete(X, every, rho=1.0, loss="huber")
    with pytest.raises(ValueError, match="delta"):
        model.complete(X, every, rho=1.0, loss="huber", delta=-1.0)
    with pytest.raises(ValueError, match="weights"):
        model.complete(X, every, starts="each", weights="inverse")


def test_complete_checks_feature_names_as_transform_does():
    import pandas as pd

    X = data()
    frame = pd.DataFrame(X, columns=["a", "b", "c"])
    model = RobustKernelPCA(gamma=0.5, tau=0.5).fit(frame)
    every = np.ones(X.shape, bool)
    with pytest.raises(ValueError, match="feature names"):
        model.transform(frame[["b", "a", "c"]])
    with pytest.raises(ValueError, match="feature names"):
        model.complete(frame[["b", "a", "c"]], every)
    np.testing.assert_array_equal(model.complete(frame, every), X)  # nothing missing: X unchanged


def test_inverse_transform_overflow_names_z():
    model = RobustKernelPCA(gamma=0.5, tau=0.5).fit(data())
    with pytest.raises(ValueError, match="Z has entries up to"):
        model.inverse_transform(np.full((1, model.n_components_), 1e200))
