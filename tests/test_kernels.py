import numpy as np
import pytest
from sklearn.metrics.pairwise import rbf_kernel as sk_rbf
from sklearn.preprocessing import KernelCenterer

from nldr.kernels import (
    center_cross_kernel,
    center_kernel,
    d_max_width,
    d_med_width,
    rbf_kernel,
    rbf_kernel_vjp,
    squared_distances,
)


def test_rbf_matches_scikit_learn_convention(rng):
    X, Y = rng.normal(size=(20, 4)), rng.normal(size=(7, 4))
    np.testing.assert_allclose(rbf_kernel(X, 0.3), sk_rbf(X, gamma=0.3), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(rbf_kernel(X, 0.3, Y), sk_rbf(X, Y, gamma=0.3), rtol=1e-12, atol=1e-14)
    K = rbf_kernel(X, 0.3)
    assert np.array_equal(K, K.T) and np.all(np.diag(K) == 1.0)


def test_squared_distances_never_negative_for_duplicates():
    X = np.ones((5, 3)) * 1e8
    assert np.all(squared_distances(X) >= 0)


def test_kernel_gradient_matches_finite_differences(rng):
    X = rng.normal(size=(9, 3))
    gamma = 0.7
    G = rng.normal(size=(9, 9))  # E(K) = sum(G * K), dE/dK = G (deliberately not symmetric)

    def energy(Z):
        return float(np.sum(G * rbf_kernel(Z, gamma)))

    grad = rbf_kernel_vjp(X, rbf_kernel(X, gamma), G, gamma)
    h = 1e-6
    fd = np.zeros_like(X)
    for idx in np.ndindex(*X.shape):
        E = np.zeros_like(X)
        E[idx] = h
        fd[idx] = (energy(X + E) - energy(X - E)) / (2 * h)
    np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-8)


def test_centring_matches_scikit_learn(rng):
    X, Y = rng.normal(size=(15, 2)), rng.normal(size=(6, 2))
    K, K_new = rbf_kernel(X, 0.5), rbf_kernel(Y, 0.5, X)
    centerer = KernelCenterer().fit(K)
    np.testing.assert_allclose(center_kernel(K), centerer.transform(K), atol=1e-13)
    np.testing.assert_allclose(
        center_cross_kernel(K_new, K.mean(axis=0)), centerer.transform(K_new), atol=1e-13
    )
    np.testing.assert_allclose(center_kernel(K).sum(axis=0), 0, atol=1e-12)


def test_width_heuristics_hit_their_kernel_values(rng):
    X = rng.normal(size=(30, 5))
    D = np.sqrt(squared_distances(X))
    iu = np.triu_indices(30, 1)
    K = rbf_kernel(X, d_max_width(X))
    np.testing.assert_allclose(K[iu].min(), np.exp(-4.5), rtol=1e-10)
    K = rbf_kernel(X, d_med_width(X))
    # the kernel value at the median distance is exactly 1/2
    np.testing.assert_allclose(np.exp(-d_med_width(X) * np.median(D[iu]) ** 2), 0.5, rtol=1e-12)
    assert np.median(K[iu]) == pytest.approx(0.5, abs=1e-12)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: rbf_kernel(np.ones((3, 2)), 0.0), "gamma"),
        (lambda: rbf_kernel(np.ones((3, 2)), -1), "gamma"),
        (lambda: rbf_kernel(np.array([[np.nan, 1.0]]), 1.0), "X"),
        (lambda: rbf_kernel(np.ones(3), 1.0), "X"),
        (lambda: rbf_kernel(np.ones((3, 2)), 1.0, np.ones((2, 3))), "same number of columns"),
        (lambda: d_max_width(np.ones((4, 2))), "coincide"),
        (lambda: d_med_width(np.ones((1, 2))), "at least 2"),
    ],
)
def test_bad_input_is_rejected_with_a_named_argument(call, match):
    with pytest.raises(ValueError, match=match):
        call()
