"""The kernel regularizer with cameras and shapes optimised jointly (Table 4's kernel stage, issue 17).

The paper's energy with unknown cameras is, for every penalty weight rho of Algorithm 1,

    E_rho(R, S) = sum_f sum_j mask_fj ||w_f(x_j) - R_f s_f(x_j)||^2 + min_C [rho/2 ||K(S) - C^T C||_F^2
                  + tau ||C||_*]                                                              (1)

with K the RBF kernel over the frames' shapes s_f (rows of S, F x 3P). Alternating the camera LM with
the shape step (:func:`~nldr.nrsfm.unknown_cameras.kernel_with_camera_refinement`) leaves the cameras
where they start: at the paper's tau = 1e-4 the shape step fits the tracks to 1e-9, so the reprojection
error the LM sees is already zero at any cameras. The regularizer's pull on the cameras only shows
when the cameras and the depths move together, which a block-coordinate scheme cannot do.

Change of variables. Complete every camera to a rotation Q_f = [R_f; r_f1 x r_f2] (3 x 3) and write the
shape in the camera's frame, Z_f = Q_f s_f (3 x P): its first two rows are the predicted image points,
its third the depths. Then R_f s_f = Z_f[:2] and (1) becomes

    E_rho(Q, Z) = sum_f ||mask_f o (W_f - Z_f[:2])||^2 + reg_rho(S),  S_f = Q_f^T Z_f,           (2)

the same energy in new coordinates (a bijection), in which a camera can turn while the image fit
stays as it is (the depths follow). :func:`joint_value_grad` evaluates (2) and its gradient with Q_f =
A(q_f) Q0_f, A(q) the rotation of the quaternion q / |q| (a local parametrisation around Q0, q = (1, 0,
0, 0) at the start); :func:`kernel_joint_cameras_shapes` minimises it by L-BFGS over (Z, q), one
penalty stage per rho as :func:`~nldr.regularizer.minimize_regularized` does, re-centring the
rotations after every stage. Gradient of the regularizer in S: the envelope theorem
(:mod:`nldr._reduced`); with G_f = d reg / d s_f (3 x P): dE/dZ_f = Q_f G_f and dE/dQ_f = Z_f G_f^T.

Scaling (issue 16). In (2) the observed image coordinates carry the data term's curvature 2, while the
depths, the unobserved image coordinates and the quaternions see only the regularizer's, 1e-6 to 1e-3
for Table 4's sequences (it grows with rho): a condition number of 1e3 to 1e6 between the blocks, on
which plain L-BFGS needed 4.5k-15k iterations per width and often hit its limit in the first stage.
With ``precondition=True`` every stage runs L-BFGS on u = v / D (a change of variables, the same
minimisers) with D = 1 on the observed image coordinates and sqrt((2 + c_z) / c_z), sqrt((2 + c_z) / c_q)
on the other coordinates and on the quaternions, c_z and c_q the curvatures of the stage's energy along
its gradient restricted to each block (:func:`block_curvature`, a difference of two gradients).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .._reduced import RankHint, lbfgs_minimize, reduced_value_grad
from .._threads import blas_threads_for
from .._validation import check_count, check_positive
from ..regularizer import isolation_safe_rho0, penalty_schedule
from ..result import SolverResult, status_from
from .reprojection import check_cameras, check_shapes, check_tracks
from .rotations import nearest_orthonormal_rows

__all__ = [
    "JointKernelResult",
    "complete_rotations",
    "quaternion_rotation",
    "joint_value_grad",
    "joint_energy",
    "block_curvature",
    "kernel_joint_cameras_shapes",
]


class _NoData:
    """A zero data term of the given shape (the reprojection error of (2) is added separately)."""

    def __init__(self, shape):
        self.shape = shape

    def value(self, S):
        return 0.0

    def gradient(self, S):
        return np.zeros(self.shape)


def complete_rotations(R) -> np.ndarray:
    """Rotations Q (F, 3, 3) whose first two rows are the cameras R (F, 2, 3) made orthonormal and
    whose third row is their cross product (det Q = +1)."""
    R = nearest_orthonormal_rows(check_cameras(R))
    return np.concatenate([R, np.cross(R[:, 0], R[:, 1])[:, None]], axis=1)


def quaternion_rotation(q, jacobian: bool = False):
    """Rotation matrices A(q) (F, 3, 3) of the quaternions q / |q| (q: (F, 4), (w, x, y, z), any
    non-zero length) and, if ``jacobian``, dA/dq (F, 3, 3, 4)."""
    q = np.asarray(q, dtype=float)
    w, x, y, z = q.T
    n = np.einsum("fi,fi->f", q, q)
    H = np.stack(
        [
            np.stack([w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], -1),
        ],
        axis=1,
    )  # (F, 3, 3), H = |q|^2 A
    A = H / n[:, None, None]
    if not jacobian:
        return A, None
    # dH/dq: every entry of H is a quadratic form in q; its derivative is linear in q
    dH = np.empty(H.shape + (4,))
    dH[:, 0, 0] = 2 * np.stack([w, x, -y, -z], -1)
    dH[:, 0, 1] = 2 * np.stack([-z, y, x, -w], -1)
    dH[:, 0, 2] = 2 * np.stack([y, z, w, x], -1)
    dH[:, 1, 0] = 2 * np.stack([z, y, x, w], -1)
    dH[:, 1, 1] = 2 * np.stack([w, -x, y, -z], -1)
    dH[:, 1, 2] = 2 * np.stack([-x, -w, z, y], -1)
    dH[:, 2, 0] = 2 * np.stack([-y, z, -w, x], -1)
    dH[:, 2, 1] = 2 * np.stack([x, w, z, y], -1)
    dH[:, 2, 2] = 2 * np.stack([w, -x, -y, z], -1)
    # d(H / n) = dH / n - H (2 q^T) / n^2
    J = dH / n[:, None, None, None] - A[..., None] * (2 * q / n[:, None])[:, None, None, :]
    return A, J


def joint_value_grad(Z, q, Q0, W3, m3, gamma, tau, rho, center=False, hint=None):
    """Energy (2) of the module docstring and its gradients; no validation.

    Parameters
    ----------
    Z : array (F, 3, P)
        Shapes in the cameras' frames.
    q : array (F, 4)
        Local quaternions: Q_f = A(q_f) Q0_f.
    Q0 : array (F, 3, 3)
        Reference rotations.
    W3 : array (F, 2, P)
        Tracks, zero where unobserved.
    m3 : array (F, 1, P)
        Visibility as 0/1 weights.
    gamma, tau, rho : float
    center : bool

    Returns
    -------
    value : float
    grad_Z : array (F, 3, P)
    grad_q : array (F, 4)
    """
    F, _, P = Z.shape
    A, dA = quaternion_rotation(q, jacobian=True)
    Q = A @ Q0
    S = Q.transpose(0, 2, 1) @ Z  # (F, 3, P), s_f = Q_f^T z_f
    reg, G, _ = reduced_value_grad(
        S.reshape(F, 3 * P), _NoData((F, 3 * P)), gamma, tau, rho, center, "auto", hint
    )
    G = G.reshape(F, 3, P)
    E = m3 * (W3 - Z[:, :2])
    value = float(np.vdot(E, E)) + float(reg)
    grad_Z = Q @ G
    grad_Z[:, :2] -= 2 * E
    grad_Q = Z @ G.transpose(0, 2, 1)  # dE/dQ_f = Z_f G_f^T
    grad_A = grad_Q @ Q0.transpose(0, 2, 1)
    grad_q = np.einsum("fij,fijk->fk", grad_A, dA)
    return value, grad_Z, grad_q


def joint_energy(W2d, mask, R, X, *, gamma: float, tau: float, rho: float, center: bool = False) -> float:
    """The paper's energy (1) at cameras R (F, 2, 3) and shapes X (F, 3P): reprojection error over the
    observed points plus the regularizer with C eliminated in closed form, at penalty weight rho.
    Comparable across solvers that end their schedules at the same rho (used to choose between the
    alternation and the joint step without ground truth)."""
    W, vis = check_tracks(W2d, mask)
    F, P = vis.shape
    X = check_shapes(X, F, P)
    Q = complete_rotations(check_cameras(R, F))
    Z = Q @ X.reshape(F, 3, P)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (F, 1))
    value, _, _ = joint_value_grad(
        Z, q, Q, W.reshape(F, 2, P), vis[:, None, :].astype(float), check_positive(gamma, "gamma"),
        check_positive(tau, "tau"), check_positive(rho, "rho"), bool(center),
    )  # fmt: skip
    return value


def block_curvature(value_grad, v, grad, block, step: float) -> float:
    """Curvature d^T H d / d^T d of ``value_grad`` at v along d = ``grad`` restricted to ``block``.

    By a forward difference of gradients, (g(v + h d) - g(v)) . d / h with |d| = 1 and h = ``step``
    (exact for a quadratic up to rounding); 0.0 if the gradient vanishes on the block.

    Parameters
    ----------
    value_grad : callable v -> (value, gradient)
    v, grad : array (n,)
        The point and the gradient there.
    block : bool array (n,)
    step : float > 0

    Returns
    -------
    float (may be <= 0 where the energy is not convex along d)
    """
    d = np.where(block, grad, 0.0)
    norm = float(np.linalg.norm(d))
    if norm == 0.0:
        return 0.0
    d /= norm
    return float((value_grad(v + step * d)[1] - grad) @ d) / step


def _stage_scaling(value_grad, v, observed, n_z, max_ratio=1e6):
    """The diagonal D of the module docstring's scaling at v (observed: bool (n_z,)); curvatures are
    floored at 2 / max_ratio (so no entry of D exceeds about sqrt(max_ratio))."""
    _, grad = value_grad(v)
    z_block = np.zeros(v.size, dtype=bool)
    z_block[:n_z] = ~observed
    q_block = np.zeros(v.size, dtype=bool)
    q_block[n_z:] = True
    z_scale = float(np.sqrt(np.mean(v[:n_z] ** 2))) or 1.0
    floor = 2.0 / max_ratio
    c_z = max(block_curvature(value_grad, v, grad, z_block, 1e-6 * z_scale), floor)
    c_q = max(block_curvature(value_grad, v, grad, q_block, 1e-6), floor)
    D = np.empty(v.size)
    D[:n_z] = np.where(observed, 1.0, np.sqrt((2.0 + c_z) / c_z))
    D[n_z:] = np.sqrt((2.0 + c_z) / c_q)
    return D


@dataclass(kw_only=True, repr=False)
class JointKernelResult(SolverResult):
    """Result of :func:`kernel_joint_cameras_shapes` (a :class:`~nldr.result.SolverResult`).

    Attributes
    ----------
    x : array (F, 3P)
        Shapes (world frame, as rows).
    R : array (F, 2, 3)
        Cameras.
    fun : float
        Energy (1) at the last rho.
    stage_energy : array (n_stages,)
        Energy at the end of every penalty stage (at its rho).
    rho_history : array (n_stages,)
    reprojection : float
        Sum of squared reprojection errors over the observed points at the end.
    """

    R: np.ndarray
    stage_energy: np.ndarray
    rho_history: np.ndarray
    reprojection: float


def kernel_joint_cameras_shapes(
    W2d,
    mask,
    R0,
    X0,
    *,
    gamma: float,
    tau: float,
    rho0: float = 1e-3,
    rho_growth: float = 10.0,
    rho_max: float = 10.0,
    center: bool = False,
    max_inner: int = 3000,
    tol: float = 1e-10,
    gtol: float = 1e-6,
    isolation_guard: bool = True,
    precondition: bool = True,
) -> JointKernelResult:
    """Minimise the paper's energy (1) over cameras and shapes together, by the penalty method.

    For rho = rho0, rho0 rho_growth, ... <= rho_max (as :func:`~nldr.regularizer.minimize_regularized`,
    isolation guard included), L-BFGS on (2) of the module docstring over the camera-frame shapes Z
    and local quaternions q, from the previous stage's cameras and shapes.

    Parameters
    ----------
    W2d : array (F, 2P)
        Centred image tracks as rows.
    mask : bool array (F, P) or None
    R0 : array (F, 2, 3)
        Starting cameras (e.g. the tuned TNH's).
    X0 : array (F, 3P)
        Starting shapes (e.g. the tuned TNH's).
    gamma, tau : float > 0
        RBF inverse squared width and trace-norm weight.
    rho0, rho_growth, rho_max : float
        Penalty schedule (:func:`~nldr.regularizer.penalty_schedule`).
    center : bool, default False
        Double-centre the kernel.
    max_inner : int, default 3000
        L-BFGS iterations per stage.
    tol, gtol : float > 0
        L-BFGS's relative energy decrease and gradient tolerances.
    isolation_guard : bool, default True
        As in :func:`~nldr.regularizer.minimize_regularized`.
    precondition : bool, default True
        Scale the blocks as the module docstring's "Scaling" (False: L-BFGS on (Z, q) as they are,
        the implementation before issue 16; tol and gtol then apply to unscaled gradients).

    Returns
    -------
    JointKernelResult
    """
    start = time.perf_counter()
    W, vis = check_tracks(W2d, mask)
    F, P = vis.shape
    Q = complete_rotations(check_cameras(R0, F, name="R0"))
    X0 = check_shapes(X0, F, P, name="X0")
    gamma, tau = check_positive(gamma, "gamma"), check_positive(tau, "tau")
    floor = isolation_safe_rho0(tau) if isolation_guard else None
    rhos = penalty_schedule(rho0, rho_growth, rho_max, floor=floor)
    max_inner = check_count(max_inner, "max_inner")
    tol, gtol = check_positive(tol, "tol"), check_positive(gtol, "gtol")
    W3, m3 = W.reshape(F, 2, P), vis[:, None, :].astype(float)
    Z = Q @ X0.reshape(F, 3, P)
    identity = np.tile([1.0, 0.0, 0.0, 0.0], (F, 1))
    n_z = Z.size
    observed = np.zeros((F, 3, P), dtype=bool)
    observed[:, :2] = vis[:, None, :]
    observed = observed.ravel()
    hint = RankHint()
    stage_energy, failures, nit = [], [], 0
    with blas_threads_for(F):  # one BLAS thread on small problems (nldr._threads)
        for rho in rhos:

            def value_grad(v, Q=Q, rho=rho):
                value, gZ, gq = joint_value_grad(
                    v[:n_z].reshape(F, 3, P), v[n_z:].reshape(F, 4), Q, W3, m3, gamma, tau, rho, center, hint
                )
                return value, np.concatenate([gZ.ravel(), gq.ravel()])

            v0 = np.concatenate([Z.ravel(), identity.ravel()])
            D = _stage_scaling(value_grad, v0, observed, n_z) if precondition else np.ones(v0.size)

            def scaled(u, D=D, value_grad=value_grad):
                value, grad = value_grad(D * u)
                return value, D * grad

            u, stage_nit, ok, why = lbfgs_minimize(scaled, v0 / D, max_inner, tol, gtol, [])
            v = D * u
            nit += stage_nit
            if not ok:
                failures.append(f"rho={rho:g}: {why}")
            stage_energy.append(value_grad(v)[0])
            Z = v[:n_z].reshape(F, 3, P).copy()
            Q = quaternion_rotation(v[n_z:].reshape(F, 4))[0] @ Q  # re-centre: q back to the identity
    X = (Q.transpose(0, 2, 1) @ Z).reshape(F, 3 * P)
    E = m3 * (W3 - Z[:, :2])
    if failures:
        message = "iteration limit reached in " + "; ".join(failures)
    else:
        message = f"all {len(rhos)} penalty stages converged (rho {rhos[0]:g} to {rhos[-1]:g})"
    return JointKernelResult(
        x=X,
        fun=float(stage_energy[-1]),
        status=status_from(not failures),
        message=message,
        nit=nit,
        wall_time=time.perf_counter() - start,
        R=Q[:, :2].copy(),
        stage_energy=np.asarray(stage_energy),
        rho_history=np.asarray(rhos, dtype=float),
        reprojection=float(np.vdot(E, E)),
    )
