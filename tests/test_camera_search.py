"""The data-only camera search of TNH with unknown cameras (nldr.nrsfm._camera_refinement.tnh_camera_search,
tnh_basin_search, lowest_energy).

Tolerances. The proposals on a noise-free constant-velocity camera path are exact in exact arithmetic
(a composition of three rotations), so their bounds absorb rounding only (1e-12 on the entries). The search's
guarantees are orderings of energies it computes itself (never above its start; a kept round lower
by more than rtol; the basin search's result within tie_rtol of its lowest start), checked exactly.
The tie rule is a function of the set of (label, energy) pairs, so permuting them gives the identical
choice, and the basin search run with its starts in another order gives bit-identical arrays.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import project
from scipy.spatial.transform import Rotation

from nldr.datasets import load_mocap
from nldr.nrsfm._basin_search import STARTS, lowest_energy, tnh_basin_search, tnh_continuation
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


@pytest.mark.parametrize("mode", ["forward", "backward", "local", "worst"])
def test_proposals_leave_a_smooth_path_alone(mode):
    R = orbit(10)
    R_new, changed = propose_cameras(R, mode)
    assert changed.size == 0
    np.testing.assert_allclose(R_new, R, atol=1e-12)


@pytest.mark.parametrize("mode", ["forward", "backward", "local", "worst"])
@pytest.mark.parametrize("frames", [[4], [4, 5]])
def test_proposals_restore_turned_frames_of_a_constant_velocity_path(mode, frames):
    R = orbit(10)
    if mode in ("local", "worst") and len(frames) > 1:
        frames = frames[:1]  # the midpoint of two neighbours needs both to be right; worst moves one
    R_new, changed = propose_cameras(turned(R, frames), mode)
    assert list(changed) == frames
    np.testing.assert_allclose(R_new, R, atol=1e-12)


@pytest.mark.parametrize("frame", [0, 9])
def test_worst_proposal_restores_an_end_frame_from_the_extrapolation(frame):
    """An end frame has one neighbour: the prediction is the constant-velocity extrapolation of the
    two nearest cameras, exact on this path; a frame turned by only 20 degrees (below the sweeps'
    30-degree test, above worst's 15) is restored."""
    R = orbit(10)
    R_turned = R.copy()
    M = Rotation.from_rotvec([0.0, 0.0, np.radians(20.0)]).as_matrix()
    R_turned[frame] = R[frame] @ M
    assert propose_cameras(R_turned, "forward")[1].size == 0 or frame == 0
    R_new, changed = propose_cameras(R_turned, "worst")
    assert list(changed) == [frame]
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


def test_lowest_energy_takes_the_lowest_beyond_the_tolerance():
    assert lowest_energy([("rigid", 10.0), ("continuation", 9.9)], 1e-4, STARTS) == "continuation"
    assert lowest_energy([("b", 1.0)], 0.0) == "b"


@pytest.mark.parametrize("seed", range(5))
def test_lowest_energy_breaks_ties_by_rule_whatever_the_order(seed):
    """Energies within rtol of the lowest are one basin: the first label of the priority wins (then the
    smallest name), and any permutation of the candidates gives the same label."""
    rng = np.random.default_rng(seed)
    tied = [("rigid", 5.0 * (1 + 0.9e-4)), ("continuation", 5.0), ("zeta", 5.0 * (1 + 0.5e-4))]
    pairs = [*tied, ("far", 5.0 * (1 + 2e-4))]
    for _ in range(6):
        order = rng.permutation(len(pairs))
        permuted = [pairs[k] for k in order]
        assert lowest_energy(permuted, 1e-4, STARTS) == "rigid"
        assert lowest_energy(permuted, 1e-4) == "continuation"  # no priority: the smallest name
        assert lowest_energy(permuted, 0.0, STARTS) == "continuation"  # no tolerance: strictly lowest


def test_lowest_energy_rejects_bad_arguments():
    with pytest.raises(ValueError, match="at least one"):
        lowest_energy([], 1e-4)
    with pytest.raises(ValueError, match="distinct"):
        lowest_energy([("a", 1.0), ("a", 2.0)], 1e-4)
    with pytest.raises(ValueError, match="rtol"):
        lowest_energy([("a", 1.0)], -1.0)


def test_continuation_without_rungs_is_the_plain_alternation():
    W, R, _ = deforming_orbit()
    plain = tnh_with_camera_refinement(W, None, turned(R, [6]), 0.5, max_outer=300)
    path = tnh_continuation(W, None, turned(R, [6]), 0.5, log10_tau_high=np.log10(0.5), max_outer=300)
    assert path.search["n_alternations"] == 1
    np.testing.assert_array_equal(path.R, plain.R)
    np.testing.assert_array_equal(path.x, plain.x)


def test_basin_search_keeps_the_lowest_start_whatever_their_order():
    """The kept energy is within tie_rtol of the lowest start's and never above the rigid start's
    search; the starts in the other order give bit-identical cameras and shapes."""
    W, R, _ = deforming_orbit()
    tau, options = 0.5, dict(max_outer=2000, log10_tau_high=1.0)
    R0 = turned(R, [6, 7])
    out = tnh_basin_search(W, None, R0, tau, **options)
    energies = out.search["start_energies"]
    assert set(energies) == set(STARTS)
    assert out.search["start"] in STARTS
    assert out.fun <= min(energies.values()) * (1 + 1e-4)
    rigid = tnh_camera_search(W, None, tnh_with_camera_refinement(W, None, R0, tau, max_outer=2000), tau,
                              max_outer=2000)  # fmt: skip
    assert energies["rigid"] == rigid.fun
    assert out.fun <= rigid.fun * (1 + 1e-4)
    assert out.fun == pytest.approx(tnh_energy(W, None, out.R, out.x, tau), rel=1e-12)
    swapped = tnh_basin_search(W, None, R0, tau, starts=STARTS[::-1], **options)
    assert swapped.search["start"] == out.search["start"]
    np.testing.assert_array_equal(swapped.R, out.R)
    np.testing.assert_array_equal(swapped.x, out.x)


def test_basin_search_with_the_rigid_start_alone_is_the_camera_search():
    W, R, _ = deforming_orbit()
    tau, R0 = 0.5, turned(R, [6, 7])
    rigid = tnh_with_camera_refinement(W, None, R0, tau, max_outer=2000)
    alone = tnh_basin_search(W, None, R0, tau, starts=("rigid",), rigid=rigid, max_outer=2000)
    search = tnh_camera_search(W, None, rigid, tau, max_outer=2000)
    assert alone.fun == search.fun
    np.testing.assert_array_equal(alone.R, search.R)
    with pytest.raises(ValueError, match="starts"):
        tnh_basin_search(W, None, R0, tau, starts=("rigid", "rigid"))
    with pytest.raises(ValueError, match="starts"):
        tnh_basin_search(W, None, R0, tau, starts=("mirror",))


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
