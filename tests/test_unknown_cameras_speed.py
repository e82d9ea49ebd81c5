"""The fast TNH-with-estimated-cameras (Table 4) keeps the results of the first implementation.

Three changes make :func:`~nldr.nrsfm._camera_refinement.tnh_with_camera_refinement` faster, each checked
here against the slow-but-plain path it replaces:

1. Singular value thresholding through the Gram matrix of the short side
   (:func:`~nldr.nrsfm._tnh.soft_threshold_singular_values_gram`) instead of a full SVD
   (:func:`~nldr.nrsfm._tnh.soft_threshold_singular_values`).
2. The camera LM's normal equations from 3x3 and 3x2 summaries of each frame
   (:func:`~nldr.nrsfm._camera_refinement.lm_normal_equations`) instead of the explicit Jacobian.
3. The shape step's FISTA tolerance follows the alternation's progress (loose while the joint energy
   falls fast, the former 1e-12 near convergence) instead of 1e-12 throughout
   (:func:`~nldr.reference.nrsfm.tnh_with_camera_refinement_reference`).

Tolerances. (1) and (2) are the same quantities computed differently: they agree to rounding,
a small multiple of eps times the size of the data. (3) changes the path of the alternation, not its
fixed point; both runs stop by the same test (relative decrease of the joint energy below tol = 1e-8
over a window of outer iterations), which leaves each at some distance from the fixed point. That
distance is measured, not guessed: the reference is run again with tol = 1e-13 ("tight", about twice
as many outer iterations), and the distance of the default-tolerance reference to it bounds how far a
run stopped by the default test may be from the fixed point. The fast run must lie within a few times
that distance of the reference (triangle inequality: both are within about that distance of the fixed
point). The joint energy is invariant under a global rotation Q of the shapes (cameras R Q^T), and the
two paths may end at slightly different rotations (0.03 degrees on pickup), so shapes and cameras are
compared after one global rotation, the gauge of every NRSfM evaluation (:mod:`nldr.nrsfm._metrics`).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_rotation

import nldr.nrsfm._camera_refinement as cr
from nldr.nrsfm._camera_refinement import lm_normal_equations, tnh_alternation, tnh_with_camera_refinement
from nldr.nrsfm._factorization import initialize_cameras
from nldr.nrsfm._metrics import center_per_frame, e3d, procrustes_rotation
from nldr.nrsfm._rotations import quaternion_rotation
from nldr.nrsfm._tnh import (
    GRAM_SAFETY,
    fista_tnh,
    soft_threshold_singular_values,
    soft_threshold_singular_values_gram,
)
from nldr.reference.nrsfm import tnh_with_camera_refinement_reference

EPS = np.finfo(float).eps


def scene(n_frames=10, n_points=12, rank=2, missing=0.2, noise=0.02, seed=0):
    """Low-rank deforming shapes, random rotation cameras, noisy tracks (F, 2P) and a visibility mask
    with 4 points always seen (so that every frame keeps >= 3 observed points)."""
    rng = np.random.default_rng(seed)
    basis = rng.standard_normal((rank + 1, 3 * n_points))
    coeffs = np.column_stack([np.ones(n_frames), 0.5 * rng.standard_normal((n_frames, rank))])
    X = center_per_frame(coeffs @ basis, n_points)
    R = np.stack([random_rotation(rng)[:2] for _ in range(n_frames)])
    W = np.einsum("fck,fkp->fcp", R, X.reshape(n_frames, 3, n_points)).reshape(n_frames, 2 * n_points)
    W = W + noise * rng.standard_normal(W.shape)
    mask = rng.random((n_frames, n_points)) > missing
    mask[:, :4] = True
    return W, mask, R, X


def matrix_with_singular_values(s, shape, rng):
    m, n = shape
    U = np.linalg.qr(rng.standard_normal((m, len(s))))[0]
    V = np.linalg.qr(rng.standard_normal((n, len(s))))[0]
    return (U * s) @ V.T


# ---------------------------------------------------------------------------------------------------------
# 1. thresholding through the Gram matrix


@pytest.mark.parametrize("shape", [(36, 123), (123, 36), (20, 20)])
def test_gram_thresholding_matches_the_full_svd(shape, rng):
    """Singular values from 80 down to 1e-4 (the scale of pickup's shapes), several within 1e-3 of the
    threshold on both sides and a near-degenerate pair straddling it: the thresholded matrix and its
    nuclear norm agree with the SVD's to rounding. Bound: n eps s_max for the products (as an SVD),
    plus, for components closer to the threshold t than the eigenvalues' error n eps s_max^2 / t, which
    the Gram matrix cannot separate, their whole contribution (s - t)_+ <= n eps s_max^2 / t."""
    t = 0.05
    k = min(shape)
    s = np.sort(
        np.concatenate([[80.0, 12.0, 9.0, 1.5], rng.uniform(0.2, 1.0, 4), rng.uniform(1e-4, 0.04, k - 14)])
    )
    s = np.concatenate([s, t + np.array([-1e-3, -1e-6, -1e-9, 1e-9, 1e-6, 1e-3])])[::-1]
    Y = matrix_with_singular_values(s, shape, rng)
    X_ref, nuc_ref = soft_threshold_singular_values(Y, t)
    X, nuc = soft_threshold_singular_values_gram(Y, t)
    bound = 100 * max(shape) * EPS * s.max() + 4 * min(shape) * EPS * s.max() ** 2 / t
    assert np.abs(X - X_ref).max() <= bound
    assert nuc == pytest.approx(nuc_ref, abs=bound)
    assert nuc == pytest.approx(np.sum(np.maximum(s - t, 0)), abs=bound)


def test_gram_thresholding_falls_back_to_the_svd_when_the_threshold_is_tiny(rng):
    """Eigenvalue errors (n eps s_max^2) above GRAM_SAFETY t^2: the SVD path, bit for bit."""
    Y = matrix_with_singular_values(np.logspace(2, -8, 30), (30, 60), rng)
    t = 1e-6
    assert 30 * EPS * 1e4 > GRAM_SAFETY * t * t
    X, nuc = soft_threshold_singular_values_gram(Y, t)
    X_ref, nuc_ref = soft_threshold_singular_values(Y, t)
    np.testing.assert_array_equal(X, X_ref)
    assert nuc == nuc_ref
    # and a threshold above every singular value gives zero
    X, nuc = soft_threshold_singular_values_gram(Y, 200.0)
    assert nuc == 0.0 and not X.any()


def test_fista_with_gram_thresholding_follows_the_svd_iterates():
    """The same FISTA run with either thresholding: same iteration count, shapes equal to 1e-9."""
    W, mask, R, _ = scene(seed=3)
    F, P = mask.shape
    W3 = np.where(np.concatenate([mask, mask], axis=1), W, 0.0).reshape(F, 2, P)
    m3 = mask[:, None, :].astype(float)
    start = np.zeros((F, 3, P))
    fast = fista_tnh(W3, m3, R, start, 0.0, 0.3, 400, 1e-10, soft_threshold_singular_values_gram)
    slow = fista_tnh(W3, m3, R, start, 0.0, 0.3, 400, 1e-10, soft_threshold_singular_values)
    # the two thresholdings agree to rounding, so the stop test (relative decrease < tol) can fall on
    # either side of tol on the one iteration where the decrease crosses it: one iteration either way
    assert fast.success and abs(fast.nit - slow.nit) <= 1
    assert np.abs(fast.x - slow.x).max() <= 1e-9 * np.abs(slow.x).max()
    assert fast.nuclear_norm == pytest.approx(slow.nuclear_norm, rel=1e-12)
    assert fast.fun == 0.3 * fast.nuclear_norm + fast.reprojection_error


# ---------------------------------------------------------------------------------------------------------
# 2. the camera LM's normal equations


def test_lm_normal_equations_match_the_explicit_jacobian(rng):
    """J^T J and -J^T r from the 3x3 / 3x2 summaries equal the sums over the explicit (2, P, 4) Jacobian."""
    F, P = 7, 11
    q = rng.standard_normal((F, 4))
    J = quaternion_rotation(q / np.linalg.norm(q, axis=1, keepdims=True), jacobian=True)[1][:, :2]
    S = rng.standard_normal((F, 3, P))
    mask = rng.random((F, P)) > 0.3
    E = rng.standard_normal((F, 2, P)) * mask[:, None, :]
    D = np.einsum("fcki,fkp->fcpi", J, S) * mask[:, None, :, None]
    C = (S * mask[:, None, :]) @ S.transpose(0, 2, 1)
    C2 = np.zeros((F, 6, 6))
    C2[:, :3, :3] = C2[:, 3:, 3:] = C
    JtJ, g = lm_normal_equations(J, C2, S @ E.transpose(0, 2, 1))
    scale = np.abs(J).max() ** 2 * np.abs(S).max() ** 2 * P
    np.testing.assert_allclose(JtJ, np.einsum("fcpi,fcpj->fij", D, D), rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(g, np.einsum("fcpi,fcp->fi", D, E), rtol=0, atol=1e-13 * scale)


# ---------------------------------------------------------------------------------------------------------
# 3. the alternation: same fixed point, fewer FISTA iterations


def aligned_distance(a, b, P):
    """Relative shape distance and max camera difference of run a to run b after the global rotation
    Q (det +1) that best maps a's shapes onto b's."""
    F = a.x.shape[0]
    Q = procrustes_rotation(a.x, b.x, P, allow_reflection=False)
    Xa = np.einsum("kl,flp->fkp", Q, a.x.reshape(F, 3, P)).reshape(a.x.shape)
    return np.linalg.norm(Xa - b.x) / np.linalg.norm(b.x), float(np.abs(a.R @ Q.T - b.R).max())


@pytest.mark.parametrize(("tau", "seed"), [(2.0, 0), (1.0, 2)])
def test_adaptive_shape_tolerance_keeps_the_converged_result(tau, seed, monkeypatch):
    W, mask, _, X_true = scene(seed=seed)
    F, P = mask.shape
    R0 = initialize_cameras(W, mask)
    counts = []

    def counting(*args, **kwargs):
        out = fista_tnh(*args, **kwargs)
        counts.append(out.nit)
        return out

    monkeypatch.setattr(cr, "fista_tnh", counting)
    ref = tnh_with_camera_refinement_reference(W, mask, R0, tau)
    ref_iterations, counts[:] = sum(counts), []
    fast = tnh_with_camera_refinement(W, mask, R0, tau)
    fast_iterations = sum(counts)
    tight = tnh_with_camera_refinement_reference(W, mask, R0, tau, tol=1e-13)
    assert ref.success and fast.success and tight.success
    assert tight.nit > 1.5 * ref.nit  # the tight run does go further towards the fixed point

    # distance of a default-tolerance run to the fixed point (measured: 2e-4 to 4e-4 relative)
    reach_X, reach_R = aligned_distance(ref, tight, P)
    assert 0 < reach_X < 1e-2
    dX, dR = aligned_distance(fast, ref, P)  # measured: 7e-6 to 8e-6 and 1e-5
    assert dX <= 2 * reach_X and dR <= 2 * reach_R
    # joint energies: both above the tight run's by at most its gap to the reference (relative 1e-8)
    E_ref, E_fast, E_tight = ref.energy_history[-1], fast.energy_history[-1], tight.energy_history[-1]
    assert E_tight <= E_ref and E_ref - E_tight <= 1e-6 * E_tight
    assert abs(E_fast - E_ref) <= 2 * (E_ref - E_tight) + 1e-12 * E_ref
    # the evaluation the tau search sees: e3D within 2x the reference's own distance to the fixed point
    e_ref, e_fast, e_tight = (e3d(r.x, X_true, P, align=True) for r in (ref, fast, tight))
    assert abs(e_fast - e_ref) <= 2 * abs(e_ref - e_tight) + 1e-9
    # the point of the exercise: the joint energy still never increases, with far fewer FISTA iterations
    assert np.all(np.diff(fast.energy_history) <= 1e-12 * fast.energy_history[0])
    assert abs(fast.nit - ref.nit) <= 0.1 * ref.nit
    assert fast_iterations < 0.6 * ref_iterations


def test_fixed_shape_tolerance_is_the_reference_up_to_the_thresholding():
    """The alternation's shape steps at the fixed tolerance 1e-12 without carried momentum: the
    reference up to the thresholding (Gram matrix against a full SVD, equal to rounding)."""
    W, mask, _, _ = scene(n_frames=8, n_points=10, seed=4)
    R0 = initialize_cameras(W, mask)
    ref = tnh_with_camera_refinement_reference(W, mask, R0, 3.0)
    fixed = tnh_alternation(
        W, mask, R0, 3.0, 20_000, 1e-8, 10, None, shape_tol=(1e-12, 0.0, 1e-12), momentum=False
    )
    assert abs(fixed.nit - ref.nit) <= 1  # the thresholdings agree to rounding: the stop test may shift one
    n = min(fixed.energy_history.size, ref.energy_history.size)
    np.testing.assert_allclose(fixed.energy_history[:n], ref.energy_history[:n], rtol=1e-9)


def test_tnh_with_camera_refinement_validates():
    W, mask, _, _ = scene(n_frames=6, n_points=8, seed=5)
    R0 = initialize_cameras(W, mask)
    for kwargs, name in [
        ({"tau": 0.0}, "tau"),
        ({"tau": 1.0, "window": 0}, "window"),
        ({"tau": 1.0, "X0": W}, "X0"),
    ]:
        with pytest.raises(ValueError, match=name):
            tnh_with_camera_refinement(W, mask, R0, **kwargs)
