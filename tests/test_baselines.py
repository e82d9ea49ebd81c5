"""Imputation baselines of Table 2: mean, 1-NN, PPCA, PKPCA, RKPCA (synthetic data, fast)."""

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from threadpoolctl import threadpool_limits

from nldr._baselines import mean_impute, nearest_neighbour_impute, pkpca_impute, ppca_impute, rkpca_impute
from nldr._baselines._lbfgs import outer_loop_outcome
from nldr._baselines.pkpca import _objective as pkpca_objective
from nldr._baselines.ppca import _e_step
from nldr._baselines.rkpca import _energy, _fit_subspace
from nldr.kernels import center_kernel, d_med_width, rbf_kernel
from nldr.result import CONVERGED, INACCURATE, MAX_ITER


@pytest.fixture(autouse=True)
def single_threaded_blas():
    """Small eigendecompositions in a loop: multithreaded BLAS only adds contention (DESIGN.md)."""
    with threadpool_limits(limits=1):
        yield


def random_mask(rng, shape, p_missing, *, min_observed_per_row=1):
    """Entries missing independently with probability p; every column and row keeps some entries."""
    while True:
        mask = rng.random(shape) >= p_missing
        if mask.any(axis=0).all() and (mask.sum(axis=1) >= min_observed_per_row).all():
            return mask


def with_nans(X, mask):
    return np.where(mask, X, np.nan)


def central_differences(f, X, h=1e-6):
    G = np.zeros_like(X)
    for idx in np.ndindex(*X.shape):
        E = np.zeros_like(X)
        E[idx] = h
        G[idx] = (f(X + E) - f(X - E)) / (2 * h)
    return G


def curve(n, rng):
    """Points on three quarters of a helix turn in R^3 (a 1-D non-linear manifold), scale ~1."""
    t = np.sort(rng.uniform(0, 1.5 * np.pi, n))
    return np.column_stack([np.cos(t), np.sin(t), t / np.pi])


# --------------------------------------------------------------------------------------- mean


def test_mean_impute_fills_with_observed_column_means(rng):
    X = rng.normal(size=(25, 6))
    mask = random_mask(rng, X.shape, 0.3)
    out = mean_impute(with_nans(X, mask), mask)
    expected = np.nanmean(with_nans(X, mask), axis=0)
    np.testing.assert_array_equal(out[mask], X[mask])
    np.testing.assert_allclose(out, np.where(mask, X, expected[None, :]), rtol=1e-14, atol=0)


def test_mean_impute_accepts_zero_one_mask_and_ignores_values_at_missing_entries(rng):
    X = rng.normal(size=(10, 3))
    mask = random_mask(rng, X.shape, 0.3)
    a = mean_impute(np.where(mask, X, 1e300), mask.astype(int))
    b = mean_impute(with_nans(X, mask), mask)
    np.testing.assert_array_equal(a, b)


# --------------------------------------------------------------------------------------- 1-NN


def test_the_one_observed_standardisation_is_what_the_imputers_and_the_benchmark_use(rng):
    from nldr._baselines._masked import observed_standardisation
    from nldr.experiments._benchmark import _standardise
    from nldr.impute import KernelRegularizerImputer

    X = rng.normal(3.0, 2.0, size=(25, 5))
    X[:, 4] = 1.5  # a constant column: centred, scale 1
    mask = random_mask(rng, X.shape, 0.3)
    mask[0] = True  # every column observed
    W = with_nans(X, mask)
    mean, scale = observed_standardisation(np.where(mask, X, 0.0), mask)
    np.testing.assert_allclose(mean, np.nanmean(W, axis=0), rtol=1e-14, atol=0)
    sd = np.nanstd(W, axis=0)
    np.testing.assert_allclose(scale, np.where(sd > 1e-12, sd, 1.0), rtol=1e-13, atol=0)
    assert scale[4] == 1.0
    # one computation: bit-identical wherever it is used
    Z, mean_b, scale_b = _standardise(W)
    np.testing.assert_array_equal(mean_b, mean)
    np.testing.assert_array_equal(scale_b, scale)
    np.testing.assert_array_equal(Z, (W - mean) / scale)
    est = KernelRegularizerImputer(gamma=None, tau=0.1).fit(W)
    np.testing.assert_array_equal(est.mean_, mean)
    np.testing.assert_array_equal(est.scale_, scale)


