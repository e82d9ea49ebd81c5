"""Checks at the edge and their messages: what a user gets for an input the methods cannot take (a
string for a boolean, tracks not centred, an all-NaN column, a missing tau, entries beyond float64's
range of squares, ...) is a message that names the argument and the fix, never a wrong answer given
silently or an error from deep inside. Tiny synthetic data: the whole file runs in seconds."""

import warnings

import numpy as np
import pytest
from conftest import curve_rows, synthetic_sequence
from sklearn.base import clone

from nldr import impute
from nldr.model_selection import HoldoutSearch
from nldr.nrsfm import reconstruct
from nldr.robust_kpca import RobustKernelPCA


def _centred_tracks(n_points=9):
    """A small synthetic sequence's tracks (F, 2P), centred per frame on all points, and its cameras."""
    _, W, R = synthetic_sequence(n_points=n_points)
    F, P = W.shape[0], W.shape[1] // 2
    W3 = W.reshape(F, 2, P)
    return (W3 - W3.mean(axis=2, keepdims=True)).reshape(F, 2 * P), R


def _estimators():
    """One instance of every estimator whose parameters include a boolean (default True or False)."""
    out = [getattr(impute, name)() for name in impute.__all__ if name != "DecompositionDenoiser"]
    out.append(HoldoutSearch(impute.SoftImputer(), {"lam": [0.1, 1.0]}))
    out.append(RobustKernelPCA())
    return out


def _boolean_parameters():
    for estimator in _estimators():
        for name, value in estimator.get_params(deep=False).items():
            if isinstance(value, bool):
                yield pytest.param(estimator, name, id=f"{type(estimator).__name__}.{name}")


@pytest.mark.parametrize("estimator, name", list(_boolean_parameters()))
def test_boolean_parameters_refuse_strings(estimator, name):
    X = curve_rows()
    model = clone(estimator).set_params(**{name: "no"})
    data = X if not isinstance(model, RobustKernelPCA) else np.nan_to_num(X)
    with pytest.raises(ValueError, match=name):
        model.fit(data)


def test_holdout_search_names_an_all_missing_column():
    from sklearn.impute import SimpleImputer

    X = curve_rows()
    X[:, 2] = np.nan
    search = HoldoutSearch(SimpleImputer(), {"strategy": ["mean", "median"]})
    with pytest.raises(ValueError, match=r"column\(s\) \[2\] have no observed entry.*drop those columns"):
        search.fit(X)


def test_reconstruct_says_tau_is_required_with_estimated_cameras():
    W, _ = _centred_tracks()
    with pytest.raises(ValueError, match="tau is required with estimated cameras") as info:
        reconstruct(W)
    assert "-1" not in str(info.value)  # no internal placeholder in the message


@pytest.mark.parametrize(
    "call, named",
    [
        (dict(tnh={"tau": 1.0}, bogus=1), "bogus"),  # estimated cameras
        (dict(tnh={"tau": 1.0}, multistart="no"), "multistart"),
        (dict(known=True, bogus=1), "bogus"),
        (dict(known=True, width="widest"), "width"),
    ],
)
def test_reconstruct_refuses_kernel_options_before_solving_its_start(monkeypatch, call, named):
    import nldr.nrsfm._reconstruct as module

    def solved(*args, **kwargs):
        raise AssertionError("the TNH start was solved before the options were checked")

    monkeypatch.setattr(module, "tnh_with_camera_refinement", solved)
    monkeypatch.setattr(module, "trace_norm_heuristic", solved)
    W, R = _centred_tracks()
    call = dict(call)
    cameras = R if call.pop("known", False) else "estimate"
    with pytest.raises(ValueError, match=named):
        reconstruct(W, cameras=cameras, prior="kernel", **call)


