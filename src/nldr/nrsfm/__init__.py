"""Non-rigid structure from motion (paper Section 4.3): layouts, e3D metric, reprojection term, TNH.

TNH (the trace-norm heuristic) is solved by cvxpy (:class:`TraceNormHeuristic`) or, in its exact-fit
form and for full-length sequences, by ADMM (:func:`tnh_admm`).

Shapes are samples as rows, X (F, 3P); image tracks W (F, 2P); cameras R (F, 2, 3); visibility
masks (F, P). See :mod:`nldr.nrsfm.layout` for conversions from the benchmark's stacked matrices.
"""

from .admm import tnh_admm
from .layout import (
    cameras_from_stack,
    cameras_to_stack,
    random_visibility_mask,
    rows_to_stack,
    stack_to_rows,
)
from .metrics import center_per_frame, e3d, e3d_per_frame, ground_truth_sigma, procrustes_rotation
from .reprojection import OrthographicReprojection
from .tnh import TNHResult, TNHSolveError, TraceNormHeuristic, trace_norm_heuristic

__all__ = [
    "stack_to_rows",
    "rows_to_stack",
    "cameras_from_stack",
    "cameras_to_stack",
    "random_visibility_mask",
    "e3d",
    "e3d_per_frame",
    "ground_truth_sigma",
    "center_per_frame",
    "procrustes_rotation",
    "OrthographicReprojection",
    "TraceNormHeuristic",
    "TNHResult",
    "TNHSolveError",
    "trace_norm_heuristic",
    "tnh_admm",
]
