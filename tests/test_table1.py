import numpy as np
import pytest

from nldr._baselines.kpca import kpca_spectrum, project_points, spectral_kernel_errors, truncated_spectra
from nldr.experiments._table1 import figure3_curves, run_noise_level, summarise
from nldr.kernels import center_kernel, rbf_kernel


def test_spectral_errors_equal_direct_computation(rng):
    A = rng.normal(size=(8, 8))
    K = A @ A.T
    T = center_kernel(rbf_kernel(rng.normal(size=(8, 2)), 0.5))
    lam, U = np.linalg.eigh(K)
    spectra = rng.uniform(0, 2, size=(3, 8))
    got = spectral_kernel_errors(U, T, spectra)
    direct = [np.sum(((U * d) @ U.T - T) ** 2) / np.sum(T**2) for d in spectra]
    np.testing.assert_allclose(got, direct, rtol=1e-12)


@pytest.fixture
def two_moons_like(rng):
    def sample(n):
        t = rng.uniform(0, np.pi, n)
        y = rng.integers(0, 2, n)
        X = np.c_[np.cos(t) + y, np.sin(t) * (1 - 2 * y) + 0.5 * y, 0.1 * rng.normal(size=n)]
        return X, y

    return sample(120), sample(80)


def test_run_reports_each_methods_minimum_and_scores_it(two_moons_like):
    (Xtr, ytr), (Xte, yte) = two_moons_like
    taus = np.geomspace(0.01, 10, 15)
    runs = run_noise_level(Xtr, ytr, Xte, yte, noise_std=0.1, seed=3, gamma=1.0, max_rank=20, taus=taus)
    for method in ("KPCA", "CFS"):
        rows = runs[runs["method"] == method]
        best = rows[rows["best"]]
        assert len(best) == 1
        assert best["manifold_error"].iloc[0] == rows["manifold_error"].min()
        assert 0 <= best["classification_error"].iloc[0] <= 100
    assert runs[runs["method"] == "KPCA"]["rank"].tolist() == list(range(1, 21))
    # larger tau never increases the rank (the threshold grows with tau)
    assert np.all(np.diff(runs[runs["method"] == "CFS"]["rank"].to_numpy()) <= 0)
    # the same seed gives the same draw
    again = run_noise_level(Xtr, ytr, Xte, yte, noise_std=0.1, seed=3, gamma=1.0, max_rank=20, taus=taus)
    assert again.equals(runs)
    table = summarise(runs)
    assert set(table["metric"]) >= {"manifold_error", "classification_error_pct", "best_rank"}
    curves = figure3_curves(runs)
    assert (curves["error_min"] <= curves["error"] + 1e-15).all() and (
        curves["error"] <= curves["error_max"] + 1e-15
    ).all()


def test_run_validates_its_arguments(two_moons_like):
    (Xtr, ytr), (Xte, yte) = two_moons_like
    kwargs = dict(noise_std=0.1, seed=0, gamma=1.0, max_rank=5, taus=[1.0])
    with pytest.raises(ValueError, match="taus"):
        run_noise_level(Xtr, ytr, Xte, yte, **{**kwargs, "taus": [-1.0]})
    with pytest.raises(ValueError, match="max_rank"):
        run_noise_level(Xtr, ytr, Xte, yte, **{**kwargs, "max_rank": 0})
    with pytest.raises(ValueError, match="X_test"):
        run_noise_level(Xtr, ytr, Xte[:, :2], yte, **kwargs)


