"""Shared fixtures. Real-data tests use $NLDR_DATA_MIRROR (set by .ci/run); when the mirror is set
and a file is missing they fail, never skip. Without a mirror they fall back to ./resources or the
network, and fail with the loader's message if neither has the file."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]

#: Fixtures that read the real data files: a test that uses one is a ``realdata`` test.
REAL_DATA_FIXTURES = frozenset({"data_dir", "oil40"})


def pytest_collection_modifyitems(config, items):
    """Mark every test that reads the real data as ``realdata``, so that ``make test`` (the unit tests,
    ``-m "not pipeline and not realdata"``) needs neither the data nor the network."""
    for item in items:
        if REAL_DATA_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.realdata)


@pytest.fixture(scope="session")
def data_dir(tmp_path_factory) -> Path:
    """A data directory filled on demand from the mirror (or the repository's resources/)."""
    if os.environ.get("NLDR_DATA_MIRROR"):
        return tmp_path_factory.mktemp("resources")
    return REPO / "resources"


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(12345)


def random_rotation(rng) -> np.ndarray:
    """A uniformly random 3x3 rotation (det +1) from a seeded numpy Generator."""
    Q, Rq = np.linalg.qr(rng.standard_normal((3, 3)))
    Q = Q * np.sign(np.diag(Rq))
    return Q if np.linalg.det(Q) > 0 else -Q


# NRSfM test scenes: shapes as rows X (F, 3P), cameras R (F, 2, 3), image tracks W (F, 2P).


def project(R, X) -> np.ndarray:
    """Image tracks (F, 2P) of shapes X (F, 3P) under cameras R (F, 2, 3)."""
    F, P = X.shape[0], X.shape[1] // 3
    return np.einsum("fck,fkp->fcp", R, X.reshape(F, 3, P)).reshape(F, 2 * P)


def nuclear_norm(X) -> float:
    return float(np.linalg.svd(X, compute_uv=False).sum())


def alternate(W2d, mask, R0, shape_step, *, max_outer=20, tol=1e-4, window=1):
    """A shape step ``R (F, 2, 3) -> X (F, 3P)`` alternated with the library's camera LM (100
    iterations a step) until the reprojection error falls by less than ``tol`` (relative) over
    ``window`` iterations: the rigid bundle adjustment of the camera tests, and the kernel alternation
    the joint step is compared with. ``history`` / ``shape_history``: the error after each camera /
    shape step."""
    from types import SimpleNamespace

    from nldr.nrsfm._camera_refinement import camera_lm
    from nldr.nrsfm._reprojection import check_tracks
    from nldr.nrsfm._rotations import camera_to_quaternion, nearest_orthonormal_rows

    W, mask = check_tracks(W2d, mask)
    F, P = mask.shape
    W3 = W.reshape(F, 2, P)
    R = nearest_orthonormal_rows(R0)
    q = camera_to_quaternion(R)
    history, shape_history = [], []
    for k in range(1, max_outer + 1):
        X = shape_step(R.copy())
        S = X.reshape(F, 3, P)
        E = mask[:, None, :] * (W3 - R @ S)
        shape_history.append(float(np.vdot(E, E)))
        q, R, _, cost, _, _, _ = camera_lm(W3, mask, q, S, 100)
        history.append(float(cost.sum()))
        if k > window and history[-1 - window] - history[-1] < tol * history[-1 - window]:
            break
    return SimpleNamespace(x=X, R=R, nit=k, history=np.array(history), shape_history=np.array(shape_history))


def curve_rows(n=24, seed=0, hidden=0.15):
    """Rows near a 1-d curve in 4 columns, ``hidden`` of the entries NaN (every column observed)."""
    rng = np.random.default_rng(seed)
    t = rng.uniform(0.0, 3.0, n)
    X = np.column_stack([t, np.sin(t), np.cos(t), t**2 / 3]) + 0.01 * rng.standard_normal((n, 4))
    X[rng.random(X.shape) < hidden] = np.nan
    return X


def synthetic_sequence(n_frames=12, n_points=9, rank=2, seed=0):
    """Shapes from a rank-`rank` linear basis around a mean shape, random rotation cameras, exact tracks.

    Returns (X (F, 3P), W (F, 2P), R (F, 2, 3))."""
    rng = np.random.default_rng(seed)
    basis = rng.standard_normal((rank + 1, 3 * n_points))
    coeffs = np.column_stack([np.ones(n_frames), 0.5 * rng.standard_normal((n_frames, rank))])
    X = coeffs @ basis
    R = np.stack([random_rotation(rng)[:2] for _ in range(n_frames)])
    return X, project(R, X), R


def denoising_problem(n=60, d=10, seed=1, hidden_share=1 / 3):
    """Rows on a smooth 2-d manifold in [0, 1]^d plus Gaussian noise; a third of the entries hidden."""
    rng = np.random.default_rng(seed)
    t = rng.random((n, 2))
    X = 0.5 + 0.5 * np.sin(t @ (3 * rng.normal(size=(2, d))) + 2 * np.pi * rng.random(d))
    Y = X + 0.1 * rng.normal(size=X.shape)
    mask = rng.random(X.shape) >= hidden_share
    return X, np.where(mask, Y, np.nan), mask


def within_observed_range(S, W, mask):
    """Hidden entries inside [min - spread, max + spread] of their column's observed values."""
    obs = np.where(mask, W, np.nan)
    low, high = np.nanmin(obs, axis=0), np.nanmax(obs, axis=0)
    spread = high - low
    inside = (S >= low - spread) & (S <= high + spread)
    return bool(np.all(inside[~mask]))
