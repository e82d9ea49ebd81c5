import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize
from sklearn.decomposition import KernelPCA
from sklearn.utils.estimator_checks import check_estimator

from nldr.kernels import center_cross_kernel, center_kernel, rbf_kernel
from nldr.robust_kpca import (
    RobustKernelPCA,
    closed_form_rank_penalty,
    rank_penalty_energy,
    rank_penalty_threshold,
    shrink_eigenvalues,
)


def scalar_cost(l, lam, tau, rho):
    return rho / 2 * (lam - l**2) ** 2 + tau * l


@given(
    lam=st.floats(-5, 50),
    tau=st.floats(1e-3, 20),
    rho=st.floats(1e-2, 100),
)
@settings(max_examples=300, deadline=None)
def test_shrink_is_the_global_minimiser_of_the_scalar_problem(lam, tau, rho):
    l = shrink_eigenvalues(np.array([lam]), tau, rho)[0]
    grid = np.linspace(0, np.sqrt(max(lam, 0)) + 2, 20001)
    brute = scalar_cost(grid, lam, tau, rho).min()
    got = scalar_cost(l, lam, tau, rho)
    # a grid of step h misses the minimum by at most max|phi'| * h / 2
    h = grid[1] - grid[0]
    slope = rho * 2 * abs(lam) * grid[-1] + 2 * rho * grid[-1] ** 3 + tau
    assert got <= brute + slope * h / 2 + 1e-12
    assert l >= 0


def test_threshold_separates_zero_from_positive():
    tau, rho = 3.0, 2.0
    t = rank_penalty_threshold(tau, rho)
    b = tau / (2 * rho)
    # at the threshold the root l = 3b / t gives the same cost as zero
    l_star = 3 * b / t
    assert l_star**3 - t * l_star + b == pytest.approx(0, abs=1e-12)
    assert scalar_cost(l_star, t, tau, rho) == pytest.approx(scalar_cost(0, t, tau, rho), rel=1e-12)
    below = t * (1 - 1e-9) * np.array([1.0, 0.5, 0.0, -3.0])
    assert np.all(shrink_eigenvalues(below, tau, rho) == 0)
    above = shrink_eigenvalues(np.array([t * (1 + 1e-6), 2 * t]), tau, rho)
    assert np.all(above > 0)


def random_psd(rng, n, rank):
    A = rng.normal(size=(n, rank))
    return A @ A.T + 1e-3 * np.eye(n)


@given(seed=st.integers(0, 10_000), n=st.integers(2, 5), tau=st.floats(0.05, 5.0))
@settings(max_examples=15, deadline=None)
def test_closed_form_beats_numerical_minimisation_from_random_starts(seed, n, tau):
    rng = np.random.default_rng(seed)
    K = random_psd(rng, n, rng.integers(1, n + 1))
    rho = 1.0
    C = closed_form_rank_penalty(K, tau, rho)
    best = rank_penalty_energy(K, C, tau, rho)

    def energy_and_gradient(c):
        # d/dC: tau U V^T (a subgradient of the trace norm) - 2 rho C (K - C^T C)
        C_ = c.reshape(n, n)
        U, s, Vt = np.linalg.svd(C_)
        R = K - C_.T @ C_
        value = tau * s.sum() + rho / 2 * np.sum(R**2)
        return value, (tau * U @ Vt - 2 * rho * C_ @ R).ravel()

    for _ in range(6):
        res = minimize(energy_and_gradient, rng.normal(size=n * n), jac=True, method="L-BFGS-B")
        assert best <= res.fun + 1e-9 * max(1.0, abs(res.fun))


def test_spectrum_energy_and_matrix_energy_agree(rng):
    K = random_psd(rng, 12, 4)
    tau, rho = 0.5, 2.0
    lam, U = np.linalg.eigh(K)
    lam, U = lam[::-1], U[:, ::-1]
    l = shrink_eigenvalues(lam, tau, rho)
    C = closed_form_rank_penalty(K, tau, rho, eigensolver="full")
    spectral = rho / 2.0 * np.sum((lam - l**2) ** 2) + tau * np.sum(l)
    assert spectral == pytest.approx(rank_penalty_energy(K, C, tau, rho), rel=1e-10)
    np.testing.assert_allclose(C.T @ C, (U * l**2) @ U.T, atol=1e-12)
    # stationarity of each kept singular value: l^3 - lambda l + tau / (2 rho) = 0
    kept = l > 0
    np.testing.assert_allclose(l[kept] ** 3 - lam[kept] * l[kept] + tau / (2 * rho), 0, atol=1e-10)


