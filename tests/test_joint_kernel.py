"""The kernel regularizer with cameras and shapes optimised jointly (nldr.nrsfm._joint_kernel).

Tolerances. Gradients are checked against central differences with step h = 1e-6: the truncation error
is O(h^2 |f'''|) ~ 1e-12 and the rounding error O(eps |f| / h) ~ 1e-10 for energies of order one, so a
relative agreement of 1e-6 has four orders of margin and fails for any wrong term. Identities between
two evaluations of the same energy hold to rounding (1e-12 relative).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import alternate, project, random_rotation
from scipy.spatial.transform import Rotation

from nldr.data_terms import Huber
from nldr.kernels import d_med_width
from nldr.nrsfm._joint_kernel import joint_value_grad, kernel_energy, solve_joint_kernel
from nldr.nrsfm._layout import random_visibility_mask
from nldr.nrsfm._metrics import center_per_frame
from nldr.nrsfm._reprojection import OrthographicReprojection
from nldr.nrsfm._rotations import complete_rotations, quaternion_rotation
from nldr.regularizer import minimize_regularized, reduced_energy


def deforming_scene(n_frames=16, n_points=8, seed=0):
    """Shapes on a one-dimensional non-linear path (a bending motion), random cameras, tracks."""
    rng = np.random.default_rng(seed)
    base = rng.standard_normal(3 * n_points) * np.repeat([3.0, 2.0, 1.0], n_points)
    modes = rng.standard_normal((2, 3 * n_points))
    t = np.linspace(-1, 1, n_frames)[:, None]
    X = base + np.sin(2 * t) * modes[0] + (t**2) * modes[1]
    X = center_per_frame(X, n_points)
    R = np.stack([random_rotation(rng)[:2] for _ in range(n_frames)])
    return project(R, X), R, X


def perturb(R, degrees, rng):
    axes = rng.standard_normal((R.shape[0], 3))
    axes *= np.radians(degrees) / np.linalg.norm(axes, axis=1, keepdims=True)
    return R @ Rotation.from_rotvec(axes).as_matrix()


def test_quaternion_rotation_is_a_rotation_with_the_central_difference_jacobian():
    rng = np.random.default_rng(1)
    q = rng.standard_normal((7, 4)) * 3
    A, J = quaternion_rotation(q, jacobian=True)
    assert np.allclose(A @ A.transpose(0, 2, 1), np.eye(3), atol=1e-14)
    assert np.allclose(np.linalg.det(A), 1.0, atol=1e-14)
    assert np.allclose(quaternion_rotation(q / np.linalg.norm(q, axis=1, keepdims=True))[0], A, atol=1e-15)
    h = 1e-6
    for k in range(4):
        e = np.zeros(4)
        e[k] = h
        numeric = (quaternion_rotation(q + e)[0] - quaternion_rotation(q - e)[0]) / (2 * h)
        assert np.allclose(numeric, J[..., k], atol=1e-8)


@pytest.mark.parametrize("missing, delta", [(0.0, None), (0.4, None), (0.4, 0.5)])
def test_joint_value_grad_matches_central_differences(missing, delta):
    """Squared loss and Huber (delta = 0.5 puts about a third of these unit-normal residuals in the
    linear zone; the Huber loss is C^1, and no residual sits within h of +-delta)."""
    rng = np.random.default_rng(2)
    F, P = 9, 6
    Q0 = complete_rotations(np.stack([random_rotation(rng)[:2] for _ in range(F)]))
    Z = rng.standard_normal((F, 3, P))
    q = np.tile([1.0, 0, 0, 0], (F, 1)) + 0.2 * rng.standard_normal((F, 4))
    mask = random_visibility_mask(F, P, missing, 3) if missing else np.ones((F, P), bool)
    m3 = mask[:, None, :].astype(float)
    W3 = rng.standard_normal((F, 2, P)) * m3
    args = (Q0, W3, m3, 0.05, 0.01, 3.0, False, None, delta)
    value, gZ, gq = joint_value_grad(Z, q, *args)
    h = 1e-6
    for _ in range(5):
        dZ, dq = rng.standard_normal(Z.shape), rng.standard_normal(q.shape)
        numeric = (
            joint_value_grad(Z + h * dZ, q + h * dq, *args)[0]
            - joint_value_grad(Z - h * dZ, q - h * dq, *args)[0]
        ) / (2 * h)
        analytic = np.vdot(gZ, dZ) + np.vdot(gq, dq)
        assert abs(numeric - analytic) <= 1e-6 * max(1.0, abs(analytic))


def test_kernel_energy_is_the_regularizers_energy_with_the_orthographic_data_term():
    """The change of variables (camera-frame shapes) leaves the energy unchanged, and it is invariant
    under one rotation of every shape with the cameras turned back (the gauge)."""
    W, R, X = deforming_scene()
    rng = np.random.default_rng(4)
    F, P = X.shape[0], X.shape[1] // 3
    mask = random_visibility_mask(F, P, 0.3, 5)
    Rp = perturb(R, 10.0, rng)
    Xp = X + 0.1 * rng.standard_normal(X.shape)
    kw = dict(gamma=0.07, tau=1e-3, rho=1.0)
    direct, _ = reduced_energy(Xp, OrthographicReprojection(W, mask, Rp), **kw)
    ours = kernel_energy(W, mask, Rp, Xp, **kw)
    assert ours == pytest.approx(direct, rel=1e-12)
    G = random_rotation(rng)
    turned = np.einsum("ij,fjp->fip", G, Xp.reshape(F, 3, P)).reshape(F, 3 * P)
    assert kernel_energy(W, mask, Rp @ G.T, turned, **kw) == pytest.approx(ours, rel=1e-10)
    huber, _ = reduced_energy(Xp, Huber(OrthographicReprojection(W, mask, Rp), 0.3), **kw)
    assert kernel_energy(W, mask, Rp, Xp, delta=0.3, **kw) == pytest.approx(huber, rel=1e-12)


def test_joint_step_descends_and_returns_orthonormal_cameras():
    """One penalty stage (rho0 = rho_max) is L-BFGS from the start: the energy cannot increase."""
    W, R, X = deforming_scene(n_frames=10, n_points=6, seed=6)
    rng = np.random.default_rng(7)
    F, P = X.shape[0], X.shape[1] // 3
    mask = random_visibility_mask(F, P, 0.3, 8)
    R0, X0 = perturb(R, 5.0, rng), X + 0.05 * rng.standard_normal(X.shape)
    gamma = d_med_width(X0)
    res = solve_joint_kernel(W, mask, R0, X0, gamma=gamma, tau=1e-3, rho0=10.0, rho_max=10.0)
    start = kernel_energy(W, mask, R0, X0, gamma=gamma, tau=1e-3, rho=10.0)
    assert res.fun < start
    assert res.fun == pytest.approx(
        kernel_energy(W, mask, res.R, res.x, gamma=gamma, tau=1e-3, rho=10.0), rel=1e-12
    )
    assert np.allclose(res.R @ res.R.transpose(0, 2, 1), np.eye(2), atol=1e-12)
    assert res.rho_history.tolist() == [10.0]


def test_joint_step_moves_the_cameras_the_alternation_leaves_in_place():
    """From the same start at a small tau, the camera/shape alternation stops where it began (its shape
    step fits the tracks, leaving the camera LM nothing to reduce), while the joint step turns the
    cameras and ends at a lower energy (the paper's energy at the last rho)."""
    W, R, X = deforming_scene(n_frames=10, n_points=6, seed=9)
    rng = np.random.default_rng(10)
    R0 = perturb(R, 8.0, rng)
    X0 = X + 0.05 * rng.standard_normal(X.shape)
    gamma, tau = d_med_width(X0), 1e-4
    schedule = dict(rho0=1.0, rho_growth=10.0, rho_max=10.0)
    state = {"X": X0}

    def kernel_shape_step(R):  # the kernel method's shape step at fixed cameras, warm-started
        term = OrthographicReprojection(W, None, R)
        state["X"] = minimize_regularized(term, state["X"], gamma=gamma, tau=tau, **schedule).x
        return state["X"]

    alt = alternate(W, None, R0, kernel_shape_step, max_outer=5, tol=1e-4, window=3)
    joint = solve_joint_kernel(W, None, R0, X0, gamma=gamma, tau=tau, **schedule)
    e_alt = kernel_energy(W, None, alt.R, alt.x, gamma=gamma, tau=tau, rho=10.0)
    assert joint.fun < e_alt

    def turned(Ra, Rb):
        return np.degrees(
            np.arccos(
                np.clip(
                    (np.einsum("fij,fij->f", complete_rotations(Ra), complete_rotations(Rb)) - 1) / 2, -1, 1
                )
            )
        ).mean()

    assert turned(alt.R, R0) < 0.1
    assert turned(joint.R, R0) > 10 * turned(alt.R, R0)


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"gamma": 0.0}, "gamma"),
        ({"tau": -1.0}, "tau"),
        ({"R0": np.zeros((3, 2, 3))}, "R0"),
        ({"X0": np.zeros((16, 5))}, "X0"),
        ({"max_inner": 0}, "max_inner"),
    ],
)
def test_bad_input_raises_value_error_naming_the_argument(kwargs, name):
    W, R, X = deforming_scene()
    args = {"R0": R, "X0": X, "gamma": 0.1, "tau": 1e-4} | kwargs
    with pytest.raises(ValueError, match=name):
        solve_joint_kernel(W, None, args.pop("R0"), args.pop("X0"), **args)
