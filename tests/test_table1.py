import numpy as np
import pytest

from nldr.experiments.table1 import figure3_curves, run_noise_level, spectral_kernel_errors, summarise
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