@pytest.mark.parametrize("k", [1, 3])
def test_neighbour_fill_is_the_mean_of_the_nearest_rows_observing_the_entry_by_brute_force(rng, k):
    """Written out: the distance on the columns both rows observe, scaled by d / (their count); the k
    nearest rows among those observing the column; a row observing nothing takes the column means."""
    from nldr._baselines._masked import mean_fill, neighbour_fill

    X = rng.normal(size=(30, 4))
    mask = random_mask(rng, X.shape, 0.3)
    mask[0], mask[5] = True, False  # every column observed; row 5 observes nothing
    W = np.where(mask, X, 0.0)
    expected = mean_fill(W, mask)
    for i, j in zip(*np.nonzero(~mask), strict=True):
        if not mask[i].any():
            continue
        donors = [r for r in np.flatnonzero(mask[:, j]) if r != i and (mask[r] & mask[i]).any()]
        both = [mask[r] & mask[i] for r in donors]
        pairs = zip(donors, both, strict=True)
        dist = [np.sqrt(4 / b.sum() * np.sum((X[r, b] - X[i, b]) ** 2)) for r, b in pairs]
        nearest = np.asarray(donors)[np.argsort(dist)[:k]]
        expected[i, j] = X[nearest, j].mean()
    np.testing.assert_allclose(neighbour_fill(W, mask, k), expected, rtol=1e-13, atol=1e-13)
    np.testing.assert_array_equal(neighbour_fill(W, mask, k, max_donors=30), neighbour_fill(W, mask, k))


def test_neighbour_fill_beyond_max_donors_draws_from_an_even_subsample_of_the_rows(rng):
    """Beyond ``max_donors`` rows the donors are the evenly spaced rows 0, 2, ..., 40 of 41: each missing
    entry is the mean of the k nearest of those observing its column (brute force as above)."""
    from nldr._baselines._masked import neighbour_fill

    X = rng.normal(size=(41, 3))
    mask = random_mask(rng, X.shape, 0.3)
    mask[0] = True
    W = np.where(mask, X, 0.0)
    donors = np.linspace(0, 40, 21).astype(int)
    out = neighbour_fill(W, mask, 2, max_donors=21)
    for i, j in zip(*np.nonzero(~mask), strict=True):
        if not mask[i].any():
            continue
        pool = [r for r in donors if mask[r, j] and (mask[r] & mask[i]).any()]
        pairs = zip(pool, [mask[r] & mask[i] for r in pool], strict=True)
        dist = [np.sqrt(3 / b.sum() * np.sum((X[r, b] - X[i, b]) ** 2)) for r, b in pairs]
        nearest = np.asarray(pool)[np.argsort(dist)[:2]]
        assert out[i, j] == pytest.approx(X[nearest, j].mean(), rel=1e-12, abs=1e-12)


def test_nearest_neighbour_copies_from_brute_force_nearest_complete_row(rng):
    X = rng.normal(size=(40, 5))
    mask = random_mask(rng, X.shape, 0.15)
    mask[3] = False  # a row with nothing observed: every distance is 0, ties go to the first donor
    res = nearest_neighbour_impute(with_nans(X, mask), mask)
    complete = np.flatnonzero(mask.all(axis=1))
    assert res.success and res.n_complete_rows == complete.size > 1
    for i in range(X.shape[0]):
        o = mask[i]
        dist = [np.sum((X[i, o] - X[c, o]) ** 2) for c in complete]
        donor = i if o.all() else complete[int(np.argmin(dist))]
        assert res.neighbour[i] == donor
        np.testing.assert_array_equal(res.x[i], np.where(o, X[i], X[donor]))
    assert res.neighbour[3] == complete[0]
    # fun: the summed squared distance of every row to its donor over the row's observed columns
    expected = sum(np.sum((X[i, mask[i]] - X[res.neighbour[i], mask[i]]) ** 2) for i in range(X.shape[0]))
    assert res.fun == pytest.approx(expected, rel=1e-12) and res.nit == 0


def test_nearest_neighbour_reports_not_available_without_complete_rows(rng):
    X = rng.normal(size=(8, 4))
    mask = np.ones_like(X, dtype=bool)
    mask[np.arange(8), np.arange(8) % 4] = False  # one missing entry in every row
    res = nearest_neighbour_impute(with_nans(X, mask), mask)
    assert not res.success and res.status == INACCURATE and "NA" in res.message
    assert res.x is None and res.neighbour is None and res.n_complete_rows == 0 and np.isnan(res.fun)


