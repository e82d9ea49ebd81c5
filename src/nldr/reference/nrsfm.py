"""Reference paths of the NRSfM solvers, kept to check the fast ones against (tests/, benchmarks/).

:func:`tnh_with_camera_refinement_reference` is Table 4's TNH alternation with its shape steps as first
implemented: every shape step from a plain proximal step (no carried momentum) to the fixed FISTA
tolerance 1e-12 (at most 300 iterations), thresholding by a full SVD. The production
:func:`~nldr.nrsfm.unknown_cameras.tnh_with_camera_refinement` reaches the same fixed point faster
(tests/test_unknown_cameras_speed.py checks it; benchmarks/bench_table4.py times both).
"""

from __future__ import annotations

from ..nrsfm.camera_refinement import CameraShapeResult
from ..nrsfm.svt import soft_threshold_singular_values
from ..nrsfm.unknown_cameras import tnh_with_camera_refinement

__all__ = ["REFERENCE_SHAPE_STEPS", "tnh_with_camera_refinement_reference"]

#: The reference's shape and camera steps, as options of ``tnh_with_camera_refinement``.
REFERENCE_SHAPE_STEPS = dict(
    shape_max_iter=300,
    shape_tol=1e-12,
    shape_tol_ratio=0.0,
    shape_tol_max=1e-12,
    shape_momentum=False,
    camera_max_iter=50,
    callback=None,
    svt=soft_threshold_singular_values,
)


def tnh_with_camera_refinement_reference(
    W2d, mask, R0, tau: float, *, max_outer: int = 20_000, tol: float = 1e-8, window: int = 10
) -> CameraShapeResult:
    """Table 4's TNH alternation with the shape steps as first implemented (see the module docstring).

    The camera step is the production LM (:func:`~nldr.nrsfm.camera_refinement.refine_cameras`), which
    differs from the first one only by rounding and by stopping a frame whose cost no longer changes
    beyond rounding, so this runs faster than the first implementation did. Parameters and result as
    :func:`~nldr.nrsfm.unknown_cameras.tnh_with_camera_refinement`.
    """
    return tnh_with_camera_refinement(
        W2d, mask, R0, tau, max_outer=max_outer, tol=tol, window=window, **REFERENCE_SHAPE_STEPS
    )
