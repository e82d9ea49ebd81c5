"""The one entry point of NRSfM reconstruction (nldr.nrsfm.reconstruct): every (cameras, prior, loss)
runs the solver its docstring names, with the same arguments, so the result is that solver's to the
bit (one deterministic computation repeated); its own fields agree with the energies computed apart.

Tolerances. Equalities of arrays are exact (the same computation twice). Energies recomputed by
another helper agree to rounding of sums of order-one terms (1e-12 relative).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import synthetic_sequence

from nldr.data_terms import Huber
from nldr.kernels import d_max_width, d_med_width
from nldr.nrsfm import (
    CameraFrameVariables,
    OrthographicReprojection,
    Reconstruction,
    center_per_frame,
    initialize_cameras,
    random_visibility_mask,
    reconstruct,
    reprojection_error,
)
from nldr.nrsfm._admm import robust_trace_norm_heuristic
from nldr.nrsfm._camera_refinement import tnh_with_camera_refinement
from nldr.nrsfm._joint_kernel import joint_kernel_multistart, kernel_energy
from nldr.nrsfm._reconstruct import trace_norm_heuristic
from nldr.nrsfm._reprojection import tnh_energy
from nldr.regularizer import minimize_regularized

SCHEDULE = {"rho0": 1e-2, "rho_growth": 10.0, "rho_max": 1.0, "max_inner": 200}
SOLVER = {"rho0": 1e-2, "rho_growth": 10.0, "rho_max": 1.0, "options": {"max_inner": 200}}  # the same


@pytest.fixture(scope="module")
def scene():
    X, W, R = synthetic_sequence(n_frames=10, n_points=8, seed=3)
    X = center_per_frame(X, 8)
    W = np.einsum("fck,fkp->fcp", R, X.reshape(10, 3, 8)).reshape(10, 16)
    mask = random_visibility_mask(10, 8, 0.25, random_state=3)
    return W, R, mask


def test_known_cameras_tnh_and_kernel_are_their_solvers(scene):
    W, R, mask = scene
    tnh = reconstruct(W, mask, cameras=R)
    ref = trace_norm_heuristic(W, mask, R)
    assert isinstance(tnh, Reconstruction) and tnh.prior == "tnh" and tnh.tau == 0.0
    np.testing.assert_array_equal(tnh.x, ref.x)
    np.testing.assert_array_equal(tnh.R, R)
    assert tnh.fun == ref.fun and tnh.nit == ref.nit and np.isnan(tnh.gamma)
    assert tnh.reprojection == reprojection_error(W, mask, R, tnh.x)
    kernel = reconstruct(
        W, mask, cameras=R, prior="kernel", width="d_max", start=tnh, depth_scale=10.0, **SCHEDULE
    )
    by_hand = minimize_regularized(
        OrthographicReprojection(W, mask, R), ref.x, gamma=d_max_width(ref.x), tau=1e-4,
        variables=CameraFrameVariables(R, mask, 10.0), **SOLVER,
    )  # fmt: skip
    np.testing.assert_array_equal(kernel.x, by_hand.x)
    assert kernel.fun == by_hand.fun and kernel.gamma == d_max_width(ref.x) and kernel.start is tnh
    # the default start is the exact-fit TNH
    default = reconstruct(W, mask, cameras=R, prior="kernel", **SCHEDULE)
    given = reconstruct(W, mask, cameras=R, prior="kernel", start=tnh, **SCHEDULE)
    np.testing.assert_array_equal(default.x, given.x)
    np.testing.assert_array_equal(default.start.x, tnh.x)


def test_estimated_cameras_tnh_is_the_alternation_from_the_rigid_cameras(scene):
    W, _, mask = scene
    rec = reconstruct(W, mask, prior="tnh", tau=0.5, max_outer=200)
    ref = tnh_with_camera_refinement(W, mask, initialize_cameras(W, mask), 0.5, max_outer=200)
    np.testing.assert_array_equal(rec.x, ref.x)
    np.testing.assert_array_equal(rec.R, ref.R)
    assert rec.fun == ref.fun
    assert rec.fun == pytest.approx(tnh_energy(W, mask, rec.R, rec.x, 0.5), rel=1e-12)


def test_estimated_cameras_kernel_is_the_multistart_and_returns_the_other_width(scene):
    W, _, mask = scene
    tnh = reconstruct(W, mask, prior="tnh", tau=0.5, max_outer=200)
    rec = reconstruct(W, mask, prior="kernel", width="d_med", start=tnh, **SCHEDULE)
    gammas = {"d_med": d_med_width(tnh.x), "d_max": d_max_width(tnh.x)}
    ref = joint_kernel_multistart(W, mask, tnh.R, tnh.x, gammas, tau=1e-4, **SCHEDULE)
    for width, out in (("d_med", rec), ("d_max", rec.other_widths["d_max"])):
        res, energy = ref[width]
        np.testing.assert_array_equal(out.x, res.x)
        np.testing.assert_array_equal(out.R, res.R)
        assert out.fun == energy and out.gamma == gammas[width]
        assert energy == pytest.approx(
            kernel_energy(W, mask, out.R, out.x, gamma=gammas[width], tau=1e-4, rho=1.0), rel=1e-12
        )
    single = reconstruct(W, mask, prior="kernel", width="d_med", start=tnh, multistart=False, **SCHEDULE)
    assert single.other_widths == {} and single.fun >= rec.fun


def test_huber_loss_starts_from_the_robust_tnh(scene):
    W, R, mask = scene
    robust = reconstruct(W, mask, cameras=R, loss="huber", tau=0.05)
    ref = robust_trace_norm_heuristic(W, mask, R, tau=0.05)
    np.testing.assert_array_equal(robust.x, ref.x)
    rec = reconstruct(
        W, mask, cameras=R, prior="kernel", loss="huber", delta=0.1, tnh={"tau": 0.05}, **SCHEDULE
    )
    by_hand = minimize_regularized(
        Huber(OrthographicReprojection(W, mask, R), 0.1),
        ref.x,
        gamma=d_med_width(ref.x),
        tau=1e-4,
        **SOLVER,
    )
    np.testing.assert_array_equal(rec.x, by_hand.x)
    assert rec.start.loss == "huber" and rec.delta == 0.1


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"cameras": "known"}, "cameras"),
        ({"prior": "pca"}, "prior"),
        ({"loss": "l2"}, "loss"),
        ({"prior": "kernel", "loss": "huber", "cameras": None}, "delta"),
        ({"delta": 0.1}, "delta"),
        ({"prior": "tnh"}, "tau"),
        ({"prior": "tnh", "tau": 1.0, "rho0": 1.0}, "unknown options"),
        ({"prior": "tnh", "loss": "huber", "tau": 1.0}, "known cameras"),
        ({"prior": "kernel", "width": "d_mean", "start": None}, "width"),
    ],
)
def test_bad_arguments_raise_value_errors_naming_them(scene, kwargs, name):
    W, R, mask = scene
    kwargs = dict(kwargs)
    if kwargs.get("cameras", "") is None:
        kwargs["cameras"] = R
    if "start" in kwargs:
        kwargs["start"] = reconstruct(W, mask, cameras=R)
        kwargs["cameras"] = R
    with pytest.raises(ValueError, match=name):
        reconstruct(W, mask, **kwargs)
