"""Non-rigid structure from motion (paper Section 4.3).

:func:`reconstruct` is the one entry point of reconstruction: known or estimated cameras, TNH or the
kernel regularizer, squared or robust loss (:func:`trace_norm_heuristic`: TNH with known cameras and a
choice of solver). Energies: :func:`reprojection_error`, :func:`tnh_energy`, :func:`kernel_energy`;
evaluation up to the global gauge: :func:`e3d`, :func:`camera_error`; parameters from the tracks alone:
:func:`select_tnh_tau`, :func:`select_kernel`. Layouts: :mod:`nldr.nrsfm._layout`.
"""

from ._factorization import initialize_cameras
from ._joint_kernel import kernel_energy
from ._layout import random_visibility_mask, stack_to_rows, visibility_folds
from ._metrics import (
    camera_error,
    center_per_frame,
    e3d,
    e3d_per_frame,
    global_camera_alignment,
    ground_truth_sigma,
    procrustes_rotation,
)
from ._reconstruct import Reconstruction, reconstruct, trace_norm_heuristic
from ._reprojection import OrthographicReprojection, reprojection_error, tnh_energy
from ._rotations import CameraFrameVariables
from ._selection import NRSfMSelection, select_kernel, select_tnh_tau
from ._tnh import TNHResult, TNHSolveError

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
