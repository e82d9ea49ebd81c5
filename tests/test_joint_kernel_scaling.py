"""Block scaling of the joint camera-and-shape step and Table 4's multi-start kernel stage.

Tolerances. The curvature of a quadratic along a direction is exact by a forward difference of
gradients up to rounding: eps |g| / (h |d|) ~ 1e-16 / 1e-6 = 1e-10 relative for gradients of order one,
so 1e-7 has three orders of margin. Everything else is compared exactly: the same deterministic
computation run twice gives the same bits, and L-BFGS-B never returns a point above its start.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import project, random_rotation
from scipy.spatial.transform import Rotation

from nldr.kernels import d_max_width, d_med_width
from nldr.nrsfm._joint_kernel import (
    block_curvature,
    joint_kernel_multistart,
    kernel_energy,
    solve_joint_kernel,
)
from nldr.nrsfm._layout import random_visibility_mask
from nldr.nrsfm._metrics import center_per_frame


def scene(n_frames=10, n_points=8, seed=0, missing=0.25):
    """Shapes on a bending path, random cameras, tracks with hidden entries; a perturbed start."""
    rng = np.random.default_rng(seed)
    base = rng.standard_normal(3 * n_points) * np.repeat([3.0, 2.0, 1.0], n_points)
    modes = rng.standard_normal((2, 3 * n_points))
    t = np.linspace(-1, 1, n_frames)[:, None]
    X = center_per_frame(base + np.sin(2 * t) * modes[0] + (t**2) * modes[1], n_points)
    R = np.stack([random_rotation(rng)[:2] for _ in range(n_frames)])
    mask = random_visibility_mask(n_frames, n_points, missing, seed + 1)
    turn = Rotation.from_rotvec(np.radians(5.0) * rng.standard_normal((n_frames, 3))).as_matrix()
    R0 = np.stack([(G @ np.vstack([r, np.cross(*r)]))[:2] for G, r in zip(turn, R, strict=True)])
    return project(R, X), mask, R0, X + 0.05 * rng.standard_normal(X.shape)


def test_block_curvature_of_a_quadratic_is_the_rayleigh_quotient_along_the_restricted_gradient():
    rng = np.random.default_rng(1)
    A = rng.standard_normal((12, 12))
    H = A @ A.T + np.eye(12)
    b = rng.standard_normal(12)

    def value_grad(v):
        return 0.5 * v @ H @ v - b @ v, H @ v - b

    v = rng.standard_normal(12)
    grad = value_grad(v)[1]
    block = np.arange(12) % 3 == 0
    d = np.where(block, grad, 0.0)
    d /= np.linalg.norm(d)
    assert block_curvature(value_grad, v, grad, block, 1e-6) == pytest.approx(d @ H @ d, rel=1e-7)
    assert block_curvature(value_grad, v, np.where(block, 0.0, grad), block, 1e-6) == 0.0


def test_every_stage_ends_no_higher_than_it_starts():
    """Each stage starts where the previous ended; L-BFGS-B descends (converged or not: 300 iterations
    at most here), so the energy at a stage's end is at most the energy of the previous stage's end
    evaluated at this stage's rho (exact)."""
    W, mask, R0, X0 = scene(seed=3)
    gamma, tau = d_med_width(X0), 1e-3
    res = solve_joint_kernel(
        W,
        mask,
        R0,
        X0,
        gamma=gamma,
        tau=tau,
        rho0=0.1,
        rho_max=10.0,
        max_inner=300,
    )
    assert res.rho_history.tolist() == pytest.approx([0.1, 1.0, 10.0])
    assert res.stage_energy[0] <= kernel_energy(W, mask, R0, X0, gamma=gamma, tau=tau, rho=0.1)
    # stage k's start is stage k-1's end; its energy at rho_k is reproduced by a fresh stage-k run
    one = solve_joint_kernel(W, mask, R0, X0, gamma=gamma, tau=tau, rho0=0.1, rho_max=0.1, max_inner=300)
    assert one.fun == res.stage_energy[0]  # same computation, same bits
    assert res.stage_energy[1] <= kernel_energy(W, mask, one.R, one.x, gamma=gamma, tau=tau, rho=1.0)
    assert np.allclose(res.R @ res.R.transpose(0, 2, 1), np.eye(2), atol=1e-12)


def test_multistart_keeps_the_lowest_paper_energy_of_its_starts():
    """joint_kernel_multistart's kept energy (tie_rtol = 0) is the minimum over the starts it documents,
    each run alone (exact: the same deterministic runs), never above the single full schedule, and its
    ``nit`` sums the iterations of every start of that width."""
    W, mask, R0, X0 = scene(seed=5)
    gammas = {"d_max": d_max_width(X0), "d_med": d_med_width(X0)}
    kw = dict(tau=1e-4, rho0=1e-2, rho_growth=10.0, rho_max=1.0, tie_rtol=0.0)
    out = joint_kernel_multistart(W, mask, R0, X0, gammas, multistart=True, **kw)
    single = joint_kernel_multistart(W, mask, R0, X0, gammas, multistart=False, **kw)

    def run(width, R, X, rho0):
        res = solve_joint_kernel(W, mask, R, X, gamma=gammas[width], tau=1e-4, rho0=rho0, rho_max=1.0)
        return res, kernel_energy(W, mask, res.R, res.x, gamma=gammas[width], tau=1e-4, rho=1.0)

    first = {}
    for width in gammas:
        full, second = run(width, R0, X0, 1e-2), run(width, R0, X0, 1e-1)
        assert single[width][1] == full[1]
        first[width] = min(full, second, key=lambda pair: pair[1])
        first[width] = (first[width], full[0].nit + second[0].nit)
    for width, other in [("d_max", "d_med"), ("d_med", "d_max")]:
        (kept, energy), spent = first[width]
        cross = run(width, first[other][0][0].R, first[other][0][0].x, 1.0)
        assert out[width][1] == min(energy, cross[1])
        assert out[width][1] <= single[width][1]
        assert out[width][0].nit == spent + cross[0].nit


def test_multistart_ties_go_to_the_earlier_start():
    """With a tolerance as wide as the energies' spread, every start ties and the full schedule (the
    first) is kept; with the default, the kept energy is within tie_rtol of the lowest start's."""
    W, mask, R0, X0 = scene(seed=5)
    gammas = {"d_max": d_max_width(X0), "d_med": d_med_width(X0)}
    kw = dict(tau=1e-4, rho0=1e-2, rho_growth=10.0, rho_max=1.0)
    lowest = joint_kernel_multistart(W, mask, R0, X0, gammas, tie_rtol=0.0, **kw)
    wide = joint_kernel_multistart(W, mask, R0, X0, gammas, tie_rtol=1e6, **kw)
    default = joint_kernel_multistart(W, mask, R0, X0, gammas, **kw)
    for width in gammas:
        assert wide[width][0].message.startswith("full schedule")
        assert lowest[width][1] <= default[width][1] <= lowest[width][1] * (1 + 1e-4)
    with pytest.raises(ValueError, match="tie_rtol"):
        joint_kernel_multistart(W, mask, R0, X0, gammas, tie_rtol=-1.0, **kw)
