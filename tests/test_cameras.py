"""Camera estimation for NRSfM: rigid factorisation and metric upgrade (nldr.nrsfm._factorization),
quaternions (nldr.nrsfm._rotations), camera LM and camera/shape alternation (nldr.nrsfm._camera_refinement)
and evaluation up to the global orthogonal gauge (nldr.nrsfm._metrics).

Tolerances. On noise-free data every estimate below is exact in exact arithmetic, so the bounds only have
to absorb rounding (eps ~ 2.2e-16 times modest condition numbers) or the solvers' own stopping
tolerances (1e-12); they are set orders of magnitude above those and far below any real error.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from conftest import alternate, project, random_rotation
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from nldr.datasets import load_mocap
from nldr.experiments._table4 import tune_tau
from nldr.nrsfm._camera_refinement import camera_lm, tnh_with_camera_refinement
from nldr.nrsfm._factorization import initialize_cameras, metric_upgrade, rigid_factorization
from nldr.nrsfm._layout import random_visibility_mask, stack_to_rows
from nldr.nrsfm._metrics import (
    camera_error,
    center_per_frame,
    e3d,
    global_camera_alignment,
    procrustes_rotation,
)
from nldr.nrsfm._reprojection import OrthographicReprojection, check_tracks, reprojection_error
from nldr.nrsfm._rotations import camera_to_quaternion, nearest_orthonormal_rows, quaternion_rotation
from nldr.result import CONVERGED

# ---------------------------------------------------------------------------------------------------------
# helpers


def random_orthogonal(rng, det: int) -> np.ndarray:
    """A random 3x3 orthogonal matrix with determinant ``det`` (+1 rotation, -1 rotation and reflection)."""
    return random_rotation(rng) @ np.diag([1.0, 1.0, float(det)])


def rigid_scene(n_frames=20, n_points=15, seed=0):
    """A centred rigid shape S (3, P), random rotation cameras R (F, 2, 3), tracks W (F, 2P), shapes X."""
    rng = np.random.default_rng(seed)
    # anisotropic extent (3 : 2 : 1), so that no direction is degenerate for the factorisation
    S = rng.standard_normal((3, n_points)) * np.array([[3.0], [2.0], [1.0]])
    S -= S.mean(axis=1, keepdims=True)
    R = np.stack([random_rotation(rng)[:2] for _ in range(n_frames)])
    X = np.broadcast_to(S.ravel(), (n_frames, 3 * n_points)).copy()
    return project(R, X), R, X, S


def deforming_scene(n_frames=20, n_points=15, rank=2, seed=0):
    """Low-rank deforming shapes (mean shape plus `rank` basis shapes), centred, random rotation cameras."""
    rng = np.random.default_rng(seed)
    basis = rng.standard_normal((rank + 1, 3 * n_points))
    coeffs = np.column_stack([np.ones(n_frames), 0.5 * rng.standard_normal((n_frames, rank))])
    X = center_per_frame(coeffs @ basis, n_points)
    R = np.stack([random_rotation(rng)[:2] for _ in range(n_frames)])
    return project(R, X), R, X


def perturb_cameras(R, degrees, rng) -> np.ndarray:
    """Right-multiply every camera by a rotation of exactly `degrees` about a random axis."""
    axes = rng.standard_normal((R.shape[0], 3))
    axes *= np.radians(degrees) / np.linalg.norm(axes, axis=1, keepdims=True)
    return R @ Rotation.from_rotvec(axes).as_matrix()


def complete(R) -> np.ndarray:
    """2x3 cameras with orthonormal rows -> 3x3 rotations (third row = cross product)."""
    return np.concatenate([R, np.cross(R[:, 0], R[:, 1])[:, None]], axis=1)


def hide(W, mask) -> np.ndarray:
    """NaN at the unobserved entries, so that any use of them would show."""
    return np.where(np.concatenate([mask, mask], axis=1), W, np.nan)


def quaternion_to_camera(q):
    """The orthographic cameras (F, 2, 3) of quaternions (F, 4): the first two rows of their rotations."""
    return quaternion_rotation(q)[0][:, :2]


def refine_cameras(W2d, mask, R0, X):
    """The camera LM from R0 with the shapes X fixed, on validated arrays (as the alternation calls it)."""
    W, mask = check_tracks(W2d, mask, min_points=0)
    F, P = mask.shape
    q, R, history, cost, nit, ok, _ = camera_lm(
        W.reshape(F, 2, P), mask, camera_to_quaternion(R0), X.reshape(F, 3, P)
    )
    return SimpleNamespace(
        R=R, q=q, cost_history=history, frame_cost=cost, nit=nit, success=ok, fun=history[-1]
    )


def rigid_shape_step(W2d, mask=None):
    """Shape step of a rigid model: given cameras, the one shape S (3, P) minimising the reprojection
    error (per point, the 3x3 normal equations sum_f mask_fj R_f^T R_f s_j = sum_f mask_fj R_f^T
    w_f(x_j), with a 1e-12 relative ridge), repeated for every frame. Alternated with the camera LM this
    is a rigid bundle adjustment."""
    W, mask = check_tracks(W2d, mask)
    F, P = mask.shape
    Wf3 = W.reshape(F, 2, P)

    def step(R):
        A = np.einsum("fp,fck,fcl->pkl", mask.astype(float), R, R)
        b = np.einsum("fck,fcp->pk", R, Wf3)
        A = A + 1e-12 * np.trace(A, axis1=1, axis2=2)[:, None, None] * np.eye(3)
        S = np.linalg.solve(A, b[..., None])[..., 0].T  # (3, P)
        return np.broadcast_to(S.ravel(), (F, 3 * P)).copy()

    return step


def row_gram_error(R) -> float:
    """max |R_f R_f^T - I_2| over the frames."""
    return float(np.abs(np.einsum("fck,fdk->fcd", R, R) - np.eye(2)).max())


# ---------------------------------------------------------------------------------------------------------
# rigid factorisation and camera initialisation


def test_rigid_factorization_full_data_is_exact():
    """Full noise-free rigid tracks: the truncated SVD factorises W = M S exactly (rank 3)."""
    W, _, _, _ = rigid_scene(seed=1)
    F, P = W.shape[0], W.shape[1] // 2
    fac = rigid_factorization(W)
    assert fac.M.shape == (F, 2, 3) and fac.x.shape == (3, P)
    assert (fac.nit, fac.status, fac.success) == (0, CONVERGED, True)
    assert fac.fun == pytest.approx(fac.rms**2 * W.size, rel=1e-9, abs=1e-26)
    np.testing.assert_allclose(np.einsum("fck,kp->fcp", fac.M, fac.x).reshape(F, 2 * P), W, atol=1e-12)
    assert fac.rms < 1e-13


def test_rigid_factorization_missing_data_completes_the_tracks():
    """30% missing: variable projection finds an exact rank-3 fit, which predicts the hidden entries."""
    W, _, _, _ = rigid_scene(seed=2)
    F, P = W.shape[0], W.shape[1] // 2
    mask = random_visibility_mask(F, P, 0.3, random_state=2)
    fac = rigid_factorization(hide(W, mask), mask)
    assert fac.success and fac.nit > 0 and fac.message.startswith("variable projection")
    assert fac.fun == pytest.approx(fac.rms**2 * 2 * mask.sum(), rel=1e-9)
    # noise-free and generic: the rank-3 completion is unique, so the unobserved entries are recovered too
    fitted = np.einsum("fck,kp->fcp", fac.M, fac.x).reshape(F, 2 * P)
    np.testing.assert_allclose(fitted, W, atol=1e-8 * np.abs(W).max())
    assert fac.rms < 1e-10 * np.abs(W).max()


@pytest.mark.parametrize("refine_metric", [True, False])
@pytest.mark.parametrize("missing", [0.0, 0.3])
def test_initialize_cameras_recovers_true_cameras_up_to_global_orthogonal(missing, refine_metric):
    """Noise-free rigid object: initialize_cameras = true cameras times ONE orthogonal Q (det +-1)."""
    W, R_true, _, _ = rigid_scene(seed=3)
    F, P = W.shape[0], W.shape[1] // 2
    mask = random_visibility_mask(F, P, missing, random_state=3)
    R = initialize_cameras(hide(W, mask), mask, refine_metric=refine_metric)
    assert R.shape == (F, 2, 3)
    assert row_gram_error(R) < 1e-10
    # Independent of the module's alignment: the stacked true cameras (2F, 3) have full column rank, so
    # R_est = R_true Q0 determines Q0 by least squares; it must be orthogonal and fit exactly.
    Q0 = np.linalg.lstsq(R_true.reshape(-1, 3), R.reshape(-1, 3), rcond=None)[0]
    np.testing.assert_allclose(Q0 @ Q0.T, np.eye(3), atol=1e-6)
    np.testing.assert_allclose(R_true @ Q0, R, atol=1e-6)
    # ... and with the module's alignment: R_est Q^T = R_true
    Q = global_camera_alignment(R, R_true)
    np.testing.assert_allclose(R @ Q.T, R_true, atol=1e-6)
    np.testing.assert_allclose(Q, Q0, atol=1e-6)
    assert camera_error(R, R_true) < 1e-6  # degrees


def test_initialize_cameras_on_deforming_shapes_gives_orthonormal_cameras():
    """Non-rigid tracks (rank 9): the rigid fit is only approximate, but the cameras stay orthographic."""
    W, R_true, _ = deforming_scene(seed=4)
    fac = rigid_factorization(W)
    assert fac.rms > 1e-3 * np.abs(W).max()  # the rank-3 model cannot fit a deforming shape exactly
    R = initialize_cameras(W)
    assert R.shape == R_true.shape and row_gram_error(R) < 1e-10


@pytest.mark.parametrize("missing", [False, True])
def test_initialize_cameras_repeats_bit_for_bit(missing):
    """Identical inputs give identical bits on every call, whatever the heap held before.

    Table 4's tuned numbers move by 1e-7 (TNH) to 1e-4 (kernel columns) for a one-ulp change of the
    start, so byte-identical tables need a bit-reproducible camera initialisation. With scipy's MINPACK
    ("lm", the previous solver) 26 of these 40 repeats differed from the first call on full data."""
    W, _, _ = deforming_scene(n_frames=30, n_points=20, seed=4)
    mask = random_visibility_mask(30, 20, 0.4, 1) if missing else None
    if missing:
        W = hide(W, mask)
    first = initialize_cameras(W, mask)
    rng = np.random.default_rng(0)
    for _ in range(40):
        junk = [np.full(n, rng.standard_normal()) for n in (9, 27, 90, 108, 216, 1000)]  # reused memory
        del junk
        assert np.array_equal(initialize_cameras(W, mask), first)


# ---------------------------------------------------------------------------------------------------------
# metric upgrade


@pytest.mark.parametrize("refine", [True, False])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_metric_upgrade_undoes_a_random_affine_ambiguity(seed, refine):
    """M = R_true G^-1 (G random, cond 25, either sign of det): M G_est has orthonormal rows and
    G^-1 G_est is orthogonal, i.e. only the global gauge is left."""
    rng = np.random.default_rng(seed)
    R_true = np.stack([random_rotation(rng)[:2] for _ in range(10)])
    U, V = random_orthogonal(rng, 1), random_orthogonal(rng, (-1) ** seed)
    G = U @ np.diag([0.2, 1.0, 5.0]) @ V
    M = R_true @ np.linalg.inv(G)
    G_est = metric_upgrade(M, refine=refine)
    assert G_est.shape == (3, 3)
    assert row_gram_error(M @ G_est) < 1e-8
    H = np.linalg.solve(G, G_est)
    np.testing.assert_allclose(H @ H.T, np.eye(3), atol=1e-8)


def test_two_views_do_not_determine_the_metric_upgrade():
    """Why >= 3 frames are needed: with two cameras (normals k1, k2), Q = I + t (k1 k2^T + k2 k1^T) meets
    all six constraints m^T Q m = 1, m_a^T Q m_b = 0 and is positive definite for small t."""
    rng = np.random.default_rng(5)
    R = np.stack([random_rotation(rng)[:2] for _ in range(2)])
    k1, k2 = np.cross(R[0, 0], R[0, 1]), np.cross(R[1, 0], R[1, 1])
    for t in (0.1, 0.3):
        Q = np.eye(3) + t * (np.outer(k1, k2) + np.outer(k2, k1))
        assert np.linalg.eigvalsh(Q).min() > 0
        np.testing.assert_allclose(
            np.einsum("fck,kl,fdl->fcd", R, Q, R), np.broadcast_to(np.eye(2), (2, 2, 2)), atol=1e-14
        )
        # G = I and G = chol(Q) both make the cameras R G orthographic, yet G is not orthogonal
        G = np.linalg.cholesky(Q)
        assert row_gram_error(R @ G) < 1e-12
        assert np.abs(G @ G.T - np.eye(3)).max() > 0.05


@pytest.mark.parametrize("refine", [True, False])
def test_metric_upgrade_rejects_fewer_than_three_frames(refine):
    """Two frames do not determine G: a ValueError naming M is expected."""
    rng = np.random.default_rng(3)
    R_true = np.stack([random_rotation(rng)[:2] for _ in range(2)])
    M = R_true @ np.linalg.inv(rng.standard_normal((3, 3)))
    with pytest.raises(ValueError, match=r"^M\b"):
        metric_upgrade(M, refine=refine)


@pytest.mark.parametrize("n_frames", [1, 2])
def test_initialize_cameras_rejects_fewer_than_three_frames(n_frames):
    """Fewer than 3 frames cannot give metric cameras: a ValueError naming W2d is expected."""
    W, _, _, _ = rigid_scene(n_frames=n_frames, seed=6)
    with pytest.raises(ValueError, match="W2d"):
        initialize_cameras(W)


# ---------------------------------------------------------------------------------------------------------
# nearest matrix with orthonormal rows


def test_nearest_orthonormal_rows_is_the_polar_factor():
    """R = U V^T = (A A^T)^(-1/2) A with ||A - R||^2 = sum (s_i - 1)^2; idempotent and equivariant."""
    rng = np.random.default_rng(7)
    A = rng.standard_normal((30, 2, 3))
    R = nearest_orthonormal_rows(A)
    assert R.shape == A.shape and row_gram_error(R) < 1e-13
    U, s, Vt = np.linalg.svd(A, full_matrices=False)
    np.testing.assert_allclose(R, U @ Vt, atol=1e-12)
    lam, E = np.linalg.eigh(np.einsum("fck,fdk->fcd", A, A))
    inv_sqrt = np.einsum("fij,fj,fkj->fik", E, 1 / np.sqrt(lam), E)
    np.testing.assert_allclose(R, inv_sqrt @ A, atol=1e-10)
    np.testing.assert_allclose(np.sum((A - R) ** 2, axis=(1, 2)), np.sum((s - 1) ** 2, axis=1), atol=1e-12)
    np.testing.assert_allclose(nearest_orthonormal_rows(R), R, atol=1e-13)
    c, sn = np.cos(0.7), np.sin(0.7)
    L, Rt = np.array([[c, -sn], [sn, c]]) @ np.diag([1.0, -1.0]), random_orthogonal(rng, -1)  # orthogonal
    np.testing.assert_allclose(nearest_orthonormal_rows(L @ A @ Rt), L @ R @ Rt, atol=1e-12)


def test_nearest_orthonormal_rows_beats_brute_force():
    """No random matrix with orthonormal rows, and no small rotation of the answer, is closer to A."""
    rng = np.random.default_rng(8)
    A = rng.standard_normal((5, 2, 3))
    R = nearest_orthonormal_rows(A)
    best = np.sum((A - R) ** 2, axis=(1, 2))
    # every 2x3 matrix with orthonormal rows is the top of some orthogonal 3x3 matrix
    candidates = np.stack([random_orthogonal(rng, 1)[:2] for _ in range(3000)])
    dist = np.sum((A[:, None] - candidates[None]) ** 2, axis=(2, 3))  # (5, 3000)
    assert np.all(dist >= best[:, None] - 1e-12)
    local = R[:, None] @ Rotation.from_rotvec(1e-3 * rng.standard_normal((200, 3))).as_matrix()[None]
    assert np.all(np.sum((A[:, None] - local) ** 2, axis=(2, 3)) >= best[:, None] - 1e-12)


# ---------------------------------------------------------------------------------------------------------
# quaternions


def test_quaternion_rotation_matches_scipy_and_is_scale_invariant():
    """Any non-zero q gives the rotation of q / |q| (scalar first); J q = 0 (A is homogeneous of degree 0
    in q). Its Jacobian against central differences: tests/test_joint_kernel.py."""
    rng = np.random.default_rng(9)
    q = rng.standard_normal((40, 4)) * rng.uniform(0.5, 2.0, (40, 1))
    A, J = quaternion_rotation(q, jacobian=True)
    assert A.shape == (40, 3, 3) and row_gram_error(A[:, :2]) < 1e-13
    np.testing.assert_allclose(A, Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix(), atol=1e-13)
    np.testing.assert_allclose(quaternion_rotation(-3.0 * q)[0], A, atol=1e-13)
    assert np.abs(np.einsum("fcki,fi->fck", J, q)).max() < 1e-13


def test_camera_to_quaternion_inverts_quaternion_to_camera():
    """camera_to_quaternion(quaternion_to_camera(q)) = +-q/|q| (unit, w >= 0): generic rotations, the
    identity, half-turns about each axis and near-half-turns."""
    rng = np.random.default_rng(11)
    rotvecs = [np.zeros(3), *(np.pi * np.eye(3)), *((np.pi - 1e-9) * np.eye(3))]
    axes = rng.standard_normal((6, 3))
    rotvecs += list((np.pi - 1e-7) * axes / np.linalg.norm(axes, axis=1, keepdims=True))
    q_special = Rotation.from_rotvec(np.array(rotvecs)).as_quat()[:, [3, 0, 1, 2]]
    q = np.vstack([rng.standard_normal((40, 4)), q_special])
    q_unit = q / np.linalg.norm(q, axis=1, keepdims=True)
    q_back = camera_to_quaternion(quaternion_to_camera(q))
    assert q_back.shape == q.shape
    np.testing.assert_allclose(np.linalg.norm(q_back, axis=1), 1.0, atol=1e-13)
    assert np.all(q_back[:, 0] >= 0)
    sign = np.sign(np.sum(q_back * q_unit, axis=1))
    np.testing.assert_allclose(q_back, sign[:, None] * q_unit, atol=1e-12)


def test_camera_to_quaternion_projects_non_orthonormal_cameras():
    """For any 2x3 A, quaternion_to_camera(camera_to_quaternion(A)) is the nearest orthonormal-row matrix."""
    rng = np.random.default_rng(12)
    A = rng.standard_normal((20, 2, 3))
    np.testing.assert_allclose(
        quaternion_to_camera(camera_to_quaternion(A)), nearest_orthonormal_rows(A), atol=1e-12
    )


def test_camera_to_quaternion_error_names_its_argument():
    """A malformed camera array raises a ValueError naming R."""
    with pytest.raises(ValueError, match=r"^R\b"):
        camera_to_quaternion(np.zeros((3, 3)))


# ---------------------------------------------------------------------------------------------------------
# reprojection error and camera refinement (shapes fixed)


def test_reprojection_error_matches_the_orthographic_data_term():
    """reprojection_error equals OrthographicReprojection.value (masked sum of squares), NaN-safe."""
    W, R, X = deforming_scene(seed=13)
    F, P = W.shape[0], W.shape[1] // 2
    rng = np.random.default_rng(13)
    mask = random_visibility_mask(F, P, 0.3, random_state=13)
    X_noisy = X + rng.standard_normal(X.shape)
    expected = OrthographicReprojection(W, mask, R).value(X_noisy)
    assert reprojection_error(hide(W, mask), mask, R, X_noisy) == pytest.approx(expected, rel=1e-12)
    assert reprojection_error(W, None, R, X) < 1e-24 * np.sum(W**2)


@pytest.mark.parametrize(("degrees", "missing"), [(5.0, 0.0), (30.0, 0.0), (60.0, 0.3)])
def test_refine_cameras_returns_to_the_truth_with_true_shapes(degrees, missing):
    """Perturbed true cameras, true (deforming) shapes fixed, noise-free tracks: the LM drives the error
    to rounding level and the cameras back to the truth; its cost never increases."""
    W, R_true, X = deforming_scene(seed=14)
    F, P = W.shape[0], W.shape[1] // 2
    rng = np.random.default_rng(14)
    mask = random_visibility_mask(F, P, missing, random_state=14)
    R0 = perturb_cameras(R_true, degrees, rng)
    res = refine_cameras(hide(W, mask), mask, R0, X)
    h = res.cost_history
    assert h[0] == pytest.approx(reprojection_error(W, mask, R0, X), rel=1e-12)
    # the batched LM only accepts decreasing frames and float addition is monotone: exactly non-increasing
    assert np.all(np.diff(h) <= 0) and h.size == res.nit + 1
    assert res.success and res.fun == h[-1] == pytest.approx(res.frame_cost.sum(), rel=1e-12)
    # zero-residual problem: Gauss-Newton converges quadratically, down to rounding (~eps^2 ||W||^2)
    assert res.fun <= 1e-20 * np.sum(W**2)
    # ||(R_f - R_true,f) S_f,obs||_F >= sigma_min(S_f,obs) ||R_f - R_true,f||_F, frame by frame
    S = X.reshape(F, 3, P)
    for f in range(F):
        sigma_min = np.linalg.svd(S[f][:, mask[f]], compute_uv=False)[-1]
        assert np.linalg.norm(res.R[f] - R_true[f]) <= np.sqrt(res.frame_cost[f]) / sigma_min + 1e-12
    np.testing.assert_allclose(res.R, R_true, atol=1e-9)
    assert row_gram_error(res.R) < 1e-13
    np.testing.assert_allclose(quaternion_to_camera(res.q), res.R, atol=1e-13)


def test_refine_cameras_on_noisy_tracks_matches_an_independent_solver():
    """Noisy, 30% missing: the cost decreases monotonically to the per-frame minimum found by scipy's
    least_squares on a rotation-vector parametrisation from the same start."""
    W, R_true, X = deforming_scene(seed=15)
    F, P = W.shape[0], W.shape[1] // 2
    rng = np.random.default_rng(15)
    mask = random_visibility_mask(F, P, 0.3, random_state=15)
    W_noisy = W + 0.05 * rng.standard_normal(W.shape)
    R0 = perturb_cameras(R_true, 20.0, rng)
    res = refine_cameras(hide(W_noisy, mask), mask, R0, X)
    assert np.all(np.diff(res.cost_history) <= 0) and res.fun < res.cost_history[0]
    S, Wf = X.reshape(F, 3, P), W_noisy.reshape(F, 2, P)
    for f in range(F):
        obs = mask[f]

        def residuals(v, f=f, obs=obs):
            return (Wf[f][:, obs] - Rotation.from_rotvec(v).as_matrix()[:2] @ S[f][:, obs]).ravel()

        v0 = Rotation.from_matrix(complete(R0[f : f + 1])[0]).as_rotvec()
        ref = least_squares(residuals, v0, xtol=1e-15, ftol=1e-15, gtol=1e-15)
        # both are minima of a smooth cost: equal costs to well within the solvers' tolerances
        assert res.frame_cost[f] == pytest.approx(2 * ref.cost, rel=1e-8, abs=1e-14)


def test_refine_cameras_keeps_the_camera_of_an_unobserved_frame():
    """A frame without observations has a constant cost: its camera stays the (orthonormalised) start."""
    W, R_true, X = deforming_scene(seed=16)
    F, P = W.shape[0], W.shape[1] // 2
    mask = np.ones((F, P), dtype=bool)
    mask[3] = False
    R0 = perturb_cameras(R_true, 10.0, np.random.default_rng(16)) * 1.1  # not orthonormal
    res = refine_cameras(hide(W, mask), mask, R0, X)
    assert np.all(np.isfinite(res.R))
    np.testing.assert_allclose(res.R[3], nearest_orthonormal_rows(R0)[3], atol=1e-12)
    others = np.arange(F) != 3
    np.testing.assert_allclose(res.R[others], R_true[others], atol=1e-9)


# ---------------------------------------------------------------------------------------------------------
# alternation of shapes and cameras


def test_rigid_shape_step_is_the_least_squares_rigid_shape():
    """Given cameras, the step returns, in every frame, the S minimising the masked reprojection error."""
    W, R_true, X, _ = rigid_scene(seed=17)
    F, P = W.shape[0], W.shape[1] // 2
    rng = np.random.default_rng(17)
    mask = random_visibility_mask(F, P, 0.3, random_state=17)
    np.testing.assert_allclose(rigid_shape_step(hide(W, mask), mask)(R_true), X, atol=1e-9)
    W_noisy = W + 0.1 * rng.standard_normal(W.shape)
    R = perturb_cameras(R_true, 10.0, rng)
    X_step = rigid_shape_step(hide(W_noisy, mask), mask)(R)
    assert X_step.shape == (F, 3 * P) and np.all(X_step == X_step[0])
    Wf = W_noisy.reshape(F, 2, P)
    for j in range(P):  # brute force: per point, the stacked 2F' x 3 least-squares problem
        seen = mask[:, j]
        s_j = np.linalg.lstsq(R[seen].reshape(-1, 3), Wf[seen, :, j].ravel(), rcond=None)[0]
        np.testing.assert_allclose(X_step[0].reshape(3, P)[:, j], s_j, atol=1e-9)


@pytest.mark.parametrize("missing", [0.0, 0.3])
def test_rigid_bundle_adjustment_reaches_zero_error_monotonically(missing):
    """Rigid object, cameras perturbed by 10 degrees: shape step / camera LM alternation decreases the
    reprojection error at every half-step (within rounding), to ~0, and recovers the cameras (up to gauge)."""
    W, R_true, _, _ = rigid_scene(seed=18)
    F, P = W.shape[0], W.shape[1] // 2
    mask = random_visibility_mask(F, P, missing, random_state=18)
    R0 = perturb_cameras(R_true, 10.0, np.random.default_rng(18))
    Wh = hide(W, mask)
    res = alternate(Wh, mask, R0, rigid_shape_step(Wh, mask), max_outer=300, tol=1e-12)
    assert res.nit == res.history.size == res.shape_history.size
    # e(R_{k-1}, X_k) <= e(R_{k-1}, X_{k-1}) (the shape step is a least-squares solve, up to its 1e-12
    # relative ridge) and e(R_k, X_k) <= e(R_{k-1}, X_k) (the LM only accepts decreases); the slack is
    # a few hundred ulps of the cost's scale ||W||^2
    interleaved = np.column_stack([res.shape_history, res.history]).ravel()
    scale = np.sum(W**2)
    assert np.all(np.diff(interleaved) <= 1e-13 * scale)
    assert res.shape_history[0] == pytest.approx(
        reprojection_error(W, mask, nearest_orthonormal_rows(R0), rigid_shape_step(W, mask)(R0)), rel=1e-12
    )
    # noise-free rigid data: the global minimum is 0; the ridge of the shape step (relative 1e-12) leaves
    # a floor ~(1e-12 cond)^2 ||W||^2, far below this bound
    assert res.history[-1] <= 1e-14 * scale
    assert reprojection_error(W, mask, res.R, res.x) == pytest.approx(res.history[-1], rel=1e-9, abs=1e-25)
    assert camera_error(res.R, R_true) < 1e-6  # degrees


# ---------------------------------------------------------------------------------------------------------
# evaluation up to the global gauge


@pytest.mark.parametrize("det", [1, -1])
def test_global_alignment_of_shapes_undoes_a_global_rotation_or_reflection(det):
    """e3d(..., align=True) of Q G + translations against G is zero: the Procrustes rotation of the
    centred shapes gives back Q^T (with a reflection only when allowed)."""
    _, _, X = deforming_scene(seed=20)
    F, P = X.shape[0], X.shape[1] // 3
    rng = np.random.default_rng(20 + det)
    Q = random_orthogonal(rng, det)
    shift = rng.standard_normal((F, 3, 1))
    moved = (np.einsum("kl,flp->fkp", Q, X.reshape(F, 3, P)) + shift).reshape(F, 3 * P)
    centred, truth = center_per_frame(moved, P), center_per_frame(X, P)
    np.testing.assert_allclose(procrustes_rotation(centred, truth, P), Q.T, atol=1e-10)
    assert e3d(moved, X, P, align=True) < 1e-10
    assert e3d(moved, X, P) > 0.1  # without the alignment the rotation counts as error
    if det == -1:  # a reflection cannot be undone by a rotation
        assert np.linalg.det(procrustes_rotation(centred, truth, P, allow_reflection=False)) > 0


@pytest.mark.parametrize("det", [1, -1])
def test_global_camera_alignment_and_camera_error(det):
    """R_est = R_true Q0 gives back Q0 and a zero error; a known per-frame rotation gives its angle,
    on both branches of the angle formula (chord for small angles, arccos for large)."""
    _, R_true, _, _ = rigid_scene(seed=21)
    rng = np.random.default_rng(21 + det)
    Q0 = random_orthogonal(rng, det)
    R_est = R_true @ Q0
    Q = global_camera_alignment(R_est, R_true)
    np.testing.assert_allclose(Q, Q0, atol=1e-12)
    assert camera_error(R_est, R_true) < 1e-10 and camera_error(R_est, R_true, degrees=False) < 1e-12
    Q_rot = global_camera_alignment(R_est, R_true, allow_reflection=False)
    assert np.linalg.det(Q_rot) == pytest.approx(1.0)
    for angle in (1e-7, 0.3, 2.5):
        axes = rng.standard_normal((R_true.shape[0], 3))
        turned = (
            R_true
            @ Rotation.from_rotvec(angle * axes / np.linalg.norm(axes, axis=1, keepdims=True)).as_matrix()
        )
        err = camera_error(turned, R_true, Q=np.eye(3), degrees=False)
        assert err == pytest.approx(angle, rel=1e-8)
    with pytest.raises(ValueError, match=r"^Q\b"):
        camera_error(R_est, R_true, Q=2 * np.eye(3))


# ---------------------------------------------------------------------------------------------------------
# input validation


def _bad_input_cases():
    W, R, X, _ = rigid_scene(n_frames=6, n_points=8, seed=22)
    F, P = 6, 8
    W_nan = W.copy()
    W_nan[2, 3] = np.nan
    few = np.ones((F, P), dtype=bool)
    few[4, 2:] = False  # frame 4 keeps 2 points
    sparse = np.zeros((3, 10), dtype=bool)
    sparse[:, :4] = True  # 3 frames x 4 points: 24 coordinates < 3P = 30 unknowns
    W_sparse = rigid_scene(n_frames=3, n_points=10, seed=22)[0]

    def alternation(W2d=W, mask=None, R0=R, **options):
        return tnh_with_camera_refinement(W2d, mask, R0, 1.0, **options)

    cases = [
        ("odd columns", lambda: initialize_cameras(W[:, :-1]), "W2d"),
        ("odd columns alternation", lambda: alternation(W[:, :-1]), "W2d"),
        ("NaN observed", lambda: initialize_cameras(W_nan), "W2d"),
        ("NaN observed alternation", lambda: alternation(W_nan), "W2d"),
        ("not numeric", lambda: initialize_cameras("tracks"), "W2d"),
        ("mask shape", lambda: initialize_cameras(W, few[:, :-1]), "mask"),
        ("< 3 points init", lambda: initialize_cameras(W, few), "mask"),
        ("< 3 points alternation", lambda: alternation(mask=few), "mask"),
        ("too few observations", lambda: rigid_factorization(W_sparse, sparse), "mask"),
        ("R0 not 2x3", lambda: alternation(R0=R[:, :, :2]), "R0"),
        ("R0 frame count", lambda: alternation(R0=R[:-1]), "R0"),
        ("R0 stacked", lambda: alternation(R0=R.reshape(-1, 3)), "R0"),
        ("M shape", lambda: metric_upgrade(np.zeros((4, 3, 3))), "M"),
        ("A shape", lambda: nearest_orthonormal_rows(np.zeros((2, 3))), "A"),
    ]
    for v in (0, -1, 2.5, True, None):
        cases.append((f"max_outer={v!r}", lambda v=v: alternation(max_outer=v), "max_outer"))
    return [pytest.param(call, name, id=label) for label, call, name in cases]


@pytest.mark.parametrize(("call", "name"), _bad_input_cases())
def test_bad_input_raises_value_error_naming_the_argument(call, name):
    """Malformed input raises a ValueError whose message starts with the offending argument's name."""
    with pytest.raises(ValueError, match=rf"^{name}\b"):
        call()


