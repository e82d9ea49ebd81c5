"""Non-rigid structure from motion (paper Section 4.3).

:func:`reconstruct` is the one entry point of reconstruction: known or estimated cameras, TNH or the
kernel regularizer, squared or robust loss; tracks come first, ``reconstruct(W2d, visible, ...)``.
The fit: :func:`reprojection_error`; evaluation up to the global gauge: :func:`e3d`,
:func:`camera_error`; parameters from the tracks alone: :func:`select_tnh_tau`, :func:`select_kernel`;
layouts: :func:`stack_to_rows`, :func:`random_visibility_mask`.
"""

from ._factorization import initialize_cameras
from ._layout import random_visibility_mask, stack_to_rows
from ._metrics import camera_error, center_per_frame, e3d
from ._reconstruct import Reconstruction, reconstruct
from ._reprojection import OrthographicReprojection, reprojection_error
from ._rotations import CameraFrameVariables
from ._selection import NRSfMSelection, select_kernel, select_tnh_tau
from ._tnh import TNHResult, TNHSolveError

__all__ = [
    "reconstruct",
    "Reconstruction",
    "TNHResult",
    "TNHSolveError",
    "initialize_cameras",
    "OrthographicReprojection",
    "CameraFrameVariables",
    "reprojection_error",
    "stack_to_rows",
    "random_visibility_mask",
    "e3d",
    "center_per_frame",
    "camera_error",
    "select_tnh_tau",
    "NRSfMSelection",
    "select_kernel",
]