def test_only_ratio_tau_over_rho_changes_the_minimiser(rng):
    K = random_psd(rng, 10, 3)
    np.testing.assert_allclose(
        closed_form_rank_penalty(K, 0.2, 1.0).T @ closed_form_rank_penalty(K, 0.2, 1.0),
        closed_form_rank_penalty(K, 2.0, 10.0).T @ closed_form_rank_penalty(K, 2.0, 10.0),
        atol=1e-12,
    )


@pytest.mark.parametrize(
    ("K", "tau", "rho", "match"),
    [
        (np.array([[1.0, np.nan], [np.nan, 1.0]]), 1.0, 1.0, "K"),
        (np.array([[1.0, 0.5], [0.1, 1.0]]), 1.0, 1.0, "symmetric"),
        (np.ones((2, 3)), 1.0, 1.0, "square"),
        (np.eye(2), 0.0, 1.0, "tau"),
        (np.eye(2), 1.0, -1.0, "rho"),
        (np.eye(2), np.inf, 1.0, "tau"),
    ],
)
def test_closed_form_rejects_bad_input(K, tau, rho, match):
    with pytest.raises(ValueError, match=match):
        closed_form_rank_penalty(K, tau, rho)


def test_estimator_passes_scikit_learn_checks():
    check_estimator(RobustKernelPCA())


def test_estimator_transform_is_consistent_and_matches_kpca_without_shrinkage(rng):
    X = rng.normal(size=(40, 3))
    est = RobustKernelPCA(gamma=0.2, tau=1e-9, rho=1.0).fit(X)
    Z_fit = est.fit_transform(X)
    np.testing.assert_allclose(est.transform(X), Z_fit, atol=1e-8)
    # with a vanishing tau the closed form is plain KPCA: same eigenvalues and coordinates up to sign
    kpca = KernelPCA(n_components=5, kernel="rbf", gamma=0.2, eigen_solver="dense").fit(X)
    lam = np.linalg.eigvalsh(center_kernel(rbf_kernel(X, 0.2)))[::-1][:5]
    np.testing.assert_allclose(kpca.eigenvalues_, lam, rtol=1e-8)
    np.testing.assert_allclose(est.eigenvalues_[:5], lam, rtol=1e-8)
    np.testing.assert_allclose(np.abs(est.transform(X)[:, :5]), np.abs(kpca.transform(X)), atol=1e-6)


def test_estimator_with_the_full_eigensolver_gives_table1s_projection(rng):
    """Table 1 projects by hand onto numpy.linalg.eigh of the centred kernel; the estimator agrees."""
    X, X_new = rng.normal(size=(80, 5)), rng.normal(size=(30, 5))
    gamma, tau = 0.3, 0.5
    K = rbf_kernel(X, gamma)
    K_new = center_cross_kernel(rbf_kernel(X_new, gamma, X), K.mean(axis=0))
    lam, U = np.linalg.eigh(center_kernel(K))
    lam, U = lam[::-1], U[:, ::-1]
    l = shrink_eigenvalues(lam, tau, 1.0)
    k = int(np.count_nonzero(l))
    est = RobustKernelPCA(gamma=gamma, tau=tau, rho=1.0, center=True, eigensolver="full")
    Z = est.fit_transform(X)
    assert est.n_components_ == k > 0
    np.testing.assert_allclose(Z, U[:, :k] * l[:k], rtol=0, atol=1e-12)
    np.testing.assert_allclose(est.transform(X_new), K_new @ U[:, :k] * (l[:k] / lam[:k]), rtol=0, atol=1e-12)


def test_estimator_partial_decomposition_agrees_with_the_full_one_up_to_sign(rng):
    X, X_new = rng.normal(size=(320, 4)), rng.normal(size=(20, 4))  # n >= 300: "auto" is partial
    full = RobustKernelPCA(gamma=0.2, tau=2.0, eigensolver="full").fit(X)
    for solver in ("auto", "partial"):
        est = RobustKernelPCA(gamma=0.2, tau=2.0, eigensolver=solver).fit(X)
        assert est.n_components_ == full.n_components_ > 0
        np.testing.assert_allclose(est.eigenvalues_, full.eigenvalues_, rtol=0, atol=1e-10)
        signs = np.sign(np.sum(est.eigenvectors_ * full.eigenvectors_, axis=0))
        np.testing.assert_allclose(est.transform(X_new) * signs, full.transform(X_new), rtol=0, atol=1e-8)


def test_estimator_rejects_bad_parameters():
    X = np.random.default_rng(0).normal(size=(10, 2))
    with pytest.raises(ValueError, match="tau"):
        RobustKernelPCA(tau=-1).fit(X)
    with pytest.raises(ValueError, match="gamma"):
        RobustKernelPCA(gamma=0).fit(X)
    with pytest.raises(ValueError, match="eigensolver"):
        RobustKernelPCA(eigensolver="arpack").fit(X)
