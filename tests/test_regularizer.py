"""Tests of the penalty-method solver (Algorithm 1), its building blocks, and its reference (the
literal alternation of nldr.reference.regularizer)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from threadpoolctl import threadpool_limits

from nldr._reduced import optimal_kernel_factor
from nldr._schedule import penalty_schedule
from nldr._spectral import leading_eigenpairs
from nldr.data_terms import MaskedLeastSquares
from nldr.kernels import center_kernel, rbf_kernel
from nldr.reference.regularizer import (
    finite_difference_pre_image_step,
    kernel_mismatch_jacobian,
    kernel_mismatch_residuals,
    minimize_regularized_alternation,
    pre_image_step,
)
from nldr.regularizer import RegularizerResult, minimize_regularized, reduced_energy
from nldr.regularizer import _regularized_energy as regularized_energy
from nldr.result import CONVERGED, MAX_ITER, SolverResult
from nldr.robust_kpca import closed_form_rank_penalty, rank_penalty_threshold


def _central_difference(fun, S, h=1e-6):
    """Jacobian (m, S.size) of a vector function of S by central differences."""
    x = S.ravel()
    cols = []
    for k in range(x.size):
        e = np.zeros_like(x)
        e[k] = h
        cols.append((fun((x + e).reshape(S.shape)) - fun((x - e).reshape(S.shape))) / (2 * h))
    return np.stack(cols, axis=1)


def _helix(n, rng, noise=0.0):
    """n points on one turn of a helix in R^6 (non-linear dimension 1, linear rank 3).

    Each coordinate of the helix (cos t, sin t, 0.3 t) appears twice, once phase-shifted, so that a
    point keeping a few of its six entries is still pinned to one place on the curve.
    """
    t = np.sort(rng.uniform(0.0, 2.0 * np.pi, n))
    X = np.column_stack([np.cos(t), np.sin(t), np.cos(t + 1), np.sin(t + 1), 0.3 * t, 0.3 * t])
    return X + noise * rng.standard_normal(X.shape)


@pytest.fixture(autouse=True)
def single_blas_thread():
    # Multithreaded BLAS on small matrices is slower, and much slower beside other jobs.
    with threadpool_limits(1):
        yield


@pytest.fixture
def small_problem():
    rng = np.random.default_rng(0)
    W = rng.standard_normal((9, 3))
    mask = rng.random(W.shape) > 0.3
    S = W + 0.3 * rng.standard_normal(W.shape)
    return W, mask, S


# ---------------------------------------------------------------------------------------------
# Residuals, Jacobians, energies
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("center", [False, True])
def test_mismatch_residuals_square_to_the_penalty(small_problem, center):
    _, _, S = small_problem
    C = optimal_kernel_factor(S, gamma=0.4, tau=0.2, rho=3.0, center=center) * 0.9
    r = kernel_mismatch_residuals(S, C, gamma=0.4, rho=3.0, center=center)
    K = rbf_kernel(S, 0.4)
    if center:
        K = center_kernel(K)
    assert r.shape == (9 * 10 // 2,)
    assert r @ r == pytest.approx(1.5 * np.sum((K - C.T @ C) ** 2), rel=1e-12)


def test_sparse_jacobian_matches_finite_differences(small_problem):
    _, _, S = small_problem
    gamma, rho = 0.4, 3.0
    C = optimal_kernel_factor(S, gamma=gamma, tau=0.2, rho=rho)
    J = kernel_mismatch_jacobian(S, gamma=gamma, rho=rho)
    assert sp.issparse(J)
    n, d = S.shape
    assert J.shape == (n * (n + 1) // 2, n * d)
    assert J.nnz == n * (n - 1) // 2 * 2 * d  # 2 d entries per off-diagonal pair, none on the diagonal
    J_fd = _central_difference(lambda X: kernel_mismatch_residuals(X, C, gamma=gamma, rho=rho), S)
    np.testing.assert_allclose(J.toarray(), J_fd, atol=1e-8, rtol=1e-6)


@pytest.mark.parametrize("center", [False, True])
def test_matrix_free_jacobian_matches_finite_differences(small_problem, center):
    _, _, S = small_problem
    gamma, rho = 0.4, 3.0
    C = optimal_kernel_factor(S, gamma=gamma, tau=0.2, rho=rho, center=center)
    J = kernel_mismatch_jacobian(S, gamma=gamma, rho=rho, center=center, matrix_free=True)
    J_dense = J.matmat(np.eye(S.size))
    J_fd = _central_difference(
        lambda X: kernel_mismatch_residuals(X, C, gamma=gamma, rho=rho, center=center), S
    )
    np.testing.assert_allclose(J_dense, J_fd, atol=1e-8, rtol=1e-6)
    # The adjoint is the transpose.
    np.testing.assert_allclose(J.rmatmat(np.eye(J.shape[0])), J_dense.T, atol=1e-12)


@pytest.mark.parametrize("center", [False, True])
def test_reduced_gradient_matches_finite_differences(small_problem, center):
    W, mask, S = small_problem
    term = MaskedLeastSquares(W, mask)
    kw = dict(gamma=0.4, tau=0.2, rho=5.0, center=center)
    value, grad = reduced_energy(S, term, **kw)
    assert grad.shape == S.shape
    g_fd = _central_difference(lambda X: np.array([reduced_energy(X, term, **kw)[0]]), S).reshape(S.shape)
    np.testing.assert_allclose(grad, g_fd, atol=1e-6, rtol=1e-5)


@pytest.mark.parametrize("center", [False, True])
def test_reduced_energy_is_the_full_energy_at_the_optimal_factor(small_problem, center):
    W, mask, S = small_problem
    term = MaskedLeastSquares(W, mask)
    kw = dict(gamma=0.4, tau=0.2, rho=5.0, center=center)
    C = optimal_kernel_factor(S, **kw)
    value, _ = reduced_energy(S, term, **kw)
    assert value == pytest.approx(regularized_energy(S, C, term, **kw), rel=1e-10)
    # ... and no other factor does better.
    rng = np.random.default_rng(1)
    for _ in range(5):
        assert regularized_energy(S, C + 0.01 * rng.standard_normal(C.shape), term, **kw) > value
    K = rbf_kernel(S, 0.4)
    if not center:
        np.testing.assert_allclose(
            C.T @ C, (lambda C2: C2.T @ C2)(closed_form_rank_penalty(K, 0.2, 5.0)), atol=1e-12
        )


def test_alternation_steps_never_increase_the_energy():
    rng = np.random.default_rng(2)
    W = _helix(30, rng, noise=0.05)
    mask = rng.random(W.shape) > 0.2
    term = MaskedLeastSquares(W, mask)
    S = np.where(mask, W, np.nanmean(np.where(mask, W, np.nan), axis=0))
    kw = dict(gamma=0.5, tau=0.1, rho=10.0)
    C = optimal_kernel_factor(S, gamma=0.5, tau=0.1, rho=1.0)  # some non-optimal factor to start from
    energy = regularized_energy(S, C, term, **kw)
    for _ in range(4):
        C = optimal_kernel_factor(S, **kw)
        after_c = regularized_energy(S, C, term, **kw)
        assert after_c <= energy + 1e-12 * abs(energy)
        S = pre_image_step(S, C, term, gamma=0.5, rho=10.0, max_iter=20)
        after_s = regularized_energy(S, C, term, **kw)
        assert after_s <= after_c + 1e-12 * abs(after_c)
        energy = after_s


# ---------------------------------------------------------------------------------------------
# The solver
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def helix_completion():
    rng = np.random.default_rng(3)
    X = _helix(60, rng)
    mask = rng.random(X.shape) > 0.2
    S0 = np.where(mask, X, np.nanmean(np.where(mask, X, np.nan), axis=0))
    return X, mask, S0


@pytest.mark.parametrize("center", [False, True])
def test_recovers_points_on_a_curve_far_better_than_mean_imputation(helix_completion, center):
    X, mask, S0 = helix_completion
    res = minimize_regularized(MaskedLeastSquares(X, mask), S0, gamma=0.5, tau=0.1, center=center)
    assert isinstance(res, RegularizerResult) and isinstance(res, SolverResult)
    mean_error = np.sum((S0 - X) ** 2)
    error = np.sum((res.x - X) ** 2)
    assert error < 0.3 * mean_error, (error, mean_error)
    assert res.x.shape == X.shape and res.C.shape == (60, 60)
    assert res.n_stages == len(res.rho_history) == len(res.rank_history) == len(res.stage_energy)
    assert res.energy_history.shape == res.stage_of_iteration.shape == (res.nit,)
    assert res.fun == res.stage_energy[-1]
    assert res.wall_time > 0
    assert repr(res).startswith("RegularizerResult(success=True, status=0,") and "\n" not in repr(res)


@pytest.mark.parametrize("center", [False, True])
def test_alternation_descends_and_improves_on_mean_imputation(helix_completion, center):
    # The literal alternation crawls (see its module docstring), so only a short run is checked.
    X, mask, S0 = helix_completion
    term = MaskedLeastSquares(X, mask)
    res = minimize_regularized_alternation(
        term, S0, gamma=0.5, tau=0.1, center=center, rho_max=10.0, max_inner=10, lm_max_iter=5
    )
    assert isinstance(res, RegularizerResult)
    assert np.sum((res.x - X) ** 2) < 0.9 * np.sum((S0 - X) ** 2)
    assert res.nit == res.energy_history.size == 20
    assert res.fun == res.stage_energy[-1]
    for k in range(res.n_stages):
        e = res.energy_history[res.stage_of_iteration == k]
        assert np.all(np.diff(e) <= 1e-12 * np.abs(e[1:]))
        # The final closed-form C-step can only lower the stage's last energy further.
        assert res.stage_energy[k] <= e[-1] * (1 + 1e-12)
    C = optimal_kernel_factor(res.x, gamma=0.5, tau=0.1, rho=10.0, center=center)
    np.testing.assert_allclose(res.C.T @ res.C, C.T @ C, atol=1e-10)


def test_finite_difference_pre_image_step_agrees_with_the_analytic_one(small_problem):
    W, mask, S = small_problem
    term = MaskedLeastSquares(W, mask)
    C = optimal_kernel_factor(S, gamma=0.4, tau=0.2, rho=3.0)
    kw = dict(gamma=0.4, rho=3.0, max_iter=30, tol=1e-12)
    S_analytic = pre_image_step(S, C, term, **kw)
    S_fd = finite_difference_pre_image_step(S, C, term, **kw)
    np.testing.assert_allclose(S_fd, S_analytic, atol=1e-5)


def test_default_solver_converges_and_reports_it(helix_completion):
    X, mask, S0 = helix_completion
    res = minimize_regularized(MaskedLeastSquares(X, mask), S0, gamma=0.5, tau=0.1)
    assert res.success and res.status == CONVERGED
    assert "converged" in res.message
    np.testing.assert_allclose(res.rho_history, [1.0, 10.0, 100.0, 1e3, 1e4])
    assert res.nit == res.energy_history.size
    # Within a stage L-BFGS never increases the energy.
    for k in range(res.n_stages):
        e = res.energy_history[res.stage_of_iteration == k]
        assert np.all(np.diff(e) <= 1e-9 * np.abs(e[1:]))


@pytest.mark.parametrize("solver", ["reduced", "alternation"])
def test_iteration_limit_is_reported(helix_completion, solver):
    X, mask, S0 = helix_completion
    term = MaskedLeastSquares(X, mask)
    kw = dict(gamma=0.5, tau=0.1, rho_max=10.0)
    if solver == "reduced":
        res = minimize_regularized(term, S0, options={"max_inner": 1}, **kw)
    else:
        res = minimize_regularized_alternation(term, S0, lm_max_iter=3, max_inner=1, **kw)
    assert not res.success and res.status == MAX_ITER
    assert "limit" in res.message and "rho=1" in res.message
    assert res.nit == 2 * 1


# ---------------------------------------------------------------------------------------------
# Validation at the edge
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        (dict(gamma=0.0), "gamma"),
        (dict(gamma=-1.0), "gamma"),
        (dict(tau=0.0), "tau"),
        (dict(tau=np.nan), "tau"),
        (dict(rho0=0.0), "rho0"),
        (dict(rho_growth=1.0), "rho_growth"),
        (dict(rho_max=0.5, rho0=1.0), "rho_max"),
        (dict(max_inner=0), "max_inner"),
        (dict(max_inner=2.5), "max_inner"),
        (dict(tol=-1.0), "tol"),
        (dict(eigensolver="lanczos"), "eigensolver"),
    ],
)
@pytest.mark.parametrize("solver", [minimize_regularized, minimize_regularized_alternation])
def test_bad_parameters_raise_naming_the_argument(small_problem, kwargs, name, solver):
    W, mask, S = small_problem
    args = dict(gamma=0.4, tau=0.1) | kwargs
    if solver is minimize_regularized and name in ("max_inner", "tol", "eigensolver"):  # its options
        args = dict(gamma=0.4, tau=0.1, options=kwargs)
    with pytest.raises(ValueError, match=name):
        solver(MaskedLeastSquares(W, mask), S, **args)


def test_bad_reference_parameters_raise_naming_the_argument(small_problem):
    W, mask, S = small_problem
    term = MaskedLeastSquares(W, mask)
    with pytest.raises(ValueError, match="lm_max_iter"):
        minimize_regularized_alternation(term, S, gamma=0.4, tau=0.1, lm_max_iter=0)
    with pytest.raises(ValueError, match="lm_tol"):
        minimize_regularized_alternation(term, S, gamma=0.4, tau=0.1, lm_tol=0.0)
    with pytest.raises(ValueError, match="S0"):
        minimize_regularized_alternation(term, S[:-1], gamma=0.4, tau=0.1)


def test_penalty_schedule_runs_from_rho0_to_rho_max():
    assert penalty_schedule(1.0, 10.0, 1e4) == [1.0, 10.0, 100.0, 1000.0, 10000.0]
    # 0.1 * 3 * 3 rounds to 0.9000000000000001 > 0.9: the relative 1e-12 slack keeps that stage
    assert penalty_schedule(0.1, 3.0, 0.9) == pytest.approx([0.1, 0.3, 0.9], rel=1e-15)
    assert penalty_schedule(2.0, 3.0, 2.0) == [2.0]
    with pytest.raises(ValueError, match="rho_growth"):
        penalty_schedule(1.0, 0.5, 10.0)


def test_bad_start_or_data_term_raises(small_problem):
    W, mask, S = small_problem
    term = MaskedLeastSquares(W, mask)
    with pytest.raises(ValueError, match="S0"):
        minimize_regularized(term, S[:-1], gamma=0.4, tau=0.1)
    with pytest.raises(ValueError, match="S0"):
        minimize_regularized(term, S.T, gamma=0.4, tau=0.1)
    S_nan = S.copy()
    S_nan[0, 0] = np.nan
    with pytest.raises(ValueError, match="S0"):
        minimize_regularized(term, S_nan, gamma=0.4, tau=0.1)
    with pytest.raises(ValueError, match="data_term"):
        minimize_regularized(object(), S, gamma=0.4, tau=0.1)
    with pytest.raises(ValueError, match="C"):
        regularized_energy(S, np.ones((3, 4)), term, gamma=0.4, tau=0.1, rho=1.0)


# ---------------------------------------------------------------------------------------------
# Partial eigendecomposition against the reference (full) implementation
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def large_helix_completion():
    # n = 320 >= 300, so eigensolver="auto" takes the partial path.
    rng = np.random.default_rng(4)
    X = _helix(320, rng)
    mask = rng.random(X.shape) > 0.2
    S0 = np.where(mask, X, np.nanmean(np.where(mask, X, np.nan), axis=0))
    return X, mask, S0


def test_leading_eigenpairs_are_exactly_the_ones_above_the_threshold(large_helix_completion):
    _, _, S0 = large_helix_completion
    K = rbf_kernel(S0, 0.5)
    t = rank_penalty_threshold(0.1, 1.0)
    full = np.linalg.eigvalsh(K)[::-1]
    for solver in ("auto", "partial", "full"):
        lam, U = leading_eigenpairs(K, t, solver)
        # Backward-stable eigensolvers: eigenvalues to n eps ||K||, eigenpairs K u = lam u likewise.
        bound = K.shape[0] * np.finfo(float).eps * np.linalg.norm(K, 2)
        # the count may differ from eigvalsh's only by eigenvalues within that bound of t (none here)
        assert abs(lam.size - np.count_nonzero(full > t)) <= np.count_nonzero(np.abs(full - t) <= bound)
        assert lam.size < K.shape[0] // 4
        np.testing.assert_allclose(lam, full[: lam.size], rtol=0, atol=bound)
        assert np.all(np.diff(lam) <= 0)
        np.testing.assert_allclose(K @ U, U * lam, rtol=0, atol=10 * bound)
        np.testing.assert_allclose(U.T @ U, np.eye(lam.size), rtol=0, atol=10 * bound)


@pytest.mark.parametrize("center", [False, True])
@pytest.mark.parametrize("rho", [1.0, 1e4])
def test_partial_eigensolver_gives_the_reference_energy_and_gradient(large_helix_completion, center, rho):
    X, mask, S0 = large_helix_completion
    term = MaskedLeastSquares(X, mask)
    kw = dict(gamma=0.5, tau=0.1, rho=rho, center=center)
    v_ref, g_ref = reduced_energy(S0, term, eigensolver="full", **kw)
    K = rbf_kernel(S0, 0.5)
    # dE/dK = rho (K - C^T C) is formed from eigenpairs exact to n eps ||K|| (backward error), so each
    # entry of the gradient moves by at most about rho n eps ||K||_F; the value by far less.
    atol = rho * K.shape[0] * np.finfo(float).eps * np.linalg.norm(K)
    for solver in ("auto", "partial"):
        v, g = reduced_energy(S0, term, eigensolver=solver, **kw)
        assert v == pytest.approx(v_ref, rel=1e-12)
        np.testing.assert_allclose(g, g_ref, rtol=0, atol=atol)


@pytest.mark.parametrize("center", [False, True])
def test_solver_with_partial_decompositions_reproduces_the_reference_solve(large_helix_completion, center):
    """Fixed seeds: the new default ("auto") against the original full-decomposition solver."""
    X, mask, S0 = large_helix_completion
    term = MaskedLeastSquares(X, mask)
    ref = minimize_regularized(term, S0, gamma=0.5, tau=0.1, center=center, options={"eigensolver": "full"})
    new = minimize_regularized(term, S0, gamma=0.5, tau=0.1, center=center)
    assert ref.success and new.success
    # integer ranks: every stage's eigenvalues lie > 1e7 rounding bounds (n eps ||K||) from the threshold
    np.testing.assert_array_equal(new.rank_history, ref.rank_history)
    # Both stop at the same minimum, each once a step lowers the energy by less than ftol = 1e-10
    # relative; what remains is a few times that per stage.
    np.testing.assert_allclose(new.stage_energy, ref.stage_energy, rtol=1e-8)
    np.testing.assert_allclose(new.x, ref.x, rtol=0, atol=1e-3 * np.abs(X).max())
    np.testing.assert_allclose(new.C.T @ new.C, ref.C.T @ ref.C, rtol=0, atol=1e-3)


def test_closed_form_partial_and_full_agree():
    rng = np.random.default_rng(5)
    K = rbf_kernel(rng.normal(size=(350, 5)), 0.2)
    C_full = closed_form_rank_penalty(K, 2.0, 1.0, eigensolver="full")
    C_part = closed_form_rank_penalty(K, 2.0, 1.0, eigensolver="partial")
    assert C_part.shape == C_full.shape == K.shape
    np.testing.assert_allclose(C_part.T @ C_part, C_full.T @ C_full, rtol=0, atol=1e-10)
    with pytest.raises(ValueError, match="eigensolver"):
        closed_form_rank_penalty(K, 2.0, 1.0, eigensolver="lanczos")
    with pytest.raises(ValueError, match="eigensolver"):
        S = K[:, :3]
        term = MaskedLeastSquares(S, S > 0.5)
        minimize_regularized(term, S, gamma=1.0, tau=1.0, options={"eigensolver": 1})


def test_the_isolation_guard_is_on_by_default():
    """Without arguments the solver starts at rho0 >= tau sqrt(27/8) (docs/REPRODUCTION.md#escape):
    the default run equals the guarded one, and differs from the unguarded one when rho0 = 1 is below
    that floor (tau = 10: floor 18.4)."""
    rng = np.random.default_rng(11)
    X = rng.random((30, 5))
    mask = rng.random(X.shape) > 0.3
    term = MaskedLeastSquares(np.where(mask, X, np.nan), mask)
    S0 = np.where(mask, X, np.nanmean(np.where(mask, X, np.nan), axis=0))
    kw = dict(gamma=2.0, tau=10.0, rho0=1.0, rho_max=1e3)
    default = minimize_regularized(term, S0, options={"max_inner": 200}, **kw)
    guarded = minimize_regularized(term, S0, options={"max_inner": 200, "isolation_guard": True}, **kw)
    unguarded = minimize_regularized(term, S0, options={"max_inner": 200, "isolation_guard": False}, **kw)
    np.testing.assert_array_equal(default.x, guarded.x)
    assert not np.array_equal(default.x, unguarded.x)


class _ThreadSpy(MaskedLeastSquares):
    """A data term that records the BLAS thread count while the solver evaluates it."""

    seen: set

    def gradient(self, S):
        self.seen |= _blas_threads()
        return super().gradient(S)


def _blas_threads():
    from threadpoolctl import threadpool_info

    return {info["num_threads"] for info in threadpool_info() if info["user_api"] == "blas"}


@pytest.mark.parametrize("auto", ["1", "0"])
def test_small_problems_run_on_one_blas_thread_unless_switched_off(monkeypatch, auto):
    """nldr._threads: below SMALL_PROBLEM_ROWS samples the solver uses one BLAS thread whatever the
    caller set (two threads on a 100-row problem were 100x slower on a busy machine, issue 20);
    NLDR_AUTO_THREADS=0 leaves the caller's setting."""
    monkeypatch.setenv("NLDR_AUTO_THREADS", auto)
    rng = np.random.default_rng(5)
    X = rng.random((40, 4))
    mask = rng.random(X.shape) > 0.2
    term = _ThreadSpy(np.where(mask, X, np.nan), mask)
    term.seen = set()
    S0 = np.where(mask, X, np.nanmean(np.where(mask, X, np.nan), axis=0))
    with threadpool_limits(2, user_api="blas"):
        callers = _blas_threads()  # 2, or 1 for a single-threaded BLAS another package loaded
        minimize_regularized(term, S0, gamma=1.0, tau=0.1, rho_max=10.0, options={"max_inner": 20})
    assert 2 in callers
    assert term.seen == ({1} if auto == "1" else callers)
