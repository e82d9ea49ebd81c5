"""Hold-out selection for NRSfM (nldr.nrsfm._selection): folds of observed 2D points, the hidden
reprojection score, and the selections of TNH's tau and the kernel method's tau and width, checked
against the same computations done by hand."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from nldr.kernels import d_med_width
from nldr.nrsfm import (
    CameraFrameVariables,
    OrthographicReprojection,
    e3d,
    initialize_cameras,
    reconstruct,
    reprojection_error,
    select_kernel,
    select_tnh_tau,
)
from nldr.nrsfm._camera_refinement import tnh_with_camera_refinement
from nldr.nrsfm._layout import visibility_folds
from nldr.nrsfm._reconstruct import trace_norm_heuristic
from nldr.nrsfm._rotations import quaternion_rotation
from nldr.regularizer import minimize_regularized


@pytest.fixture(autouse=True)
def one_blas_thread():
    with threadpool_limits(1):
        yield


def holdout_reprojection_error(W, hidden, R, X):
    """Mean over the hidden points of ||w - R s||^2: the selection's score, from the cameras and shapes."""
    return reprojection_error(W, hidden, R, X) / hidden.sum()


def synthetic_sequence(F=24, P=10, missing=0.3, noise=0.0, seed=0):
    """A non-rigid sequence of known low rank: S_f = B0 + sin(t_f) B1 + cos(2 t_f) B2 (rank 3 in the
    shape space, per-frame centred points), smoothly rotating orthographic cameras, a random mask."""
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(3, 3, P))
    B[1:] *= 0.4
    B -= B.mean(axis=2, keepdims=True)
    t = np.linspace(0, 2 * np.pi, F)
    S = B[0] + np.sin(t)[:, None, None] * B[1] + np.cos(2 * t)[:, None, None] * B[2]  # (F, 3, P)
    axis = np.stack([np.cos(t / 2), 0.3 * np.sin(t), np.sin(t / 2), 0.2 * np.ones(F)], axis=1)
    R = quaternion_rotation(axis / np.linalg.norm(axis, axis=1, keepdims=True))[0][:, :2]
    W = (R @ S).reshape(F, 2 * P) + noise * rng.normal(size=(F, 2 * P))
    mask = rng.random((F, P)) >= missing
    return W, R, S.reshape(F, 3 * P), mask


# --------------------------------------------------------------------------------------------------
# Folds and the score
# --------------------------------------------------------------------------------------------------


def test_folds_are_disjoint_observed_and_repeat_with_the_seed():
    _, _, _, mask = synthetic_sequence(F=30, P=12, missing=0.4)
    folds = visibility_folds(mask, 3, random_state=5)
    total = np.sum(folds, axis=0)
    assert total.max() == 1 and not total[~mask].any()  # disjoint, only observed points
    again = visibility_folds(mask, 3, random_state=5)
    assert all(np.array_equal(a, b) for a, b in zip(folds, again, strict=True))
    other = visibility_folds(mask, 3, random_state=6)
    assert not all(np.array_equal(a, b) for a, b in zip(folds, other, strict=True))
    for hidden in folds:  # every frame keeps 3 training points, every point one frame
        train = mask & ~hidden
        assert (train.sum(axis=1) >= 3).all() and (train.sum(axis=0) >= 1).all()


def test_holdout_fraction_hides_that_share_and_sparse_frames_keep_three_points():
    mask = np.ones((20, 10), dtype=bool)
    folds = visibility_folds(mask, 2, random_state=0, holdout_fraction=0.1)
    assert [int(h.sum()) for h in folds] == [20, 20]
    assert not (folds[0] & folds[1]).any()
    mask[4, 3:] = False  # frame 4: three observed points, none may be hidden
    mask[7, 4:] = False  # frame 7: four, at most one hidden
    for hidden in visibility_folds(mask, 3, random_state=1):
        assert not hidden[4].any() and hidden[7].sum() <= 1
        assert ((mask & ~hidden).sum(axis=1) >= 3).all()


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"n_folds": 1}, "n_folds"),
        ({"holdout_fraction": 0.6}, "holdout_fraction"),
        ({"mask": np.ones(4)}, "mask"),
    ],
)
def test_folds_reject_bad_input_naming_it(kwargs, match):
    args = {"mask": np.ones((6, 5), dtype=bool), **kwargs}
    with pytest.raises(ValueError, match=match):
        visibility_folds(args.pop("mask"), **args)