# --------------------------------------------------------------------------------------- PPCA


def test_ppca_recovers_exactly_low_rank_data(rng):
    n, d, r = 80, 8, 3
    X = rng.normal(size=(n, r)) @ rng.normal(size=(r, d)) + rng.normal(size=d)
    mask = random_mask(rng, X.shape, 0.15, min_observed_per_row=r + 1)
    res = ppca_impute(with_nans(X, mask), mask, n_components=r)
    # The noise floor sigma^2 >= 1e-6 * mean variance shrinks the posterior mean by a relative
    # amount of order sigma^2 / (smallest signal variance), ~1e-6 here; mean imputation errs by O(1).
    err = np.sqrt(np.mean((res.x - X)[~mask] ** 2))
    assert res.success
    assert err < 1e-4 * X.std()
    np.testing.assert_array_equal(res.x[mask], X[mask])


@pytest.mark.parametrize("accelerate", [False, True])
def test_ppca_log_likelihood_never_decreases(rng, accelerate):
    n, d = 60, 7
    X = rng.normal(size=(n, 2)) @ rng.normal(size=(2, d)) + 0.1 * rng.normal(size=(n, d))
    mask = random_mask(rng, X.shape, 0.3)
    res = ppca_impute(with_nans(X, mask), mask, n_components=2, accelerate=accelerate, tol=1e-9)
    ll = res.log_likelihood_history
    assert res.success and ll.size == res.nit + 1 and res.fun == -ll[-1]
    assert np.all(np.diff(ll) >= -1e-10 * np.abs(ll[1:]))
    assert ll[-1] > ll[0]


def test_ppca_log_likelihood_matches_dense_gaussian(rng):
    n, d, q = 12, 5, 2
    Y = rng.normal(size=(n, d))
    mask = random_mask(rng, Y.shape, 0.3)
    mu, C, s2 = rng.normal(size=d), rng.normal(size=(d, q)), 0.3
    expected = 0.0
    for i in range(n):
        o = mask[i]
        cov = C[o] @ C[o].T + s2 * np.eye(o.sum())
        expected += multivariate_normal(mu[o], cov).logpdf(Y[i, o])
    got = ppca_log_likelihood(with_nans(Y, mask), mask, mu, C, s2)
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_ppca_reports_the_final_likelihood_and_iteration_limit(rng):
    X = rng.normal(size=(30, 5))
    mask = random_mask(rng, X.shape, 0.2)
    res = ppca_impute(with_nans(X, mask), mask, n_components=2, max_iter=2, tol=0.0)
    assert res.nit == 2 and not res.success and res.status == MAX_ITER
    ll = ppca_log_likelihood(with_nans(X, mask), mask, res.mean, res.components, res.noise_variance)
    np.testing.assert_allclose(ll, res.log_likelihood_history[-1], rtol=1e-12)


def ppca_log_likelihood(W, mask, mean, components, noise_variance):
    """The marginal log-likelihood of the observed entries, from the E-step the solver runs."""
    return _e_step(np.where(mask, W, 0.0), mask, mean, components, noise_variance).log_likelihood


def fit_kernel_subspace(X, gamma, q):
    return _fit_subspace(X, gamma, q)


def rkpca_energy(Y, W, mask, subspace, weight):
    return _energy(Y, np.where(mask, W, 0.0), mask, subspace, weight)


def test_ppca_needs_two_rows():
    with pytest.raises(ValueError, match="at least 2 rows"):
        ppca_impute(np.ones((1, 3)), np.ones((1, 3), bool), n_components=1)


# --------------------------------------------------------------------------------------- PKPCA


def test_pkpca_objective_gradient_matches_finite_differences(rng):
    X = rng.normal(size=(10, 3))
    gamma, q = 0.4, 3
    _, grad = pkpca_objective(X, gamma, q)
    fd = central_differences(lambda Z: pkpca_objective(Z, gamma, q)[0], X)
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_pkpca_objective_is_minus_the_ppca_likelihood_of_the_spectrum(rng):
    X = rng.normal(size=(9, 2))
    n, q, gamma = 9, 2, 0.5
    lam = np.sort(np.linalg.eigvalsh(rbf_kernel(X, gamma)))[::-1] / n
    s2 = lam[q:].mean()  # the discarded eigenvalues of K / n, and tr K / n = 1
    expected = 0.5 * n * (np.log(lam[:q]).sum() + (n - q) * np.log(s2) + n)
    np.testing.assert_allclose(pkpca_objective(X, gamma, q)[0], expected, rtol=1e-12)