def test_nan_at_unobserved_entries_is_ignored():
    """NaN where the mask is False does not leak into any result (cameras compared up to the gauge, which
    the missing-data factorisation fixes only up to rounding: it is not bitwise reproducible)."""
    W, R_true, X, _ = rigid_scene(seed=23)
    F, P = W.shape[0], W.shape[1] // 2
    mask = random_visibility_mask(F, P, 0.3, random_state=23)
    Wh = hide(W, mask)
    W0 = np.where(np.concatenate([mask, mask], axis=1), W, 0.0)
    R_nan = initialize_cameras(Wh, mask)
    assert np.all(np.isfinite(R_nan)) and camera_error(R_nan, R_true) < 1e-6
    np.testing.assert_allclose(
        rigid_shape_step(Wh, mask)(R_true), rigid_shape_step(W0, mask)(R_true), atol=1e-12
    )
    assert reprojection_error(Wh, mask, R_true, X) == reprojection_error(W0, mask, R_true, X)
    res = refine_cameras(Wh, mask, perturb_cameras(R_true, 10.0, np.random.default_rng(23)), X)
    assert np.all(np.isfinite(res.cost_history)) and res.fun <= 1e-20 * np.sum(W**2)


# ---------------------------------------------------------------------------------------------------------
# real data (CMU mocap, Akhter et al.)