def test_score_is_the_mean_squared_2d_distance_of_the_hidden_points():
    W, R, X, _ = synthetic_sequence(F=5, P=4)
    rng = np.random.default_rng(1)
    X_hat = X + 0.1 * rng.normal(size=X.shape)
    hidden = np.zeros((5, 4), dtype=bool)
    hidden[1, 2] = hidden[3, 0] = True
    by_hand = []
    for f, j in zip(*np.nonzero(hidden), strict=True):
        s = X_hat[f].reshape(3, 4)[:, j]
        w = np.array([W[f, j], W[f, 4 + j]])
        by_hand.append(np.sum((w - R[f] @ s) ** 2))
    assert holdout_reprojection_error(W, hidden, R, X_hat) == pytest.approx(np.mean(by_hand), rel=1e-14)
    assert holdout_reprojection_error(W, hidden, R, X) == pytest.approx(0.0, abs=1e-24)


# --------------------------------------------------------------------------------------------------
# The kernel method with known cameras (Table 3)
# --------------------------------------------------------------------------------------------------

# Table 3's schedule, its iterations capped
SCHEDULE = {"rho0": 1e-3, "rho_growth": 10.0, "rho_max": 10.0, "options": {"max_inner": 100}}


def test_kernel_scores_are_the_hand_computed_fold_solves_and_the_refit_is_the_solver():
    W, R, _, mask = synthetic_sequence(F=12, P=7, missing=0.3)
    taus, multiples = [1e-4, 1e-3], [1.0]
    sel = select_kernel(
        W,
        mask,
        R=R,
        taus=taus,
        width_multiples=multiples,
        n_folds=2,
        warm_start=False,
        rule="min",
        **SCHEDULE,
    )
    folds = visibility_folds(mask, 2, random_state=0)
    for tau in taus:
        errors = []
        for hidden in folds:
            train = mask & ~hidden
            X0 = trace_norm_heuristic(W, train, R).x
            res = minimize_regularized(
                OrthographicReprojection(W, train, R), X0, gamma=d_med_width(X0), tau=tau, **SCHEDULE
            )
            errors.append(holdout_reprojection_error(W, hidden, R, res.x))
        row = sel.cv_results_[sel.cv_results_["tau"] == tau].iloc[0]
        assert row["mean_test_error"] == pytest.approx(np.mean(errors), rel=1e-12)
        assert row["std_test_error"] == pytest.approx(np.std(errors, ddof=1), rel=1e-9)
    assert sel.tau_ == taus[int(np.argmin(sel.cv_results_["mean_test_error"]))]
    X0 = trace_norm_heuristic(W, mask, R).x
    refit = minimize_regularized(
        OrthographicReprojection(W, mask, R),
        X0,
        gamma=sel.width_multiple_ * d_med_width(X0),
        tau=sel.tau_,
        **SCHEDULE,
    )
    np.testing.assert_array_equal(sel.result_.x, refit.x)
    assert sel.gamma_ == sel.width_multiple_ * d_med_width(X0)


def test_reference_rule_leaves_the_reference_only_for_a_candidate_better_by_one_paired_se():
    W, R, _, mask = synthetic_sequence(F=10, P=6, missing=0.2, noise=0.01, seed=0)
    kw = dict(R=R, taus=[1e-4, 1e-3], width_multiples=[0.5, 1.0], n_folds=4, **SCHEDULE)
    sel = select_kernel(W, mask, rule="reference", reference=(1e-4, 1.0), **kw)
    cv, scores = sel.cv_results_, sel.fold_scores_.to_numpy()
    assert scores.shape == (4, len(cv))
    np.testing.assert_allclose(scores.mean(axis=0), cv["mean_test_error"], rtol=1e-12)
    ref = int(np.flatnonzero((cv["tau"] == 1e-4) & (cv["width_multiple"] == 1.0))[0])
    diff = scores - scores[:, [ref]]
    se = diff.std(axis=0, ddof=1) / 2.0  # sqrt(4 folds)
    np.testing.assert_allclose(cv["mean_diff_reference"], diff.mean(axis=0), rtol=1e-12, atol=1e-300)
    np.testing.assert_allclose(cv["se_diff_reference"], se, rtol=1e-12, atol=1e-300)
    better = cv["active"].to_numpy() & (diff.mean(axis=0) + se < 0)
    expected = ref if not better.any() else np.flatnonzero(better)[np.argmin(cv["mean_test_error"][better])]
    assert (sel.tau_, sel.width_multiple_) == (cv["tau"][expected], cv["width_multiple"][expected])
    # the same folds and scores as "min", which takes the smallest mean among the active candidates
    plain = select_kernel(W, mask, rule="min", **kw)
    np.testing.assert_array_equal(plain.fold_scores_.to_numpy(), scores)
    active = cv["active"].to_numpy()
    best = np.flatnonzero(active)[np.argmin(cv["mean_test_error"][active])]
    assert (plain.tau_, plain.width_multiple_) == (cv["tau"][best], cv["width_multiple"][best])


