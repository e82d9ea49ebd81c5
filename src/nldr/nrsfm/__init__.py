"""Non-rigid structure from motion (paper Section 4.3): layouts, e3D metric, reprojection term, TNH,
camera estimation, the kernel regularizer with known or estimated cameras.

:func:`reconstruct` is the one entry point of reconstruction: known cameras (Table 3) or
``cameras="estimate"`` (Table 4: rigid factorisation, then cameras refined with the shapes), the
trace-norm heuristic (``prior="tnh"``) or the kernel regularizer (``prior="kernel"``, from a TNH
start), squared or Huber reprojection error; it returns a :class:`Reconstruction`. Underneath,
:func:`trace_norm_heuristic` solves TNH with known cameras (``method=``: ADMM exact fit, FISTA, cvxpy
as the reference), :mod:`nldr.nrsfm.camera_refinement` alternates TNH with the camera LM,
:mod:`nldr.nrsfm.camera_search` re-seats cameras that break the motion, and
:mod:`nldr.nrsfm.joint_kernel` optimises cameras and shapes jointly in the regularizer's penalty
method. Energies: :func:`reprojection_error`, :func:`tnh_energy`, :func:`kernel_energy`. Evaluation
up to the global gauge by :func:`e3d` (``align=True``) and :func:`camera_error`. With known cameras
L-BFGS runs best in :class:`CameraFrameVariables` (each point in its camera's frame, the unheld
directions scaled).

Parameters from the tracks alone (:mod:`nldr.nrsfm.selection`): :func:`select_tnh_tau` and
:func:`select_kernel` choose TNH's tau and the kernel method's tau and width by hold-out
reprojection error on hidden 2D points (:func:`visibility_folds`), never by the 3D ground truth.

Shapes are samples as rows, X (F, 3P); image tracks W (F, 2P); cameras R (F, 2, 3); visibility
masks (F, P). See :mod:`nldr.nrsfm.layout` for conversions from the benchmark's stacked matrices.
Every solver result derives from :class:`nldr.result.SolverResult` (``x``, ``fun``, ``success``,
``status``, ``message``, ``nit``, ``wall_time``).
"""

from .factorization import initialize_cameras
from .joint_kernel import kernel_energy
from .layout import (
    cameras_from_stack,
    cameras_to_stack,
    random_visibility_mask,
    rows_to_stack,
    stack_to_rows,
    visibility_folds,
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
from .reconstruct import Reconstruction, reconstruct, trace_norm_heuristic
from .reprojection import OrthographicReprojection, reprojection_error, tnh_energy
from .selection import KernelSelection, TNHTauSelection, select_kernel, select_tnh_tau
from .tnh import TNHResult, TNHSolveError
from .variables import CameraFrameVariables

__all__ = [
    "reconstruct",
    "Reconstruction",
    "trace_norm_heuristic",
    "TNHResult",
    "TNHSolveError",
    "initialize_cameras",
    "OrthographicReprojection",
    "CameraFrameVariables",
    "reprojection_error",
    "tnh_energy",
    "kernel_energy",
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
    "visibility_folds",
    "select_tnh_tau",
    "TNHTauSelection",
    "select_kernel",
    "KernelSelection",
]