def test_robust_kernel_pca_imputer_warns_truly_when_no_component_is_left():
    X = curve_rows(hidden=0.0)
    model = impute.RobustKernelPCAImputer(tau=1e6)
    with pytest.warns(UserWarning, match="removes every component") as record:
        model.fit(X)
    messages = [str(w.message) for w in record]
    assert not any("(n, 0)" in m for m in messages)  # the imputer's transform keeps every column
    assert any(f"(n, {X.shape[1]}) arrays" in m and "Lower tau" in m for m in messages)
    assert model.transform(curve_rows()).shape == X.shape


def test_both_nystroem_paths_default_to_the_same_landmark_count(monkeypatch):
    from nldr._options import solver_options
    from nldr.impute import _regularizer as module
    from nldr.impute._defaults import DEFAULT_LANDMARKS

    seen = {}

    def record(term, S0, *, method, options, **kwargs):
        seen[method] = dict(options)
        raise StopIteration  # the arguments are what is checked, not the solve

    monkeypatch.setattr(module, "minimize_regularized", record)
    for method in ("nystroem", "nystroem-warm"):
        with pytest.raises(StopIteration):
            impute.KernelRegularizerImputer(method=method, gamma=0.3, tau=0.1).fit(curve_rows())
    for method in ("nystroem", "nystroem-warm"):
        assert solver_options(method, seen[method]).landmarks == DEFAULT_LANDMARKS
    explicit = impute.KernelRegularizerImputer(method="nystroem", n_landmarks=7)._solver_options()
    assert explicit["landmarks"] == 7


def test_reconstruct_warns_about_tracks_off_centre_but_not_about_chance_offsets():
    from nldr.nrsfm import random_visibility_mask

    W, R = _centred_tracks(n_points=16)
    F, P = W.shape[0], W.shape[1] // 2
    visible = random_visibility_mask(F, P, 0.5, 0)  # the observed centroids stray from 0 by chance
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        reconstruct(W, visible, cameras=R)
        reconstruct(W, None, cameras=R)
    with pytest.warns(UserWarning, match=r"not centred: in frame\(s\) \[0, 1, .*Subtract each frame's"):
        reconstruct(W + 5.0, visible, cameras=R)


@pytest.mark.parametrize("factor", [1e200, 1e-200])
@pytest.mark.parametrize("name", [n for n in impute.__all__ if n != "DecompositionDenoiser"])
def test_entries_whose_squares_float64_cannot_hold_are_refused_by_every_imputer(name, factor):
    with pytest.raises(ValueError, match=r"(overflow|underflow) float64.*Rescale the columns of X"):
        getattr(impute, name)().fit(curve_rows() * factor)


def test_ordinary_units_pass_the_range_check_unchanged():
    from nldr._validation import check_squares_representable

    X = curve_rows()
    mask = ~np.isnan(X)
    for factor in (1e-6, 1e-3, 1.0, 1e3, 1e6):
        check_squares_representable(np.where(mask, X * factor, 0.0), mask, "X")
    X[:, 1] *= 1e-6  # one column in other units
    expected = impute.NearestNeighbourImputer().fit_transform(X) * 1e6
    got = impute.NearestNeighbourImputer().fit_transform(X * 1e6)
    # the same donors; a copied entry goes through the standardisation and back, (x - m) / s * s + m:
    # four roundings, each of half an ulp of at most the column's largest magnitude (45 ulps allowed)
    gap = np.abs(got - expected) / np.nanmax(np.abs(X * 1e6), axis=0)
    assert np.max(gap) <= 1e-14


@pytest.mark.parametrize("name", [n for n in impute.__all__ if n != "DecompositionDenoiser"])
def test_float32_input_comes_back_float64_as_documented(name):
    from protocol import REPO

    estimator = getattr(impute, name)
    X = curve_rows(hidden=0.0 if name == "RobustKernelPCAImputer" else 0.15).astype(np.float32)
    assert estimator().fit_transform(X).dtype == np.float64
    assert "float64" in estimator.transform.__doc__ and "float64" in estimator.fit_transform.__doc__
    guide = (REPO / "docs/user_guide.md").read_text()
    assert "float32" in guide and "returns float64" in guide