def test_a_tau_that_leaves_the_start_in_place_is_inactive_and_never_chosen():
    # tau = 1e-12: the regularizer's gradient is below L-BFGS's gtol at the TNH start, the solve
    # returns its start, and the hold-out score is TNH's, not the kernel method's
    W, R, _, mask = synthetic_sequence(F=12, P=7, missing=0.3)
    kw = dict(R=R, taus=[1e-12, 1e-3], width_multiples=[1.0], n_folds=2, rule="min", **SCHEDULE)
    sel = select_kernel(W, mask, **kw)
    cv = sel.cv_results_.set_index("tau")
    assert cv.loc[1e-12, "max_move"] < 1e-3 <= cv.loc[1e-3, "max_move"]
    assert not cv.loc[1e-12, "active"] and cv.loc[1e-3, "active"]
    assert sel.tau_ == 1e-3
    # with min_move = 0 every candidate is eligible: the smaller mean score wins
    anyone = select_kernel(W, mask, min_move=0.0, **kw)
    assert anyone.tau_ == cv["mean_test_error"].idxmin()


def test_kernel_selection_repeats_with_the_seed_and_rejects_bad_input():
    W, R, _, mask = synthetic_sequence(F=10, P=6, missing=0.2)
    kw = dict(R=R, taus=[1e-4, 1e-3], width_multiples=[0.5, 1.0], n_folds=2, random_state=3, **SCHEDULE)
    a, b = select_kernel(W, mask, **kw), select_kernel(W, mask, **kw)
    cols = ["tau", "width_multiple", "mean_test_error", "std_test_error"]
    assert a.cv_results_[cols].equals(b.cv_results_[cols]) and (a.tau_, a.gamma_) == (b.tau_, b.gamma_)
    assert len(a.cv_results_) == 4
    with pytest.raises(ValueError, match="exactly one"):
        select_kernel(W, mask)
    with pytest.raises(ValueError, match="width_rule"):
        select_kernel(W, mask, R=R, width_rule="d_min")
    with pytest.raises(ValueError, match="tau"):
        select_kernel(W, mask, R=R, tau=1e-4)
    with pytest.raises(ValueError, match="rule"):
        select_kernel(W, mask, R=R, rule="one_se")
    with pytest.raises(ValueError, match="reference"):
        select_kernel(W, mask, R=R, taus=[1e-3], reference=(1e-4, 1.0))
    with pytest.raises(ValueError, match="min_move"):
        select_kernel(W, mask, R=R, min_move=-1.0)


# --------------------------------------------------------------------------------------------------
# TNH with estimated cameras (Table 4), and the kernel stage after it
# --------------------------------------------------------------------------------------------------

ALTERNATION = {"max_outer": 500, "tol": 1e-6}


