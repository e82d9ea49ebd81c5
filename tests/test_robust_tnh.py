"""Robust TNH (l1 reprojection term, ADMM): agreement with cvxpy, its certificate, input checks."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import synthetic_sequence

from nldr.nrsfm import OrthographicReprojection
from nldr.nrsfm._admm import robust_trace_norm_heuristic
from nldr.nrsfm._layout import random_visibility_mask
from nldr.nrsfm._reconstruct import trace_norm_heuristic
from nldr.nrsfm._tnh import TNHResult
from nldr.result import CONVERGED

cp = pytest.importorskip("cvxpy")

# ADMM stops at a relative duality gap TOL: fun <= OPT (1 + TOL). CLARABEL is run with relative gap
# and feasibility tolerances CVX_TOL, so its objective is within about CVX_TOL of OPT too.
TOL = 1e-8
CVX_TOL = 1e-9


def corrupted_problem(missing=0.0, seed=4, n_frames=10, n_points=6, share=0.15):
    """A small rank-2 sequence with ``share`` of the observed coordinates displaced by 2-4 track sds."""
    X, W, R = synthetic_sequence(n_frames=n_frames, n_points=n_points, seed=seed)
    F, P = X.shape[0], X.shape[1] // 3
    mask = random_visibility_mask(F, P, missing, random_state=seed)
    mask2 = np.concatenate([mask, mask], axis=1)
    rng = np.random.default_rng(seed)
    idx = np.flatnonzero(mask2.ravel())
    chosen = rng.choice(idx, size=int(round(share * idx.size)), replace=False)
    Wc = W.copy().ravel()
    Wc[chosen] += rng.choice([-1.0, 1.0], chosen.size) * rng.uniform(2, 4, chosen.size) * W.std()
    return X, np.where(mask2, Wc.reshape(W.shape), np.nan), R, mask


def l1_error(W, R, mask, X):
    """Sum of absolute reprojection residuals of X over the observed coordinates."""
    return float(np.abs(OrthographicReprojection(W, mask, R).residuals(X)).sum())


def robust_objective(W, R, mask, X, tau):
    """tau ||X||_* + the l1 reprojection error: what the robust TNH minimises."""
    return tau * float(np.linalg.svd(X, compute_uv=False).sum()) + l1_error(W, R, mask, X)


def cvxpy_robust_tnh(W, R, mask, tau):
    """The same problem written directly in cvxpy: tau ||X||_* + || b + J vec(X) ||_1 (r = b + J x)."""
    term = OrthographicReprojection(W, mask, R)
    J = term.jacobian()
    b = term.residuals(np.zeros(term.shape))
    X = cp.Variable(term.shape)
    objective = tau * cp.normNuc(X) + cp.sum(cp.abs(b + J @ cp.vec(X, order="C")))
    problem = cp.Problem(cp.Minimize(objective))
    problem.solve(solver="CLARABEL", tol_gap_abs=CVX_TOL, tol_gap_rel=CVX_TOL, tol_feas=CVX_TOL)
    assert problem.status == cp.OPTIMAL
    return np.asarray(X.value), float(problem.value)


@pytest.mark.parametrize(("missing", "tau"), [(0.0, 1.0), (0.3, 0.5), (0.0, 3.0)])
def test_robust_tnh_matches_cvxpy(missing, tau):
    _, W, R, mask = corrupted_problem(missing)
    res = robust_trace_norm_heuristic(W, mask, R, tau=tau, tol=TOL, max_iter=200_000)
    X_ref, f_ref = cvxpy_robust_tnh(W, R, mask, tau)
    assert isinstance(res, TNHResult) and res.method == "admm_l1"
    assert res.status == CONVERGED and res.success
    # the reported objective is the objective at x, and both solvers reach the optimum to their tolerances
    assert res.fun == pytest.approx(robust_objective(W, R, mask, res.x, tau), rel=1e-12)
    assert abs(res.fun - f_ref) <= 2 * (TOL + CVX_TOL) * f_ref
    # the certified lower bound is below every objective value, cvxpy's included
    lower_bound = res.fun - res.duality_gap
    assert lower_bound <= f_ref * (1 + CVX_TOL) and lower_bound <= res.fun
    assert res.duality_gap <= TOL * res.fun
    # the solutions: with a unique minimiser and quadratic growth, a relative suboptimality eps moves the
    # minimiser by O(sqrt(eps)) relative; 10 sqrt(eps) of slack for the unknown growth constant
    eps = TOL + CVX_TOL
    assert np.linalg.norm(res.x - X_ref) <= 10 * np.sqrt(eps) * np.linalg.norm(X_ref)


def test_dual_certificate_is_feasible():
    """The returned multiplier is dual feasible: |mu| <= 1, ||A^T mu||_2 <= tau, zero where unobserved;
    its dual value is the lower bound."""
    _, W, R, mask = corrupted_problem(0.3)
    tau = 0.7
    res = robust_trace_norm_heuristic(W, mask, R, tau=tau, tol=1e-7)
    mu = res.dual
    F, P = mask.shape
    mask2 = np.concatenate([mask, mask], axis=1)
    assert np.all(mu[~mask2] == 0.0) and np.max(np.abs(mu)) <= 1.0 + 1e-12
    AtMu = np.einsum("fck,fcp->fkp", R, mu.reshape(F, 2, P)).reshape(F, 3 * P)
    assert np.linalg.norm(AtMu, 2) <= tau * (1 + 1e-10)
    b = np.where(mask2, W, 0.0)
    assert float(np.vdot(mu, b)) == pytest.approx(res.fun - res.duality_gap, rel=1e-9)


def test_small_tau_gives_the_exact_fit_and_large_tau_rejects_outliers():
    """tau -> 0: the l1 term forces the exact fit (the exact-fit TNH's nuclear norm); at a moderate tau
    the displaced coordinates carry the residual and the clean ones are fit (sparse residuals)."""
    X, W, R, mask = corrupted_problem(0.0, n_frames=20, n_points=10, share=0.05)
    exact = trace_norm_heuristic(W, mask, R, tol=1e-9)
    small = robust_trace_norm_heuristic(W, mask, R, tau=1e-3, tol=1e-9, max_iter=100_000)
    assert l1_error(W, R, mask, small.x) <= 1e-6 * np.abs(np.nan_to_num(W)).sum()
    assert small.nuclear_norm == pytest.approx(exact.nuclear_norm, rel=1e-5)
    robust = robust_trace_norm_heuristic(W, mask, R, tau=2.0, tol=1e-8, max_iter=100_000)
    assert l1_error(W, R, mask, robust.x) > 0 and robust.nuclear_norm < exact.nuclear_norm


def test_scale_free():
    """Tracks in other units: same tau, shapes scaled, objective scaled."""
    _, W, R, mask = corrupted_problem(0.3)
    a = robust_trace_norm_heuristic(W, mask, R, tau=1.0, tol=1e-9, max_iter=100_000)
    b = robust_trace_norm_heuristic(1000.0 * W, mask, R, tau=1.0, tol=1e-9, max_iter=100_000)
    assert b.fun == pytest.approx(1000.0 * a.fun, rel=1e-7)
    assert np.linalg.norm(b.x - 1000.0 * a.x) <= 1e-3 * np.linalg.norm(b.x)


def test_input_validation():
    _, W, R, mask = corrupted_problem(0.0)
    with pytest.raises(ValueError, match="tau"):
        robust_trace_norm_heuristic(W, mask, R, tau=0.0)
    with pytest.raises(ValueError, match="tau"):
        robust_trace_norm_heuristic(W, mask, R, tau=-1.0)
    with pytest.raises(ValueError, match="tol must be in"):
        robust_trace_norm_heuristic(W, mask, R, tau=1.0, tol=2.0)
    with pytest.raises(ValueError, match="max_iter"):
        robust_trace_norm_heuristic(W, mask, R, tau=1.0, max_iter=0)
    with pytest.raises(ValueError, match="relaxation"):
        robust_trace_norm_heuristic(W, mask, R, tau=1.0, relaxation=2.5)
    with pytest.raises(ValueError, match="X0 must have shape"):
        robust_trace_norm_heuristic(W, mask, R, tau=1.0, X0=np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"R must have shape \(F, 2, 3\)"):
        robust_trace_norm_heuristic(W, mask, R[:, :1], tau=1.0)
    with pytest.raises(ValueError, match="mask must have shape"):
        robust_trace_norm_heuristic(W, mask[:, :2], R, tau=1.0)
    with pytest.raises(RuntimeWarning, match="max_iter"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            robust_trace_norm_heuristic(W, mask, R, tau=1.0, max_iter=5)