@pytest.mark.realdata
def test_real_data_pickup_camera_initialisation_and_rigid_refinement(data_dir):
    """pickup, every 10th frame: rigid-factorisation cameras are far better than chance, and the rigid
    bundle adjustment from them never increases the reprojection error."""
    seq = load_mocap("pickup", data_dir).subsample(10)
    F, P = seq.n_frames, seq.n_points
    assert (F, P) == (36, 41)
    W = stack_to_rows(seq.W, 2)
    R0 = initialize_cameras(W)
    assert row_gram_error(R0) < 1e-10
    # Measured: 27.39 degrees mean camera error (global alignment with reflection). pickup deforms a lot
    # (the centred shapes differ from their mean by ~25% in Frobenius norm), so the rank-3 model absorbs
    # part of the body motion into the cameras and rigid factorisation is only approximate. Bound at 2x
    # the measured value; for reference, random cameras score ~105-115 degrees and one fixed camera 90.
    error = camera_error(R0, seq.R)
    assert error < 55.0
    # Only the reprojection error is asserted below: the rigid bundle adjustment fits the tracks better
    # but moves these cameras further from the truth (measured 32.7 degrees after it).
    step = rigid_shape_step(W)
    res = alternate(W, None, R0, step)
    start = reprojection_error(W, None, R0, step(R0))  # measured 214.4 (track unit squared)
    assert res.shape_history[0] == pytest.approx(start, rel=1e-12)
    interleaved = np.column_stack([res.shape_history, res.history]).ravel()
    assert np.all(np.diff(interleaved) <= 1e-13 * np.sum(W**2))
    assert res.history[-1] <= start  # measured 132.7
    assert reprojection_error(W, None, res.R, res.x) == pytest.approx(res.history[-1], rel=1e-9)