def test_factor_projection_maps_training_rows_onto_their_coordinates_and_matches_the_estimator(rng):
    """The test-point map applied to a training point's own kernel row returns its training
    coordinates (K U = U diag(lam)); for the closed form they are the columns of C, as in the
    RobustKernelPCA estimator (same eigendecomposition, so equal to rounding)."""
    from nldr.kernels import center_cross_kernel
    from nldr.robust_kpca import RobustKernelPCA, shrink_eigenvalues

    X, X_new = rng.normal(size=(60, 4)), rng.normal(size=(25, 4))
    K = rbf_kernel(X, 0.3)
    Kc = center_kernel(K)
    lam, U = np.linalg.eigh(Kc)
    lam, U = lam[::-1], U[:, ::-1]
    l = shrink_eigenvalues(lam, 0.5, 1.0)
    k = int(np.count_nonzero(l))
    for projection in ("factor", "eigenvectors", "whitened"):
        train, again = project_points(U, lam, Kc, l[:k], projection)
        np.testing.assert_allclose(again, train, rtol=0, atol=1e-9)
    K_new = center_cross_kernel(rbf_kernel(X_new, 0.3, X), K.mean(axis=0))
    train, test = project_points(U, lam, K_new, l[:k], "factor")
    est = RobustKernelPCA(gamma=0.3, tau=0.5, rho=1.0, center=True, eigensolver="full")
    np.testing.assert_allclose(np.abs(est.fit_transform(X)), np.abs(train), rtol=0, atol=1e-10)
    np.testing.assert_allclose(np.abs(est.transform(X_new)), np.abs(test), rtol=0, atol=1e-10)
    # eigenvectors: KPCA's coordinates on the same subspace; whitened: unit variance over training
    eig_train, _ = project_points(U, lam, K_new, l[:k], "eigenvectors")
    np.testing.assert_allclose(eig_train.T @ eig_train, np.diag(lam[:k]), atol=1e-10)
    white_train, _ = project_points(U, lam, K_new, l[:k], "whitened")
    np.testing.assert_allclose(white_train.T @ white_train, np.eye(k), atol=1e-10)
    norm_train, norm_test = project_points(U, lam, K_new, l[:k], "normalised")
    np.testing.assert_allclose(np.linalg.norm(np.vstack([norm_train, norm_test]), axis=1), 1.0, rtol=1e-12)
    with pytest.raises(ValueError, match="projection"):
        project_points(U, lam, K_new, l[:k], "bogus")


def test_test_manifold_error_is_bounded_by_the_first_dropped_eigenvalue(two_moons_like):
    """Without noise, the joint centred kernel of [train; test] is PSD, so a test row is
    k = K^(1/2) v with ||v||^2 <= c (its centred self-kernel), and the part of k outside the kept
    eigenvectors has squared norm sum_dropped lam_i v_i^2 <= lam_(k+1) c. With KPCA's coordinates
    (the "eigenvectors" projection) the kept part is reproduced exactly, so the test manifold error is
    at most lam_(k+1) sum_t c_t / ||K_test||^2."""
    from nldr.kernels import center_cross_kernel

    (Xtr, ytr), (Xte, yte) = two_moons_like
    gamma = 1.0
    runs = run_noise_level(
        Xtr,
        ytr,
        Xte,
        yte,
        noise_std=0.0,
        seed=0,
        gamma=gamma,
        max_rank=40,
        taus=[1e-3],
        projection="eigenvectors",
    )
    K = rbf_kernel(Xtr, gamma)
    lam = np.linalg.eigvalsh(center_kernel(K))[::-1]
    K_test = center_cross_kernel(rbf_kernel(Xte, gamma, Xtr), K.mean(axis=0))
    c = 1.0 - 2.0 * rbf_kernel(Xte, gamma, Xtr).mean(axis=1) + K.mean()
    best = runs[runs["best"]].set_index("method")
    for method in ("KPCA", "CFS"):
        k = int(best.loc[method, "rank"])
        bound = lam[k] * c.sum() / np.sum(K_test**2)
        assert 0 < best.loc[method, "test_manifold_error"] <= bound * (1 + 1e-9)
    with pytest.raises(ValueError, match="projection"):
        run_noise_level(
            Xtr, ytr, Xte, yte, noise_std=0.1, seed=0, gamma=1.0, max_rank=5, taus=[1.0], projection="x"
        )


def test_kpca_truncation_is_the_eckart_young_best_psd_approximation(rng):
    """At rank k the truncated spectrum's relative error against K itself is the dropped squared
    eigenvalues (negative ones included) over ||K||^2, and it never increases with k."""
    A = rng.normal(size=(10, 10))
    K = A @ A.T - 3.0 * np.eye(10)  # some negative eigenvalues
    lam, U = kpca_spectrum(K)
    assert np.all(np.diff(lam) <= 0)
    np.testing.assert_allclose((U * lam) @ U.T, K, atol=1e-10)
    spectra = truncated_spectra(lam, np.arange(11))
    errors = spectral_kernel_errors(U, K, spectra)
    dropped = [np.sum(np.where(np.arange(10) < k, np.minimum(lam, 0.0), lam) ** 2) for k in range(11)]
    np.testing.assert_allclose(errors, np.array(dropped) / np.sum(K**2), rtol=1e-10, atol=1e-14)
    assert np.all(np.diff(errors) <= 1e-14)
    with pytest.raises(ValueError, match="ranks"):
        truncated_spectra(lam, [11])
    with pytest.raises(ValueError, match="symmetric"):
        kpca_spectrum(A)
