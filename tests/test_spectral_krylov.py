"""Tests of the Lanczos ("krylov") eigensolver path and of the regularizer's per-stage tolerance."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from nldr._reduced import KRYLOV_AUTO_FRACTION
from nldr._reduced import RankHint as _RankHint
from nldr._spectral import KRYLOV_MAX_FRACTION, krylov_eigenpairs, leading_eigenpairs
from nldr.data_terms import MaskedLeastSquares
from nldr.kernels import rbf_kernel
from nldr.regularizer import minimize_regularized, reduced_energy
from nldr.robust_kpca import closed_form_rank_penalty, rank_penalty_threshold


@pytest.fixture(autouse=True)
def single_blas_thread():
    with threadpool_limits(1):
        yield


@pytest.fixture(scope="module")
def completion():
    """320 points near a curve in R^6 (n >= 300: the regularizer's "auto" may choose Lanczos)."""
    rng = np.random.default_rng(11)
    t = np.sort(rng.uniform(0.0, 2.0 * np.pi, 320))
    X = np.column_stack([np.cos(t), np.sin(t), np.cos(t + 1), np.sin(t + 1), 0.3 * t, 0.3 * t])
    mask = rng.random(X.shape) > 0.2
    S0 = np.where(mask, X, np.nanmean(np.where(mask, X, np.nan), axis=0))
    return X, mask, S0


def _bound(K):
    # Backward-stable eigensolvers (and ARPACK at tol=0): eigenvalues to about n eps ||K||_2.
    return K.shape[0] * np.finfo(float).eps * np.linalg.norm(K, 2)


@pytest.mark.parametrize("expected", [None, 1, 10, 40])
def test_krylov_finds_exactly_the_eigenpairs_above_the_threshold(completion, expected):
    _, _, S0 = completion
    K = rbf_kernel(S0, 0.1)
    t = rank_penalty_threshold(0.1, 10.0)
    full = np.linalg.eigvalsh(K)[::-1]
    k = int(np.count_nonzero(full > t))
    assert 0 < k < KRYLOV_MAX_FRACTION * K.shape[0] / 2  # the Lanczos path itself, not the fallback
    lam, U = krylov_eigenpairs(K, t, expected)
    bound = _bound(K)
    # whether the guess was too small (doubling), right, or too large; up to eigenvalues that rounding
    # cannot separate from t (within the bound of it: none here)
    assert abs(lam.size - k) <= np.count_nonzero(np.abs(full - t) <= bound)
    np.testing.assert_allclose(lam, full[:k], rtol=0, atol=bound)
    assert np.all(np.diff(lam) <= 0)
    np.testing.assert_allclose(K @ U, U * lam, rtol=0, atol=10 * bound)
    np.testing.assert_allclose(U.T @ U, np.eye(k), rtol=0, atol=10 * bound)
    # Same matrix, same answer (fixed ARPACK start), whatever was computed before.
    lam2, U2 = krylov_eigenpairs(K, t, expected)
    np.testing.assert_array_equal(lam2, lam)
    np.testing.assert_array_equal(U2, U)


def test_krylov_hands_over_to_mrrr_when_many_eigenvalues_pass():
    rng = np.random.default_rng(3)
    K = rbf_kernel(rng.normal(size=(200, 5)), 0.05)
    t = 1e-6  # most of the spectrum passes
    lam, U = krylov_eigenpairs(K, t)
    ref, _ = leading_eigenpairs(K, t, "partial")
    assert lam.size == ref.size > KRYLOV_MAX_FRACTION * K.shape[0]
    np.testing.assert_allclose(lam, ref, rtol=0, atol=_bound(K))


def test_closed_form_by_krylov_equals_the_full_one():
    rng = np.random.default_rng(5)
    K = rbf_kernel(rng.normal(size=(350, 5)), 0.2)
    C_full = closed_form_rank_penalty(K, 2.0, 1.0, eigensolver="full")
    C_kry = closed_form_rank_penalty(K, 2.0, 1.0, eigensolver="krylov")
    np.testing.assert_allclose(C_kry.T @ C_kry, C_full.T @ C_full, rtol=0, atol=1e-10)


@pytest.mark.parametrize("center", [False, True])
@pytest.mark.parametrize("rho", [1.0, 100.0])
def test_krylov_energy_and_gradient_equal_the_reference(completion, center, rho):
    X, mask, S0 = completion
    term = MaskedLeastSquares(X, mask)
    kw = dict(gamma=0.1, tau=0.1, rho=rho, center=center)
    v_ref, g_ref = reduced_energy(S0, term, eigensolver="full", **kw)
    v, g = reduced_energy(S0, term, eigensolver="krylov", **kw)
    # As for "partial" (tests/test_regularizer.py): entries of dE/dK move by about rho n eps ||K||_F.
    K = rbf_kernel(S0, 0.1)
    assert v == pytest.approx(v_ref, rel=1e-12)
    atol = rho * K.shape[0] * np.finfo(float).eps * np.linalg.norm(K)
    np.testing.assert_allclose(g, g_ref, rtol=0, atol=atol)


def test_krylov_gradient_matches_finite_differences(completion):
    """Directional derivatives of the reduced energy along random directions, central differences."""
    X, mask, S0 = completion
    term = MaskedLeastSquares(X, mask)
    kw = dict(gamma=0.1, tau=0.1, rho=10.0, eigensolver="krylov")
    _, g = reduced_energy(S0, term, **kw)
    rng = np.random.default_rng(0)
    h = 1e-5
    for _ in range(3):
        V = rng.standard_normal(S0.shape)
        V /= np.linalg.norm(V)
        fd = (reduced_energy(S0 + h * V, term, **kw)[0] - reduced_energy(S0 - h * V, term, **kw)[0]) / (2 * h)
        # Central differences err by O(h^2 |E'''|) plus rounding eps |E| / h; the energy is O(10), so
        # rounding contributes ~1e-10 and curvature terms ~1e-8 at h = 1e-5.
        assert fd == pytest.approx(float(np.sum(g * V)), rel=1e-6, abs=1e-6)


def test_auto_chooses_krylov_only_for_small_ranks_at_large_n():
    hint = _RankHint()
    assert hint.solver("auto", 1000) == "auto"  # no rank known yet
    hint.rank = 100
    assert hint.solver("auto", 1000) == "krylov"
    assert hint.solver("auto", 200) == "auto"  # below PARTIAL_MIN_N: the full decomposition
    assert hint.solver("full", 1000) == "full"
    hint.rank = int(KRYLOV_AUTO_FRACTION * 1000) + 1
    assert hint.solver("auto", 1000) == "auto"


def test_auto_solve_with_krylov_reproduces_the_reference_solve(completion):
    """The default at n = 320 (Lanczos while the rank is small) against the full-decomposition solver."""
    X, mask, S0 = completion
    term = MaskedLeastSquares(X, mask)
    kw = dict(gamma=0.1, tau=0.1, rho_max=100.0)
    ref = minimize_regularized(term, S0, options={"eigensolver": "full"}, **kw)
    new = minimize_regularized(term, S0, **kw)
    assert ref.success and new.success
    assert new.rank_history[-1] <= KRYLOV_AUTO_FRACTION * X.shape[0]  # Lanczos throughout
    # integer ranks: every stage's eigenvalues lie > 1e8 rounding bounds (n eps ||K||) from the threshold
    np.testing.assert_array_equal(new.rank_history, ref.rank_history)
    # Both stop once an iteration lowers the energy by less than ftol = 1e-10 relative (as in
    # tests/test_regularizer.py's partial-path test).
    np.testing.assert_allclose(new.stage_energy, ref.stage_energy, rtol=1e-8)
    np.testing.assert_allclose(new.x, ref.x, rtol=0, atol=1e-3 * np.abs(X).max())


def test_stage_tol_loosens_only_the_earlier_stages(completion):
    X, mask, S0 = completion
    term = MaskedLeastSquares(X[:80], mask[:80])
    kw = dict(gamma=0.1, tau=0.1, rho_max=100.0)
    ref = minimize_regularized(term, S0[:80], **kw)
    same = minimize_regularized(term, S0[:80], options={"stage_tol": 1e-10}, **kw)
    np.testing.assert_array_equal(same.x, ref.x)  # stage_tol = tol: the default, bit for bit
    loose = minimize_regularized(term, S0[:80], options={"stage_tol": 1e-5}, **kw)
    assert loose.success
    last = loose.stage_of_iteration == loose.n_stages - 1
    assert np.count_nonzero(~last) < np.count_nonzero(ref.stage_of_iteration < ref.n_stages - 1)
    # The last stage still runs to tol: its energy is a local minimum's; here (one basin) the same one.
    assert loose.stage_energy[-1] == pytest.approx(ref.stage_energy[-1], rel=1e-6)
    with pytest.raises(ValueError, match="stage_tol"):
        minimize_regularized(term, S0[:80], options={"stage_tol": 0.0}, **kw)