def test_tnh_scores_are_cold_start_fold_solves_and_cv_beats_an_extreme_tau():
    # noisy tracks of a rank-3 sequence: tau = 1000 shrinks the shapes to nothing, tau = 1 denoises;
    # the CV minimiser is also better in 3D than the extreme it rejected
    W, _, X_gt, mask = synthetic_sequence(F=16, P=8, missing=0.2, noise=0.02, seed=2)
    taus = [1.0, 1000.0]
    sel = select_tnh_tau(W, mask, taus=taus, n_folds=2, **ALTERNATION)
    folds = visibility_folds(mask, 2, random_state=0)
    for tau in taus:
        errors = []
        for hidden in folds:
            train = mask & ~hidden
            res = tnh_with_camera_refinement(W, train, initialize_cameras(W, train), tau, **ALTERNATION)
            errors.append(holdout_reprojection_error(W, hidden, res.R, res.x))
        row = sel.cv_results_[sel.cv_results_["tau"] == tau].iloc[0]
        assert row["mean_test_error"] == pytest.approx(np.mean(errors), rel=1e-12)
    assert sel.tau_ == 1.0
    refit = tnh_with_camera_refinement(W, mask, initialize_cameras(W, mask), sel.tau_, **ALTERNATION)
    np.testing.assert_array_equal(sel.result_.x, refit.x)
    extreme = tnh_with_camera_refinement(W, mask, initialize_cameras(W, mask), 1000.0, **ALTERNATION)
    P = mask.shape[1]
    assert e3d(sel.result_.x, X_gt, P, align=True) < e3d(extreme.x, X_gt, P, align=True)
    # the kernel stage after it: its folds start from the fold solves at tau_ and its refit from the
    # refit, all Table 4's kernel stage (cameras and shapes jointly)
    ksel = select_kernel(
        W, mask, tnh=sel, taus=[1e-4], width_multiples=[1.0], camera_options={"multistart": False}, **SCHEDULE
    )
    assert ksel.folds_ is sel.folds_
    gamma = d_med_width(sel.result_.x)
    by_hand = reconstruct(
        W, mask, prior="kernel", tau=1e-4, width=gamma, start=sel.result_, multistart=False, **SCHEDULE
    )
    np.testing.assert_array_equal(ksel.result_.x, by_hand.x)
    np.testing.assert_array_equal(ksel.result_.R, by_hand.R)
    hidden = sel.folds_[0]
    train = mask & ~hidden  # the fold starts from its TNH at tau_, from its own rigid cameras
    fold_tnh = reconstruct(W, train, prior="tnh", tau=sel.tau_, initial_cameras=initialize_cameras(W, train),
                           **ALTERNATION)  # fmt: skip
    fold = reconstruct(
        W, train, prior="kernel", tau=1e-4, width=d_med_width(fold_tnh.x), start=fold_tnh, multistart=False,
        **SCHEDULE,
    )  # fmt: skip
    assert ksel.fold_scores_.iloc[0, 0] == pytest.approx(
        holdout_reprojection_error(W, hidden, fold.R, fold.x), rel=1e-12
    )
    with pytest.raises(ValueError, match="another mask"):
        select_kernel(W, mask & ~sel.folds_[0], tnh=sel)


def test_depth_scale_runs_folds_and_refit_in_camera_frame_variables():
    # each fold solve and the refit are minimize_regularized with CameraFrameVariables of that
    # solve's cameras and training mask: recomputed by hand, the scores and the refit agree
    W, R, _, mask = synthetic_sequence(F=12, P=7, missing=0.3)
    sel = select_kernel(
        W, mask, R=R, taus=[1e-3], width_multiples=[1.0], n_folds=2, rule="min", depth_scale=30.0, **SCHEDULE
    )
    errors = []
    for hidden in visibility_folds(mask, 2, random_state=0):
        train = mask & ~hidden
        X0 = trace_norm_heuristic(W, train, R).x
        res = minimize_regularized(
            OrthographicReprojection(W, train, R),
            X0,
            gamma=d_med_width(X0),
            tau=1e-3,
            variables=CameraFrameVariables(R, train, 30.0),
            **SCHEDULE,
        )
        errors.append(holdout_reprojection_error(W, hidden, R, res.x))
    assert sel.cv_results_["mean_test_error"].iloc[0] == pytest.approx(np.mean(errors), rel=1e-12)
    X0 = trace_norm_heuristic(W, mask, R).x
    refit = minimize_regularized(
        OrthographicReprojection(W, mask, R),
        X0,
        gamma=d_med_width(X0),
        tau=1e-3,
        variables=CameraFrameVariables(R, mask, 30.0),
        **SCHEDULE,
    )
    np.testing.assert_array_equal(sel.result_.x, refit.x)
    with pytest.raises(ValueError, match="depth_scale"):
        select_kernel(W, mask, R=R, depth_scale=0.0)
    with pytest.raises(ValueError, match="variables"):
        select_kernel(W, mask, R=R, variables=CameraFrameVariables(R, mask, 30.0))
