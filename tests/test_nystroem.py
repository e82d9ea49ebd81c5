"""Tests of the opt-in Nystroem (landmark) approximation of minimize_regularized (nldr._nystroem)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import denoising_problem, within_observed_range
from threadpoolctl import threadpool_limits

from nldr._baselines import mean_impute
from nldr._nystroem import (
    landmark_indices,
    landmark_map,
    nystroem_factor,
    nystroem_value_grad,
    pivoted_landmarks,
)
from nldr.data_terms import MaskedLeastSquares
from nldr.kernels import center_kernel, rbf_kernel
from nldr.model_selection import median_gamma
from nldr.regularizer import minimize_regularized, reduced_energy

GAMMA, TAU, RHO = 0.3, 0.1, 10.0


@pytest.fixture
def problem():
    rng = np.random.default_rng(3)
    X = rng.standard_normal((40, 4))
    mask = rng.random(X.shape) > 0.3
    S = X + 0.1 * rng.standard_normal(X.shape)
    return MaskedLeastSquares(np.where(mask, X, 0.0), mask), S, rng


@pytest.mark.parametrize("center", [False, True])
@pytest.mark.parametrize("m", [8, 40])
def test_gradient_matches_central_differences(problem, center, m):
    term, S, rng = problem
    Z = S[landmark_indices(S.shape[0], m, 1)].copy()
    P = landmark_map(Z, GAMMA)
    _, g = nystroem_value_grad(S, Z, P, term, GAMMA, TAU, RHO, center)
    h = 1e-5
    for _ in range(3):
        V = rng.standard_normal(S.shape)
        V /= np.linalg.norm(V)
        up = nystroem_value_grad(S + h * V, Z, P, term, GAMMA, TAU, RHO, center)[0]
        down = nystroem_value_grad(S - h * V, Z, P, term, GAMMA, TAU, RHO, center)[0]
        # Central differences: O(h^2 |E'''|) ~ 1e-9 plus rounding eps |E| / h ~ 1e-10 (E is O(10)).
        assert (up - down) / (2 * h) == pytest.approx(float(np.sum(g * V)), rel=1e-6, abs=1e-7)


@pytest.mark.parametrize("center", [False, True])
def test_every_sample_a_landmark_gives_the_exact_energy_and_kernel_factor(problem, center):
    """With Z = S, K_nZ K_ZZ^+ K_Zn = K (up to the pseudo-inverse's 1e-10 relative cut-off)."""
    term, S, _ = problem
    n = S.shape[0]
    Z = S.copy()
    value, _ = nystroem_value_grad(S, Z, landmark_map(Z, GAMMA), term, GAMMA, TAU, RHO, center)
    exact, _ = reduced_energy(S, term, gamma=GAMMA, tau=TAU, rho=RHO, center=center, eigensolver="full")
    assert value == pytest.approx(exact, rel=1e-8)
    l, V = nystroem_factor(S, Z, landmark_map(Z, GAMMA), GAMMA, TAU, RHO, center)
    K = rbf_kernel(S, GAMMA)
    K = center_kernel(K) if center else K
    np.testing.assert_allclose(V.T @ V, np.eye(l.size), atol=1e-8)  # orthonormal eigenvectors of K
    np.testing.assert_allclose(K @ V, V * (V.T @ K @ V).diagonal(), atol=1e-7)
    assert l.size >= 1 and n >= l.size


def test_landmark_solve_is_seeded_and_validated(problem):
    term, S, _ = problem
    kw = dict(gamma=GAMMA, tau=TAU, rho_max=100.0, method="nystroem")
    with threadpool_limits(1):
        a = minimize_regularized(term, S, options={"landmarks": 15, "landmark_seed": 4}, **kw)
        b = minimize_regularized(term, S, options={"landmarks": 15, "landmark_seed": 4}, **kw)
        c = minimize_regularized(term, S, options={"landmarks": 15, "landmark_seed": 5}, **kw)
    assert a.success and a.n_stages == 3
    np.testing.assert_array_equal(a.x, b.x)
    assert not np.array_equal(a.x, c.x)
    assert a.C.shape == (40, 40) and np.linalg.matrix_rank(a.C) == a.rank_history[-1] <= 15
    exact = minimize_regularized(term, S, gamma=GAMMA, tau=TAU, rho_max=100.0)
    all_samples = minimize_regularized(
        term, S, gamma=GAMMA, tau=TAU, rho_max=100.0, method="nystroem", options={"landmarks": 40}
    )
    np.testing.assert_array_equal(all_samples.x, exact.x)  # landmarks >= n: the exact solver
    with pytest.raises(ValueError, match="landmarks"):
        minimize_regularized(term, S, gamma=GAMMA, tau=TAU, method="nystroem", options={"landmarks": 0})
    with pytest.raises(ValueError, match="method 'nystroem' needs the option"):
        minimize_regularized(term, S, gamma=GAMMA, tau=TAU, method="nystroem")


def test_an_isolated_sample_pays_what_the_exact_kernel_charges(problem):
    """Landmarks = every sample but one that is far from all: K~ misses that sample's eigenvalue 1 of K,
    and the residual diagonal (d = 1 for it, 0 for the landmarks) puts phi(1) back, so the energy is
    the exact one. Without the correction it would be lower by phi(1) ~ tau."""
    term, S, _ = problem
    S = S.copy()
    S[0] += 100.0  # exp(-0.3 * 1e4 * 4) = 0: row 0 of K is a unit vector
    Z = S[1:].copy()
    value, _ = nystroem_value_grad(S, Z, landmark_map(Z, GAMMA), term, GAMMA, TAU, RHO, False)
    exact, _ = reduced_energy(S, term, gamma=GAMMA, tau=TAU, rho=RHO, center=False, eigensolver="full")
    assert value == pytest.approx(exact, rel=1e-8)


@pytest.mark.parametrize("m", [5, 10, 20])
def test_hidden_entries_stay_near_the_data_on_few_landmarks(m):
    """The escape that the residual diagonal removes: on K~ alone, a sample far from every landmark
    costs nothing, and at the median-rule width every one of these solves sent hidden entries out of
    their column's range (|entries| up to 1e3 and more, data in [0, 1])."""
    _, W, mask = denoising_problem()
    term, S0, gamma = MaskedLeastSquares(W, mask), mean_impute(W, mask), median_gamma(W, mask)
    for tau in (0.01, 0.1, 1.0):
        res = minimize_regularized(
            term, S0, gamma=gamma, tau=tau, method="nystroem", options={"landmarks": m}
        )
        assert within_observed_range(res.x, W, mask), f"hidden entries escaped at tau={tau}, m={m}"


def _residual_diagonal_brute(S, chosen):
    """diag(K - K_nZ K_ZZ^+ K_Zn) of the RBF kernel at GAMMA, by the pseudo-inverse."""
    K = rbf_kernel(S, GAMMA)
    K_nZ = K[:, chosen]
    return np.diag(K - K_nZ @ np.linalg.pinv(K[np.ix_(chosen, chosen)]) @ K_nZ.T)


def test_pivoted_landmarks_are_the_greedy_choice_of_the_residual_diagonal(problem):
    """Brute force: each added pivot is the sample the previous pivots span worst (largest diagonal of
    the Nystroem residual, computed with the pseudo-inverse), the first the sample nearest the mean."""
    _, S, _ = problem
    previous = pivoted_landmarks(S, 1, GAMMA)
    assert previous.tolist() == [int(np.argmin(np.sum((S - S.mean(axis=0)) ** 2, axis=1)))]
    for m in range(2, 12):
        chosen = pivoted_landmarks(S, m, GAMMA)
        added = sorted(set(chosen.tolist()) - set(previous.tolist()))
        assert len(added) == 1 and set(previous.tolist()) <= set(chosen.tolist())
        residual = _residual_diagonal_brute(S, previous)
        # the pivoted Cholesky residual differs from the pseudo-inverse's by rounding (K_ZZ well conditioned)
        assert residual[added[0]] == pytest.approx(residual.max(), abs=1e-9)
        previous = chosen


def test_pivoted_landmarks_do_not_depend_on_the_order_and_take_isolated_samples(problem):
    _, S, rng = problem
    S = np.vstack([S, S[:1] + 50.0])  # one sample far from every other: its own kernel column
    chosen = pivoted_landmarks(S, 5, GAMMA)
    assert S.shape[0] - 1 in chosen  # the isolated sample is spanned by no other: a landmark
    order = rng.permutation(S.shape[0])
    np.testing.assert_array_equal(np.sort(order[pivoted_landmarks(S[order], 5, GAMMA)]), chosen)


def test_pivoted_landmarks_stop_at_the_kernels_rank():
    """Three distinct samples, each twice: three pivots span the kernel, the copies are never taken."""
    S = np.repeat(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]]), 2, axis=0)
    chosen = pivoted_landmarks(S, 5, GAMMA)
    assert chosen.size == 3 and len({tuple(S[i]) for i in chosen}) == 3


def test_landmark_rule_is_validated(problem):
    term, S, _ = problem
    with pytest.raises(ValueError, match="landmark_rule"):
        options = {"landmarks": 5, "landmark_rule": "kmeans"}
        minimize_regularized(term, S, gamma=GAMMA, tau=TAU, method="nystroem", options=options)


def test_pivoted_solve_is_deterministic_and_ignores_the_seed(problem):
    term, S, _ = problem
    kw = {"gamma": GAMMA, "tau": TAU, "method": "nystroem"}
    options = {"landmarks": 15, "landmark_rule": "pivoted"}
    a = minimize_regularized(term, S, options={**options, "landmark_seed": 1}, **kw)
    b = minimize_regularized(term, S, options={**options, "landmark_seed": 2}, **kw)
    np.testing.assert_array_equal(a.x, b.x)
