"""GPLVMImputer (GPy's Bayesian GP-LVM with missing data) on a small smooth manifold: it beats the column
means by a margin the setup fixes, keeps observed entries, repeats with its seed, completes new rows,
and fails with a clear message without GPy."""

import builtins

import numpy as np
import pytest
from sklearn.impute import SimpleImputer

from nldr._baselines._masked import observed_standardisation
from nldr.impute._gplvm import GPY_MISSING, GPLVMImputer
from nldr.impute._grids import baseline_grid

pytest.importorskip("GPy", reason="GPy (the peers extra) is part of make setup")


def _manifold(n=60, d=6, seed=0, hidden=0.2):
    """Rows on a closed 1-d curve in R^d (t -> sines of t), no noise; MCAR mask hiding ``hidden``."""
    rng = np.random.default_rng(seed)
    t = rng.uniform(0, 2 * np.pi, n)
    freq, phase = rng.integers(1, 3, d), rng.uniform(0, 2 * np.pi, d)
    X = np.sin(np.outer(t, freq) + phase)
    mask = rng.random(X.shape) >= hidden
    mask[np.arange(n), rng.integers(d, size=n)] = True  # no empty row
    return X, mask


def _rmse(X_hat, X, mask):
    return float(np.sqrt(np.mean((X_hat - X)[~mask] ** 2)))


def test_recovers_a_smooth_curve_far_better_than_the_column_means():
    # Every column is a smooth function of one latent angle, so the data have one degree of freedom
    # and the column mean explains none of the hidden entries' variance (its RMSE ~ the column sd,
    # 1/sqrt(2) for a sine). Any model that captures even three quarters of that variance has at most
    # half the mean's RMSE; the GP-LVM is such a model (noise-free data, 2 latent dimensions).
    X, mask = _manifold()
    W = np.where(mask, X, np.nan)
    model = GPLVMImputer(n_latent=2, n_inducing=15, max_iter=200, random_state=0)
    X_hat = model.fit_transform(W)
    base = _rmse(SimpleImputer().fit_transform(W), X, mask)
    assert _rmse(X_hat, X, mask) < 0.5 * base
    assert np.array_equal(X_hat[mask], X[mask])  # observed entries returned as given
    mean, scale = observed_standardisation(np.where(mask, X, 0.0), mask)  # the library's one standardisation
    assert np.array_equal(model.mean_, mean) and np.array_equal(model.scale_, scale)


def test_a_seed_repeats_the_fit_bit_for_bit_and_leaves_the_global_generator_alone():
    # one computation repeated (a short fit: the seed fixes the start, the optimiser is deterministic)
    X, mask = _manifold()
    W = np.where(mask, X, np.nan)
    short = {"n_latent": 2, "n_inducing": 10, "max_iter": 20, "random_state": 0}
    state = np.random.get_state()[1].copy()  # noqa: NPY002
    first = GPLVMImputer(**short).fit_transform(W)
    assert np.array_equal(np.random.get_state()[1], state)  # noqa: NPY002 (the global generator restored)
    assert np.array_equal(GPLVMImputer(**short).fit_transform(W), first)


def test_transform_completes_new_rows_and_keeps_their_observed_entries():
    X, mask = _manifold(n=70, seed=1)
    train, new = slice(0, 60), slice(60, 70)
    model = GPLVMImputer(n_latent=2, n_inducing=10, max_iter=20).fit(np.where(mask[train], X[train], np.nan))
    W_new = np.where(mask[new], X[new], np.nan)
    out = model.transform(W_new)
    assert out.shape == W_new.shape and np.isfinite(out).all()
    assert np.array_equal(out[mask[new]], X[new][mask[new]])


def test_parameters_are_checked_and_the_grid_caps_latent_and_inducing():
    W = np.where(np.eye(8, 4, dtype=bool), np.nan, 1.0) + np.arange(32).reshape(8, 4) % 5
    with pytest.raises(ValueError, match="n_latent"):
        GPLVMImputer(n_latent=0).fit(W)
    with pytest.raises(ValueError, match="random_state"):
        GPLVMImputer(random_state=1.5).fit(W)
    estimator, grid = baseline_grid("GP-LVM", W)
    assert isinstance(estimator, GPLVMImputer)
    assert max(grid["n_latent"]) <= 3 and max(grid["n_inducing"]) <= 8


def test_without_gpy_the_error_says_how_to_install_it(monkeypatch):
    real_import = builtins.__import__

    def no_gpy(name, *args, **kwargs):
        if name == "GPy" or name.startswith("GPy."):
            raise ImportError("No module named 'GPy'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_gpy)
    X, mask = _manifold(n=20)
    with pytest.raises(ImportError, match=r"pip install 'nldr\[peers\]'") as info:
        GPLVMImputer().fit(np.where(mask, X, np.nan))
    assert str(info.value) == GPY_MISSING