# ---------------------------------------------------------------------------------------------------------
# TNH with estimated cameras and the tau search (Table 4)


def test_tnh_with_camera_refinement_descends_and_converges():
    """The joint energy never increases (each half-step minimises it over one block), the run stops
    by its windowed test, and the cameras end closer to the truth than they started."""
    W, R_true, X = deforming_scene(seed=31)
    R0 = perturb_cameras(R_true, 10.0, np.random.default_rng(31))
    res = tnh_with_camera_refinement(W, None, R0, tau=0.5, max_outer=3000, tol=1e-9, window=5)
    energy = res.energy_history
    assert res.success and "over 5 iteration" in res.message and res.fun == energy[-1]
    assert np.all(np.diff(energy) <= 1e-9 * energy[0])
    assert camera_error(res.R, R_true) < camera_error(R0, R_true)


@pytest.mark.parametrize("minimum", [-0.7, 0.3, 1.6])
def test_tune_tau_finds_the_minimum_of_a_smooth_function_of_log_tau(minimum):
    res = tune_tau(lambda tau: (np.log10(tau) - minimum) ** 2 + 1.0, log10_bounds=(-1, 2), xatol=1e-3)
    assert abs(np.log10(res.tau) - minimum) < 2e-3 and res.fun == pytest.approx(1.0, abs=1e-5)
    assert res.x == res.tau and res.success and 0 < res.nit <= res.nfev
    assert res.nfev == len(res.history) and min(v for _, v in res.history) == res.fun


