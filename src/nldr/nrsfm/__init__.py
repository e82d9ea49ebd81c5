"""Non-rigid structure from motion (paper Section 4.3): layouts, e3D metric, reprojection term, TNH,
camera estimation.

Known cameras (Table 3): :func:`trace_norm_heuristic` is the one entry point of TNH (the trace-norm
heuristic, eq. 12), exact-fit by ADMM (default), penalised by FISTA, or through cvxpy (optional
dependency) as the reference; it returns a :class:`TNHResult`.

Unknown cameras (Table 4): :func:`initialize_cameras` (rigid factorisation,
:mod:`nldr.nrsfm.factorization`), :func:`tnh_with_camera_refinement` and :func:`tune_tau`
(:mod:`nldr.nrsfm.unknown_cameras`; the kernel stage with cameras and shapes optimised jointly in
:mod:`nldr.nrsfm.joint_kernel`) on top of the camera LM and the shape/camera alternation
(:mod:`nldr.nrsfm.camera_refinement`, :mod:`nldr.nrsfm.rotations`), and :func:`tnh_camera_search`
(:mod:`nldr.nrsfm.camera_search`: cameras that break the motion re-seated, kept where TNH's energy
drops); evaluation up to the global gauge by :func:`e3d` (``align=True``) and :func:`camera_error`.
With known cameras L-BFGS runs best in :class:`CameraFrameVariables` (each point in its camera's
frame, the unheld directions scaled).

Parameters from the tracks alone (:mod:`nldr.nrsfm.selection`): :func:`select_tnh_tau` and
:func:`select_kernel` choose TNH's tau and the kernel method's tau and width by hold-out
reprojection error on hidden 2D points (:func:`visibility_folds`), never by the 3D ground truth.

Shapes are samples as rows, X (F, 3P); image tracks W (F, 2P); cameras R (F, 2, 3); visibility
masks (F, P). See :mod:`nldr.nrsfm.layout` for conversions from the benchmark's stacked matrices.
Every solver result derives from :class:`nldr.result.SolverResult` (``x``, ``fun``, ``success``,
``status``, ``message``, ``nit``, ``wall_time``).
"""

from .camera_refinement import CameraShapeResult, refine_cameras_and_shapes
from .camera_search import CameraSearchResult, tnh_camera_search
from .factorization import initialize_cameras
from .joint_kernel import JointKernelResult, joint_energy, kernel_joint_cameras_shapes
from .kernel_selection import KernelSelection, select_kernel
from .layout import (
    cameras_from_stack,
    cameras_to_stack,
    random_visibility_mask,
    rows_to_stack,
    stack_to_rows,
)
from .metrics import (
    camera_error,
    center_per_frame,
    e3d,
    e3d_per_frame,
    global_camera_alignment,
    ground_truth_sigma,
    procrustes_rotation,
)
from .reprojection import OrthographicReprojection
from .selection import (
    TNHTauSelection,
    holdout_reprojection_error,
    select_tnh_tau,
    visibility_folds,
)
from .tnh import TNHResult, TNHSolveError, trace_norm_heuristic
from .unknown_cameras import (
    TauSearchResult,
    kernel_with_camera_refinement,
    tnh_with_camera_refinement,
    tune_tau,
)
from .variables import CameraFrameVariables

__all__ = [
    "CameraFrameVariables",
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
    "global_camera_alignment",
    "camera_error",
    "OrthographicReprojection",
    "trace_norm_heuristic",
    "TNHResult",
    "TNHSolveError",
    "initialize_cameras",
    "refine_cameras_and_shapes",
    "CameraShapeResult",
    "tnh_with_camera_refinement",
    "kernel_with_camera_refinement",
    "kernel_joint_cameras_shapes",
    "joint_energy",
    "JointKernelResult",
    "tune_tau",
    "TauSearchResult",
    "tnh_camera_search",
    "CameraSearchResult",
    "visibility_folds",
    "holdout_reprojection_error",
    "select_tnh_tau",
    "TNHTauSelection",
    "select_kernel",
    "KernelSelection",
]
