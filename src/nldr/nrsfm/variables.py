"""A change of variables for L-BFGS on NRSfM shapes with known (or fixed) orthographic cameras.

:class:`CameraFrameVariables` maps each 3D point into its frame's camera coordinates and scales the
directions the data term does not hold. It is what ``minimize_regularized(variables=...)`` takes
(docs/REPRODUCTION.md#table-3-solver).
"""

from __future__ import annotations

import numpy as np

from .._validation import check_positive
from .rotations import complete_rotations

__all__ = ["CameraFrameVariables"]


class CameraFrameVariables:
    """Each 3D point in its frame's camera coordinates, the unheld ones scaled: a preconditioner.

    With known orthographic cameras the data term holds a point's two image coordinates with
    curvature 2 and leaves its depth (and all three coordinates of an unobserved point) to the
    regularizer, whose curvature is smaller by orders of magnitude (tau = 1e-4): L-BFGS on S then
    needs thousands of iterations per penalty stage. In the variables Y, point j of frame f is
    ``s_fj = Q_f^T D_fj y_fj`` with ``Q_f = [R_f; r_f1 x r_f2]`` (a rotation for orthonormal
    cameras) and ``D_fj = diag(1, 1, depth_scale)`` if observed, ``depth_scale I`` if not: the
    unheld directions move ``depth_scale`` times further per unit step, which brings their
    curvature towards the data term's. The map is linear and invertible, so the minimisers are
    the same; only the path of the solver changes (docs/REPRODUCTION.md#table-3-solver). The
    methods take and return arrays of shape (F, 3P), shapes as rows (x_1..x_P, y_1..y_P, z_1..z_P).

    Parameters
    ----------
    R : array, shape (F, 2, 3)
        Orthographic cameras (rows independent).
    mask : bool array, shape (F, P)
        True where the point is observed.
    depth_scale : float > 0
        Scale of the unheld directions (1: only the rotation).
    """

    def __init__(self, R, mask, depth_scale: float):
        Q = complete_rotations(R, project=False)  # (F, 3, 3)
        mask = np.asarray(mask, dtype=bool)
        if mask.ndim != 2 or mask.shape[0] != Q.shape[0]:
            raise ValueError(f"mask must have shape (F, P) with F = {Q.shape[0]}; got {mask.shape}")
        if np.any(np.abs(np.linalg.det(Q)) < 1e-12):
            raise ValueError("R has a camera with two dependent rows; the change of variables needs a basis")
        scale = np.ones((R.shape[0], 3, mask.shape[1]))
        scale[:, 2, :] = check_positive(depth_scale, "depth_scale")
        scale[~np.broadcast_to(mask[:, None, :], scale.shape)] = depth_scale
        self._Q, self._Qinv_T, self._scale = Q, np.linalg.inv(Q).transpose(0, 2, 1), scale
        self._shape = scale.shape

    def to_samples(self, Y):
        """S = A(Y): ``s_fj = Q_f^T D_fj y_fj``."""
        Y = np.asarray(Y).reshape(self._shape)
        return np.einsum("fck,fcj->fkj", self._Q, self._scale * Y).reshape(self._shape[0], -1)

    def to_variables(self, S):
        """Y = A^-1(S)."""
        S = np.asarray(S).reshape(self._shape)
        return (np.einsum("fck,fkj->fcj", self._Qinv_T, S) / self._scale).reshape(self._shape[0], -1)

    def gradient_to_variables(self, G):
        """A^T(G): the gradient in Y of a function whose gradient in S is G."""
        G = np.asarray(G).reshape(self._shape)
        return (self._scale * np.einsum("fck,fkj->fcj", self._Q, G)).reshape(self._shape[0], -1)