def test_pkpca_beats_mean_imputation_on_a_curve(rng):
    X = curve(60, rng)
    mask = random_mask(rng, X.shape, 0.15)
    gamma = d_med_width(X)
    res = pkpca_impute(with_nans(X, mask), mask, gamma)
    err_mean = np.sum((mean_impute(with_nans(X, mask), mask) - X) ** 2)
    assert res.success and res.nit >= 1 and res.fun == res.objective_history[-1]
    assert res.objective_history[-1] < res.objective_history[0]
    np.testing.assert_array_equal(res.x[mask], X[mask])
    assert np.sum((res.x - X) ** 2) < err_mean


def test_pkpca_without_missing_entries_returns_the_data(rng):
    X = rng.normal(size=(10, 3))
    res = pkpca_impute(X, np.ones_like(X, dtype=bool), 0.5)
    assert res.success and res.nit == 0
    np.testing.assert_array_equal(res.x, X)


# --------------------------------------------------------------------------------------- RKPCA


def test_rkpca_reconstruction_error_and_gradient(rng):
    X_fit, Y = rng.normal(size=(12, 3)), rng.normal(size=(5, 3))
    gamma, q = 0.3, 4
    sub = fit_kernel_subspace(X_fit, gamma, q)
    err, grad = sub.reconstruction_error(Y)
    # Explicit feature-space check: augment the training kernel with the queries and project.
    K = rbf_kernel(np.vstack([X_fit, Y]), gamma)
    n = X_fit.shape[0]
    H = np.eye(n) - 1.0 / n
    nu, V = np.linalg.eigh(H @ K[:n, :n] @ H)
    A = V[:, ::-1][:, :q] / np.sqrt(nu[::-1][:q])
    for j in range(Y.shape[0]):
        k = K[:n, n + j]
        norm2 = K[n + j, n + j] - 2 * k.mean() + K[:n, :n].mean()
        coords = A.T @ H @ (k - K[:n, :n].mean(axis=1))
        np.testing.assert_allclose(err[j], norm2 - coords @ coords, rtol=1e-9, atol=1e-12)
    fd = central_differences(lambda Z: sub.reconstruction_error(Z)[0].sum(), Y)
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-7)


def test_rkpca_energy_gradient_with_data_term(rng):
    X_fit, Y = rng.normal(size=(10, 3)), rng.normal(size=(6, 3))
    W = rng.normal(size=Y.shape)
    mask = random_mask(rng, Y.shape, 0.3)
    sub = fit_kernel_subspace(X_fit, 0.5, 3)
    value, grad = rkpca_energy(Y, with_nans(W, mask), mask, sub, weight=2.0)
    err, _ = sub.reconstruction_error(Y)
    np.testing.assert_allclose(value, err.sum() + 2.0 * np.sum(((Y - W) * mask) ** 2), rtol=1e-12)
    fd = central_differences(lambda Z: rkpca_energy(Z, with_nans(W, mask), mask, sub, 2.0)[0], Y)
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-7)


