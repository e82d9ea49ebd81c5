"""Reference paths of the NRSfM solvers, kept to check the fast ones against (tests/, benchmarks/).

:func:`tnh_with_camera_refinement_reference` is Table 4's TNH alternation with its shape steps as first
implemented: every shape step from a plain proximal step (no carried momentum) to the fixed FISTA
tolerance 1e-12 (at most 300 iterations), thresholding by a full SVD. The production
:func:`~nldr.nrsfm._camera_refinement.tnh_with_camera_refinement` reaches the same fixed point faster
(tests/test_unknown_cameras_speed.py checks it; benchmarks/bench_table4.py times both).
"""

from __future__ import annotations

from ..nrsfm._camera_refinement import CameraShapeResult, tnh_alternation
from ..nrsfm._tnh import soft_threshold_singular_values

__all__ = ["tnh_with_camera_refinement_reference"]


def tnh_with_camera_refinement_reference(
    W2d, mask, R0, tau: float, *, max_outer: int = 20_000, tol: float = 1e-8, window: int = 10, X0=None
) -> CameraShapeResult:
    """Table 4's TNH alternation with the shape steps as first implemented (see the module docstring).

    The camera step is the production LM (:func:`~nldr.nrsfm._camera_refinement.camera_lm`), which
    differs from the first one only by rounding and by stopping a frame whose cost no longer changes
    beyond rounding. Parameters and result as
    :func:`~nldr.nrsfm._camera_refinement.tnh_with_camera_refinement`.
    """
    return tnh_alternation(
        W2d, mask, R0, tau, max_outer, tol, window, X0,
        shape_tol=(1e-12, 0.0, 1e-12), momentum=False, svt=soft_threshold_singular_values,
    )  # fmt: skip