def test_tune_tau_validates():
    with pytest.raises(ValueError, match="log10_bounds"):
        tune_tau(lambda t: t, log10_bounds=(2, 1))
    with pytest.raises(ValueError, match="finite"):
        tune_tau(lambda t: np.nan)


# ---------------------------------------------------------------------------------------------------------
# one result convention


def test_every_nrsfm_solver_result_is_a_solver_result():
    """x, fun, status, message, nit and wall_time everywhere; success means status CONVERGED; the repr
    is one line."""
    from nldr.nrsfm._reconstruct import trace_norm_heuristic
    from nldr.nrsfm._tnh import fista_tnh
    from nldr.result import STATUS_NAMES, SolverResult

    W, R_true, X = deforming_scene(n_frames=8, n_points=9, seed=41)
    F, P = X.shape[0], X.shape[1] // 3
    R0 = perturb_cameras(R_true, 5.0, np.random.default_rng(41))
    W3 = W.reshape(F, 2, P)
    results = [
        trace_norm_heuristic(W, None, R_true),
        fista_tnh(W3, None, R_true, np.zeros((F, 3, P)), 0.0, 1.0, 50, 1e-10),
        rigid_factorization(W),
        tnh_with_camera_refinement(W, None, R0, 1.0, max_outer=3),
        tune_tau(lambda tau: (np.log10(tau) - 0.5) ** 2, xatol=0.1),
    ]
    for res in results:
        assert isinstance(res, SolverResult)
        assert res.success == (res.status == CONVERGED) and res.status in STATUS_NAMES
        assert isinstance(res.nit, int) and res.nit >= 0 and res.wall_time >= 0
        assert np.isfinite(res.fun) and res.message
        text = repr(res)
        assert "\n" not in text and text.startswith(type(res).__name__) and f"nit={res.nit}" in text
