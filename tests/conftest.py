"""Shared fixtures. Real-data tests use $NLDR_DATA_MIRROR (set by .ci/run); when the mirror is set
and a file is missing they fail, never skip. Without a mirror they fall back to ./resources or the
network, and fail with the loader's message if neither has the file."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


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
