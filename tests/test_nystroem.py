"""Tests of the opt-in Nystroem (landmark) approximation of minimize_regularized (nldr._nystroem)."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from nldr._nystroem import landmark_indices, landmark_map, nystroem_factor, nystroem_value_grad
from nldr.data_terms import MaskedLeastSquares
from nldr.kernels import center_kernel, rbf_kernel
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
    kw = dict(gamma=GAMMA, tau=TAU, rho_max=100.0, landmarks=15)
    with threadpool_limits(1):
        a = minimize_regularized(term, S, landmark_seed=4, **kw)
        b = minimize_regularized(term, S, landmark_seed=4, **kw)
        c = minimize_regularized(term, S, landmark_seed=5, **kw)
    assert a.success and a.n_stages == 3
    np.testing.assert_array_equal(a.x, b.x)
    assert not np.array_equal(a.x, c.x)
    assert a.C.shape == (40, 40) and np.linalg.matrix_rank(a.C) == a.rank_history[-1] <= 15
    exact = minimize_regularized(term, S, gamma=GAMMA, tau=TAU, rho_max=100.0)
    all_samples = minimize_regularized(term, S, gamma=GAMMA, tau=TAU, rho_max=100.0, landmarks=40)
    np.testing.assert_array_equal(all_samples.x, exact.x)  # landmarks >= n: the exact solver
    with pytest.raises(ValueError, match="landmarks"):
        minimize_regularized(term, S, gamma=GAMMA, tau=TAU, landmarks=0)
