"""NRSfM building blocks with known cameras: layouts, e3D metric, reprojection term, TNH (cvxpy)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from conftest import nuclear_norm, project, random_rotation, synthetic_sequence

from nldr.data_terms import DataTerm
from nldr.nrsfm import TNHSolveError
from nldr.nrsfm._cvxpy_tnh import CvxpyTNH
from nldr.nrsfm._layout import random_visibility_mask, stack_to_rows
from nldr.nrsfm._metrics import center_per_frame, e3d, e3d_per_frame, ground_truth_sigma, procrustes_rotation
from nldr.nrsfm._reconstruct import trace_norm_heuristic
from nldr.nrsfm._reprojection import OrthographicReprojection, visibility_weights
from nldr.nrsfm._tnh import fista_tnh
from nldr.result import CONVERGED, MAX_ITER

# ---------------------------------------------------------------------------------------------------------
# helpers


def load_real(name: str):
    """Load a mocap sequence; a missing file fails when NLDR_DATA_MIRROR is set, else skips."""
    from nldr.datasets import load_mocap

    mirror = os.environ.get("NLDR_DATA_MIRROR")
    root = Path(mirror or "/work/shared/data")
    if not (root / "nrsfm" / f"{name}.mat").is_file():
        message = f"nrsfm/{name}.mat not found under {root}"
        if mirror:
            pytest.fail(f"{message} (NLDR_DATA_MIRROR is set, so the data must be there)")
        pytest.skip(message)
    return load_mocap(name, data_dir=root)


# ---------------------------------------------------------------------------------------------------------
# layout


@pytest.mark.parametrize("dim", [2, 3])
def test_layout_round_trip(dim):
    rng = np.random.default_rng(1)
    F, P = 5, 7
    M = rng.standard_normal((dim * F, P))
    X = stack_to_rows(M, dim)
    assert X.shape == (F, dim * P)
    for f in range(F):
        np.testing.assert_array_equal(X[f], M[dim * f : dim * f + dim].ravel())
    np.testing.assert_array_equal(X.reshape(dim * F, P), M)  # the inverse is a reshape


def test_layout_errors():
    with pytest.raises(ValueError, match="multiple of dim"):
        stack_to_rows(np.zeros((7, 4)), 3)
    with pytest.raises(ValueError, match="dim"):
        stack_to_rows(np.zeros((8, 4)), 4)


def test_random_visibility_mask():
    mask = random_visibility_mask(36, 41, 0.5, random_state=3)
    assert mask.shape == (36, 41) and mask.dtype == bool
    assert (~mask).sum() == round(0.5 * 36 * 41)
    np.testing.assert_array_equal(mask, random_visibility_mask(36, 41, 0.5, random_state=3))
    assert not np.array_equal(mask, random_visibility_mask(36, 41, 0.5, random_state=4))
    assert random_visibility_mask(3, 4, 0.0).all()
    with pytest.raises(ValueError, match="missing_fraction"):
        random_visibility_mask(3, 4, 1.0)


# ---------------------------------------------------------------------------------------------------------
# e3D


def e3d_brute_force(X_est, X_gt, P):
    """Loop transcription of the definition (per-row population std, as in compareStructs.m)."""
    F = X_gt.shape[0]
    S_gt, S_est = X_gt.reshape(3 * F, P), X_est.reshape(3 * F, P)
    stds = []
    for row in range(3 * F):
        values = S_gt[row]
        stds.append(np.sqrt(np.sum((values - values.mean()) ** 2) / P))
    sigma = np.mean(stds)
    total = 0.0
    for f in range(F):
        A = S_gt[3 * f : 3 * f + 3]
        B = S_est[3 * f : 3 * f + 3]
        A = A - A.mean(axis=1, keepdims=True)
        B = B - B.mean(axis=1, keepdims=True)
        for j in range(P):
            total += np.sqrt(np.sum((A[:, j] - B[:, j]) ** 2))
    return total / (sigma * F * P)


def test_e3d_zero_translation_invariant_and_brute_force():
    rng = np.random.default_rng(4)
    F, P = 6, 10
    X_gt = 3.0 * rng.standard_normal((F, 3 * P))
    X_est = X_gt + 0.2 * rng.standard_normal((F, 3 * P))
    assert e3d(X_gt, X_gt, P) == pytest.approx(0.0, abs=1e-14)
    shift = np.repeat(rng.standard_normal((F, 3)), P, axis=1)  # per-frame translation
    assert e3d(X_gt + shift, X_gt, P) == pytest.approx(0.0, abs=1e-12)
    value = e3d(X_est, X_gt, P)
    assert value == pytest.approx(e3d_brute_force(X_est, X_gt, P), rel=1e-12)
    assert e3d(X_est + shift, X_gt - shift, P) == pytest.approx(value, rel=1e-12)
    assert e3d(7.0 * X_est, 7.0 * X_gt, P) == pytest.approx(value, rel=1e-12)  # unit-free
    assert e3d_per_frame(X_est, X_gt, P).mean() == pytest.approx(value, rel=1e-12)


def test_sigma_definitions_and_alignment():
    rng = np.random.default_rng(5)
    F, P = 8, 12
    X_gt = rng.standard_normal((F, 3 * P)) * np.repeat(rng.uniform(0.5, 3, (F, 3)), P, axis=1)
    # per-frame-averaged std <= pooled std (Jensen), equal only when all frames have the same spread
    assert ground_truth_sigma(X_gt, P) < ground_truth_sigma(X_gt, P, pooled=True)
    Q = random_rotation(rng)
    X_rot = np.einsum("kl,flp->fkp", Q, center_per_frame(X_gt, P).reshape(F, 3, P)).reshape(F, 3 * P)
    assert e3d(X_rot, X_gt, P) > 0.1
    assert e3d(X_rot, X_gt, P, align=True) == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(procrustes_rotation(X_rot, X_gt, P), Q.T, atol=1e-12)


def test_e3d_validation():
    with pytest.raises(ValueError, match="X_est"):
        e3d(np.zeros((4, 9)), np.ones((4, 12)), 4)
    with pytest.raises(ValueError, match="P"):
        e3d(np.zeros((4, 12)), np.ones((4, 12)), 0)
    with pytest.raises(ValueError, match="same shape"):
        e3d(np.zeros((3, 12)), np.ones((4, 12)), 4)


# ---------------------------------------------------------------------------------------------------------
# reprojection data term


def test_reprojection_vanishes_at_ground_truth_and_matches_loop():
    X, W, R = synthetic_sequence(seed=6)
    F, P = X.shape[0], X.shape[1] // 3
    mask = random_visibility_mask(F, P, 0.3, random_state=6)
    W_nan = np.where(np.concatenate([mask, mask], axis=1), W, np.nan)
    term = OrthographicReprojection(W_nan, mask, R)
    assert isinstance(term, DataTerm)
    assert term.shape == (F, 3 * P) and term.n_residuals == 2 * mask.sum()
    np.testing.assert_allclose(term.residuals(X), 0.0, atol=1e-12)
    assert term.value(X) == pytest.approx(0.0, abs=1e-20)

    rng = np.random.default_rng(7)
    Y = rng.standard_normal(X.shape)
    expected = sum(
        np.sum((W[f].reshape(2, P)[:, j] - R[f] @ Y[f].reshape(3, P)[:, j]) ** 2)
        for f in range(F)
        for j in range(P)
        if mask[f, j]
    )
    assert term.value(Y) == pytest.approx(expected, rel=1e-12)


def test_reprojection_jacobian_and_gradient_match_finite_differences():
    X, W, R = synthetic_sequence(n_frames=5, n_points=6, seed=8)
    F, P = X.shape[0], X.shape[1] // 3
    mask = random_visibility_mask(F, P, 0.4, random_state=8)
    term = OrthographicReprojection(W, mask, R)
    rng = np.random.default_rng(9)
    Y = rng.standard_normal(X.shape)
    J = term.jacobian(Y).toarray()
    assert J.shape == (term.n_residuals, Y.size)
    h = 1e-6
    fd = np.empty_like(J)
    for i in range(Y.size):
        E = np.zeros(Y.size)
        E[i] = h
        E = E.reshape(Y.shape)
        fd[:, i] = (term.residuals(Y + E) - term.residuals(Y - E)) / (2 * h)
    np.testing.assert_allclose(J, fd, atol=1e-8)
    G = term.gradient(Y)
    np.testing.assert_allclose(G.ravel(), 2 * J.T @ term.residuals(Y), atol=1e-12)
    g_fd = np.array(
        [
            (term.value(Y + h * e.reshape(Y.shape)) - term.value(Y - h * e.reshape(Y.shape))) / (2 * h)
            for e in np.eye(Y.size)
        ]
    )
    np.testing.assert_allclose(G.ravel(), g_fd, rtol=1e-6, atol=1e-6)


def test_reprojection_jacobian_is_minus_the_projection():
    X, W, R = synthetic_sequence(n_frames=4, n_points=5, seed=10)
    R2 = R[::-1].copy()
    term = OrthographicReprojection(W, None, R2)
    np.testing.assert_allclose(term.residuals(X), (W - project(R2, X)).ravel(), atol=1e-12)
    np.testing.assert_allclose(term.jacobian() @ X.ravel(), -project(R2, X).ravel(), atol=1e-12)


def test_reprojection_validation():
    X, W, R = synthetic_sequence(n_frames=4, n_points=5, seed=11)
    mask = np.ones((4, 5), dtype=bool)
    mask[1, 2] = False
    W_bad = W.copy()
    W_bad[1, 2] = np.nan  # unobserved x: fine
    W_bad[1, 5 + 2] = np.nan  # unobserved y: fine
    OrthographicReprojection(W_bad, mask, R)
    W_bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="W2d"):
        OrthographicReprojection(W_bad, mask, R)
    with pytest.raises(ValueError, match="W2d"):
        OrthographicReprojection(W[:, :-1], None, R)
    with pytest.raises(ValueError, match="mask"):
        OrthographicReprojection(W, mask[:, :-1], R)
    with pytest.raises(ValueError, match="mask"):
        OrthographicReprojection(W, np.full((4, 5), 2), R)
    with pytest.raises(ValueError, match="R"):
        OrthographicReprojection(W, None, R.reshape(-1, 3))
    with pytest.raises(ValueError, match="R"):
        OrthographicReprojection(W, None, R[:3])


# ---------------------------------------------------------------------------------------------------------
# trace-norm heuristic


@pytest.mark.parametrize("missing", [0.0, 0.4])
def test_tnh_exact_fit_reprojects_and_has_minimal_nuclear_norm(missing):
    X, W, R = synthetic_sequence(n_frames=12, n_points=9, rank=3, seed=12)
    F, P = X.shape[0], X.shape[1] // 3
    mask = random_visibility_mask(F, P, missing, random_state=12)
    result = trace_norm_heuristic(W, mask, R, method="cvxpy")
    assert result.success and result.exact_fit and result.tau == 0.0 and result.solver == "SCS"
    assert result.method == "cvxpy" and result.status == CONVERGED and "optimal" in result.message
    assert result.x.shape == X.shape
    scale = np.abs(W).max()
    assert result.max_abs_residual < 1e-6 * scale
    term = OrthographicReprojection(W, mask, R)
    np.testing.assert_allclose(term.residuals(result.x), 0.0, atol=1e-6 * scale)
    # the ground truth is feasible, so the minimum nuclear norm cannot exceed its nuclear norm
    assert result.nuclear_norm <= nuclear_norm(X) * (1 + 1e-6)
    assert result.fun == pytest.approx(result.nuclear_norm, rel=1e-5)
    assert result.wall_time > 0 and result.nit > 0 and result.solver_time is not None
    # the default method (ADMM) solves the same problem
    admm = trace_norm_heuristic(W, mask, R)
    assert admm.method == "admm" and admm.success
    assert admm.nuclear_norm == pytest.approx(result.nuclear_norm, rel=1e-5)


def test_tnh_scs_agrees_with_clarabel():
    X, W, R = synthetic_sequence(n_frames=10, n_points=8, rank=3, seed=13)
    F, P = X.shape[0], X.shape[1] // 3
    mask = random_visibility_mask(F, P, 0.5, random_state=13)
    tnh = CvxpyTNH(W, mask, R)
    for tau in (None, 0.3):
        scs = tnh.solve(tau, solver="SCS")
        clarabel = tnh.solve(tau, solver="CLARABEL")
        assert clarabel.solver == "CLARABEL" and clarabel.success
        assert scs.fun == pytest.approx(clarabel.fun, rel=1e-6)
        # a tiny SDP like this is well-posed; with the default eps 1e-6 SCS lands on CLARABEL's point
        np.testing.assert_allclose(scs.x, clarabel.x, atol=1e-4 * np.abs(X).max())
        assert abs(e3d(scs.x, X, P) - e3d(clarabel.x, X, P)) < 1e-4


def penalised_objective(term, X, tau):
    return tau * nuclear_norm(X) + term.value(X)


def test_tnh_penalised_optimality_and_sweep():
    X, W, R = synthetic_sequence(n_frames=12, n_points=9, rank=3, seed=14)
    F, P = X.shape[0], X.shape[1] // 3
    mask = random_visibility_mask(F, P, 0.3, random_state=14)
    noisy = W + 0.05 * np.random.default_rng(14).standard_normal(W.shape)
    tnh = CvxpyTNH(noisy, mask, R)
    term = tnh.data_term
    exact = tnh.solve()
    results = [tnh.solve(0.1)]
    compiled = tnh._penalised._cache.param_prog  # cvxpy's compiled parametric program
    assert compiled is not None
    results += [tnh.solve(tau, warm_start=True) for tau in (1.0, 10.0)]
    rng = np.random.default_rng(15)
    for res in results:
        assert res.success and not res.exact_fit
        f_opt = penalised_objective(term, res.x, res.tau)
        assert res.fun == pytest.approx(f_opt, rel=1e-5)
        assert f_opt <= penalised_objective(term, exact.x, res.tau) + 1e-6
        assert f_opt <= penalised_objective(term, X, res.tau) + 1e-6
        for _ in range(5):
            Y = res.x + 1e-2 * rng.standard_normal(X.shape)
            assert f_opt <= penalised_objective(term, Y, res.tau) + 1e-6
    # a larger tau trades reprojection error for a smaller nuclear norm
    nuclear = [res.nuclear_norm for res in results]
    errors = [res.reprojection_error for res in results]
    assert nuclear == sorted(nuclear, reverse=True) and errors == sorted(errors)
    assert exact.nuclear_norm >= nuclear[0] - 1e-6
    # the penalised problem was compiled once: the same compiled program served every tau
    assert tnh._penalised._cache.param_prog is compiled
    assert tnh.tau.value == pytest.approx(10.0)


def test_tnh_errors():
    X, W, R = synthetic_sequence(n_frames=4, n_points=5, seed=16)
    for method in ("admm", "cvxpy"):
        with pytest.raises(ValueError, match="tau"):
            trace_norm_heuristic(W, None, R, tau=-1.0, method=method)
    with pytest.raises(ValueError, match="method must be one of"):
        trace_norm_heuristic(W, None, R, method="SCS")  # a conic solver is an option of method="cvxpy"
    with pytest.raises(ValueError, match="solver"):
        trace_norm_heuristic(W, None, R, method="cvxpy", solver="NO_SUCH_SOLVER")
    with pytest.raises(ValueError, match="method must be one of"):
        trace_norm_heuristic(W, None, R, tau=1.0, method="fista")  # the penalised form: method="cvxpy"
    with pytest.raises(ValueError, match=r"unknown options for method 'admm': \['solver'\]"):
        trace_norm_heuristic(W, None, R, solver="SCS")
    with pytest.raises(ValueError, match=r"unknown options for method 'cvxpy': \['tol'\]"):
        trace_norm_heuristic(W, None, R, method="cvxpy", tol=1e-6)
    # a zero camera cannot reproduce non-zero image points: the exact fit is infeasible
    R_zero = R.copy()
    R_zero[0] = 0.0
    with pytest.raises(TNHSolveError, match="status"):
        trace_norm_heuristic(W, None, R_zero, method="cvxpy", solver="CLARABEL")
    with pytest.raises(ValueError, match="no exact fit exists"):
        trace_norm_heuristic(W, None, R_zero)


def test_tnh_cvxpy_is_optional(monkeypatch):
    """Without cvxpy the ADMM method works and method="cvxpy" says how to install it."""
    import sys

    X, W, R = synthetic_sequence(n_frames=4, n_points=5, seed=17)
    monkeypatch.setitem(sys.modules, "cvxpy", None)  # import cvxpy now raises ImportError
    monkeypatch.delitem(sys.modules, "nldr.nrsfm._cvxpy_tnh", raising=False)
    with pytest.raises(ImportError, match=r"pip install nldr\[cvxpy\]"):
        trace_norm_heuristic(W, None, R, method="cvxpy")
    assert trace_norm_heuristic(W, None, R).success


# ---------------------------------------------------------------------------------------------------------
# real data (CMU mocap, Akhter et al.)


@pytest.mark.realdata
def test_real_data_reprojects_exactly_with_ground_truth_cameras():
    seq = load_real("pickup").subsample(10)
    P = seq.n_points
    assert (seq.n_frames, P) == (36, 41)
    term = OrthographicReprojection(stack_to_rows(seq.W, 2), None, seq.R)
    X_gt = stack_to_rows(seq.S)
    assert np.max(np.abs(term.residuals(X_gt))) < 1e-12 * np.abs(seq.W).max()
    assert e3d(X_gt, X_gt, P) == 0.0


@pytest.mark.realdata
def test_real_data_tnh_exact_fit_pickup():
    seq = load_real("pickup").subsample(10)
    P = seq.n_points
    result = trace_norm_heuristic(stack_to_rows(seq.W, 2), None, seq.R, method="cvxpy")
    # paper Table 3: 0.0487; this implementation measures 0.0475 (benchmarks/bench_tnh.py)
    assert e3d(result.x, stack_to_rows(seq.S), P) == pytest.approx(0.0475, abs=5e-4)


# ---------------------------------------------------------------------------------------------------------
# penalised TNH by proximal gradient (fista_tnh, the shape step of the camera/shape alternation)


def fista(W, R, mask=None, *, tau, X0=None, max_iter=5000, tol=1e-10):
    """fista_tnh on tracks as rows (F, 2P), from zeros or X0 (F, 3P)."""
    F, P = R.shape[0], W.shape[1] // 2
    vis = np.ones((F, P), dtype=bool) if mask is None else mask
    W3 = np.where(np.concatenate([vis, vis], axis=1), W, 0.0).reshape(F, 2, P)
    X = np.zeros((F, 3, P)) if X0 is None else X0.reshape(F, 3, P)
    nuclear = float(np.linalg.svd(X.reshape(F, 3 * P), compute_uv=False).sum())
    return fista_tnh(W3, visibility_weights(vis), R, X, nuclear, tau, max_iter, tol)


@pytest.mark.parametrize("tau", [0.1, 1.0, 10.0])
def test_proximal_tnh_meets_the_optimality_condition_and_matches_cvxpy(tau):
    """At the optimum -grad g(X) lies in tau * subdifferential of ||X||_*: with X = U S V^T,
    U^T (-grad) V = tau I and the part of -grad outside the row/column spaces has spectral norm <= tau."""
    X, W, R = synthetic_sequence(n_frames=12, n_points=9, rank=3, seed=21)
    F, P = X.shape[0], X.shape[1] // 3
    mask = random_visibility_mask(F, P, 0.3, random_state=21)
    noisy = W + 0.05 * np.random.default_rng(21).standard_normal(W.shape)
    res = fista(noisy, R, mask, tau=tau, tol=1e-14, max_iter=50_000)
    assert res.success and res.status == CONVERGED and res.method == "fista" and not res.exact_fit
    term = OrthographicReprojection(noisy, mask, R)
    assert res.fun == pytest.approx(penalised_objective(term, res.x, tau), rel=1e-12)
    assert res.max_abs_residual == pytest.approx(np.abs(term.residuals(res.x)).max(), rel=1e-12)
    minus_grad = -term.gradient(res.x)
    U, s, Vt = np.linalg.svd(res.x, full_matrices=False)
    k = int(np.sum(s > 1e-8 * s[0]))
    U, Vt = U[:, :k], Vt[:k]
    np.testing.assert_allclose(U.T @ minus_grad @ Vt.T, tau * np.eye(k), atol=1e-5 * max(tau, 1))
    outside = (
        minus_grad - U @ (U.T @ minus_grad) - (minus_grad @ Vt.T) @ Vt + U @ (U.T @ minus_grad @ Vt.T) @ Vt
    )
    assert np.linalg.norm(outside, 2) <= tau * (1 + 1e-5)
    reference = trace_norm_heuristic(noisy, mask, R, tau=tau, method="cvxpy", solver="CLARABEL")
    assert res.fun <= reference.fun * (1 + 1e-6)
    assert res.fun == pytest.approx(penalised_objective(term, reference.x, tau), rel=1e-5)


def test_proximal_tnh_warm_start_and_cap():
    X, W, R = synthetic_sequence(n_frames=8, n_points=6, rank=2, seed=22)
    cold = fista(W, R, tau=1.0, tol=1e-12)
    warm = fista(W, R, tau=1.0, X0=cold.x, tol=1e-12)
    assert warm.nit < cold.nit and warm.fun <= cold.fun * (1 + 1e-12)
    capped = fista(W, R, tau=1.0, tol=1e-12, max_iter=2)
    assert capped.status == MAX_ITER and not capped.success and capped.nit == 2
