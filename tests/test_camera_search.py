"""The data-only camera search of TNH with unknown cameras (nldr.nrsfm._camera_refinement.tnh_camera_search).

Tolerances. The proposals on a noise-free constant-velocity camera path are exact in exact arithmetic
(a composition of three rotations), so their bounds absorb rounding only (1e-12 on the entries). The search's
guarantees are orderings of energies it computes itself (never above its start; a kept round lower
by more than rtol), checked exactly.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import project
from scipy.spatial.transform import Rotation

from nldr.datasets import load_mocap
from nldr.nrsfm._camera_refinement import propose_cameras, tnh_camera_search, tnh_with_camera_refinement
from nldr.nrsfm._factorization import initialize_cameras
from nldr.nrsfm._layout import random_visibility_mask, stack_to_rows
from nldr.nrsfm._metrics import center_per_frame
from nldr.nrsfm._reprojection import tnh_energy


def orbit(n_frames, step_deg=20.0, seed=0):
    """Cameras turning at constant angular velocity about a fixed random axis, (F, 2, 3)."""
    rng = np.random.default_rng(seed)
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    start = Rotation.random(random_state=seed)
    rots = [Rotation.from_rotvec(np.radians(step_deg) * k * axis) * start for k in range(n_frames)]
    return np.stack([r.as_matrix()[:2] for r in rots])


def turned(R, frames):
    """The cameras with the given frames turned by 180 degrees about their first image axis."""
    R = R.copy()
    R[frames, 1] *= -1
    return R


@pytest.mark.parametrize("mode", ["forward", "backward", "local"])
def test_proposals_leave_a_smooth_path_alone(mode):
    R = orbit(10)
    R_new, changed = propose_cameras(R, mode)
    assert changed.size == 0
    np.testing.assert_allclose(R_new, R, atol=1e-12)


@pytest.mark.parametrize("mode", ["forward", "backward", "local"])
@pytest.mark.parametrize("frames", [[4], [4, 5]])
def test_proposals_restore_turned_frames_of_a_constant_velocity_path(mode, frames):
    R = orbit(10)
    if mode == "local" and len(frames) > 1:
        frames = frames[:1]  # the midpoint of two neighbours needs both to be right
    R_new, changed = propose_cameras(turned(R, frames), mode)
    assert list(changed) == frames
    np.testing.assert_allclose(R_new, R, atol=1e-12)


def test_propose_cameras_rejects_bad_arguments():
    with pytest.raises(ValueError, match="mode"):
        propose_cameras(orbit(5), "sideways")
    with pytest.raises(ValueError, match="threshold_deg"):
        propose_cameras(orbit(5), "forward", threshold_deg=0.0)


def deforming_orbit(n_frames=14, n_points=12, seed=1):
    rng = np.random.default_rng(seed)
    basis = rng.standard_normal((3, 3 * n_points)) * np.array([[3.0], [1.0], [0.5]])
    coeffs = np.column_stack([np.ones(n_frames), 0.4 * np.sin(np.arange(n_frames))[:, None] * [1, -0.5]])
    X = center_per_frame(coeffs @ basis, n_points)
    R = orbit(n_frames, seed=seed)
    return project(R, X), R, X


def test_tnh_energy_is_what_the_alternation_reports():
    W, R, _ = deforming_orbit()
    res = tnh_with_camera_refinement(W, None, R, 0.5, max_outer=50)
    assert tnh_energy(W, None, res.R, res.x, 0.5) == pytest.approx(res.fun, rel=1e-12)


def test_search_from_turned_frames_never_raises_the_energy_and_repeats():
    W, R, _ = deforming_orbit()
    tau = 0.5
    start = tnh_with_camera_refinement(W, None, turned(R, [6, 7]), tau, max_outer=2000)
    out = tnh_camera_search(W, None, start, tau, max_outer=2000)
    assert out.fun <= tnh_energy(W, None, start.R, start.x, tau)
    assert out.search["energies"][0] == tnh_energy(W, None, start.R, start.x, tau)
    for before, after in zip(out.search["energies"], out.search["energies"][1:], strict=False):
        assert after < before * (1 - 1e-6)  # a kept round lowers the energy by more than rtol
    again = tnh_camera_search(W, None, start, tau, max_outer=2000)
    assert again.fun == out.fun
    np.testing.assert_array_equal(again.R, out.R)
    # the search reaches at least the energy of the alternation from the true cameras
    truth = tnh_with_camera_refinement(W, None, R, tau, max_outer=2000)
    assert out.fun <= truth.fun * (1 + 1e-6)


def test_search_rejects_bad_arguments():
    W, R, _ = deforming_orbit(n_frames=6)
    start = tnh_with_camera_refinement(W, None, R, 0.5, max_outer=5)
    with pytest.raises(ValueError, match="proposals"):
        tnh_camera_search(W, None, start, 0.5, proposals=("sideways",))
    with pytest.raises(ValueError, match="start"):
        tnh_camera_search(W, None, R, 0.5)
    with pytest.raises(ValueError, match="max_rounds"):
        tnh_camera_search(W, None, start, 0.5, max_rounds=0)


@pytest.mark.realdata
def test_real_data_stretch_search_lowers_the_energy_where_the_alternation_turned_cameras(data_dir):
    """stretch, every 10th frame, 50 % missing (mask seed 2020), tau = 0.11 (near Table 4's tau*): the
    alternation from the rigid cameras leaves some frames turned over; the search must find a strictly
    lower TNH energy (it re-seats frames only if that holds) and never a higher one. e3D is reported by
    the benchmark, not asserted (the search may not look at it)."""
    seq = load_mocap("stretch", data_dir).subsample(10)
    W = stack_to_rows(seq.W, 2)
    F, P = W.shape[0], W.shape[1] // 2
    mask = random_visibility_mask(F, P, 0.5, 2020)
    tau = 0.11
    start = tnh_with_camera_refinement(W, mask, initialize_cameras(W, mask), tau)
    out = tnh_camera_search(W, mask, start, tau, max_rounds=1)
    assert out.search["n_alternations"] >= 1
    assert out.fun < start.fun * (1 - 1e-6)
    assert out.fun == pytest.approx(tnh_energy(W, mask, out.R, out.x, tau), rel=1e-12)
