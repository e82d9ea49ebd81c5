"""Non-rigid structure from motion (paper Section 4.3).

:func:`reconstruct` is the one entry point of reconstruction (:mod:`nldr.nrsfm.reconstruct`): known
or estimated cameras, the trace-norm heuristic or the kernel regularizer, squared or robust loss; it
returns a :class:`Reconstruction`. :func:`trace_norm_heuristic` is TNH with known cameras and a choice
of solver. Energies: :func:`reprojection_error`, :func:`tnh_energy`, :func:`kernel_energy`; evaluation
up to the global gauge: :func:`e3d` and :func:`camera_error`. Parameters from the tracks alone:
:func:`select_tnh_tau` and :func:`select_kernel` (hold-out reprojection error on hidden 2D points,
:func:`visibility_folds`). Layouts (:mod:`nldr.nrsfm.layout`): shapes as rows X (F, 3P), tracks W
(F, 2P), cameras R (F, 2, 3), visibility masks (F, P). Every solver result derives from
:class:`nldr.result.SolverResult`.
"""

from .factorization import initialize_cameras
from .joint_kernel import kernel_energy
from .layout import random_visibility_mask, stack_to_rows, visibility_folds
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
from .rotations import CameraFrameVariables
from .selection import NRSfMSelection, select_kernel, select_tnh_tau
from .tnh import TNHResult, TNHSolveError

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
    "NRSfMSelection",
    "select_kernel",
]