def test_rkpca_profile_energy_is_the_discarded_spectrum_and_its_gradient_is_the_envelope(rng):
    X = rng.normal(size=(10, 3))
    gamma, q = 0.4, 3

    def profile(Z):
        return fit_kernel_subspace(Z, gamma, q).reconstruction_error(Z)[0].sum()

    nu = np.sort(np.linalg.eigvalsh(center_kernel(rbf_kernel(X, gamma))))[::-1]
    np.testing.assert_allclose(profile(X), nu[q:].sum(), rtol=1e-9)
    _, grad_fixed_subspace = fit_kernel_subspace(X, gamma, q).reconstruction_error(X)
    fd = central_differences(profile, X)
    np.testing.assert_allclose(grad_fixed_subspace, fd, rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("weight", [np.inf, 10.0])
def test_rkpca_beats_mean_imputation_on_a_curve(rng, weight):
    X = curve(60, rng)
    mask = random_mask(rng, X.shape, 0.15)
    res = rkpca_impute(with_nans(X, mask), mask, d_med_width(X), n_components=8, weight=weight)
    err_mean = np.sum((mean_impute(with_nans(X, mask), mask) - X) ** 2)
    assert res.success and res.n_components == 8 and res.fun == res.energy_history[-1]
    assert res.energy_history[-1] < res.energy_history[0]
    np.testing.assert_array_equal(res.x[mask], X[mask])
    assert np.sum((res.x - X) ** 2) < err_mean


def test_rkpca_chooses_components_by_trace_fraction(rng):
    X = curve(40, rng)
    mask = random_mask(rng, X.shape, 0.1)
    res = rkpca_impute(with_nans(X, mask), mask, d_med_width(X), n_components=0.9)
    Xc = center_kernel(rbf_kernel(res.x, d_med_width(X)))
    nu = np.sort(np.linalg.eigvalsh(Xc))[::-1]
    q_expected = int(np.searchsorted(np.cumsum(nu) / nu.sum(), 0.9 - 1e-12) + 1)
    assert res.success and res.n_components == q_expected == res.n_components_history[-1]


def test_kernel_baselines_report_iteration_limits(rng):
    X = curve(30, rng)
    mask = random_mask(rng, X.shape, 0.2)
    W = with_nans(X, mask)
    for res in (
        pkpca_impute(W, mask, 0.5, max_iter=1, inner_max_iter=1),
        rkpca_impute(W, mask, 0.5, n_components=2, max_iter=1, inner_max_iter=1),
    ):
        assert not res.success and res.status == MAX_ITER and res.nit == 1 and res.n_inner_iter == 1
        assert "max_iter=1" in res.message and res.wall_time > 0


def test_an_abnormal_line_search_stop_is_inaccurate():
    assert outer_loop_outcome(False, 2, 20, "ABNORMAL")[0] == INACCURATE
    assert outer_loop_outcome(False, 1, 20, "STOP: TOTAL NO. OF ITERATIONS")[0] == MAX_ITER
    assert outer_loop_outcome(True, 0, 3, "CONVERGENCE")[0] == CONVERGED


# --------------------------------------------------------------------------------------- inputs

ALL_METHODS = [
    ("mean", lambda W, m, **kw: mean_impute(W, m)),
    ("1-NN", lambda W, m, **kw: nearest_neighbour_impute(W, m)),
    ("PPCA", lambda W, m, **kw: ppca_impute(W, m, n_components=1, **kw)),
    ("PKPCA", lambda W, m, **kw: pkpca_impute(W, m, 0.5, **kw)),
    ("RKPCA", lambda W, m, **kw: rkpca_impute(W, m, 0.5, n_components=2, **kw)),
]


@pytest.mark.parametrize("name, method", ALL_METHODS, ids=[m[0] for m in ALL_METHODS])
def test_bad_inputs_raise_value_error_naming_the_argument(rng, name, method):
    X = rng.normal(size=(10, 3))
    mask = np.ones_like(X, dtype=bool)
    mask[0, 0] = False
    with pytest.raises(ValueError, match="mask"):
        method(X, mask[:, :2])
    with pytest.raises(ValueError, match="mask"):
        method(X, np.where(mask, 1, 2))
    W = X.copy()
    W[1, 1] = np.nan  # observed (mask True) but not finite
    with pytest.raises(ValueError, match="observed entries"):
        method(W, mask)
    with pytest.raises(ValueError, match="W"):
        method(X[0], mask[0])
    if name != "1-NN":  # 1-NN needs no column means
        empty = mask.copy()
        empty[:, 1] = False
        with pytest.raises(ValueError, match="column"):
            method(X, empty)


def test_bad_parameters_raise_value_error(rng):
    X = rng.normal(size=(10, 3))
    mask = np.ones_like(X, dtype=bool)
    mask[0, 0] = False
    with pytest.raises(ValueError, match="n_components"):
        ppca_impute(X, mask, n_components=3)
    with pytest.raises(ValueError, match="n_components"):
        ppca_impute(X, mask, n_components=1.5)
    with pytest.raises(ValueError, match="gamma"):
        pkpca_impute(X, mask, 0.0)
    with pytest.raises(ValueError, match="variance_fraction"):
        pkpca_impute(X, mask, 0.5, variance_fraction=1.5)
    with pytest.raises(ValueError, match="gamma"):
        rkpca_impute(X, mask, -1.0)
    with pytest.raises(ValueError, match="n_components"):
        rkpca_impute(X, mask, 0.5, n_components=1.0)
    with pytest.raises(ValueError, match="weight"):
        rkpca_impute(X, mask, 0.5, weight=-1.0)
    with pytest.raises(ValueError, match="n_components"):
        pkpca_impute(X, mask, 0.5, n_components=10)
