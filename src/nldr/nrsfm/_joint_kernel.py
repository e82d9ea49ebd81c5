"""The kernel regularizer with cameras and shapes optimised jointly (Table 4's kernel stage).

The paper's energy with unknown cameras is, for every penalty weight rho of Algorithm 1,

    E_rho(R, S) = sum_f sum_j mask_fj ||w_f(x_j) - R_f s_f(x_j)||^2 + min_C [rho/2 ||K(S) - C^T C||_F^2
                  + tau ||C||_*]                                                              (1)

with K the RBF kernel over the frames' shapes s_f (rows of S, F x 3P); with a Huber loss the squared
reprojection error becomes sum h_delta over the image coordinates (:func:`nldr.data_terms.huber_loss`).
Alternating the camera LM with a kernel shape step leaves the cameras where they start (at tau = 1e-4
the shape step fits the tracks, so the LM sees no error to reduce; docs/REPRODUCTION.md#table-4-tnh):
the regularizer's pull on the cameras only shows when cameras and depths move together.

Change of variables. Complete every camera to a rotation Q_f = [R_f; r_f1 x r_f2] and write the shape
in the camera's frame, Z_f = Q_f s_f (3 x P): its first two rows are the predicted image points, its
third the depths. Then (1) becomes

    E_rho(Q, Z) = sum_f ||mask_f o (W_f - Z_f[:2])||^2 + reg_rho(S),  S_f = Q_f^T Z_f,           (2)

in which a camera can turn while the image fit stays (the depths follow). :func:`joint_value_grad`
evaluates (2) and its gradient with Q_f = A(q_f) Q0_f (A(q) the rotation of q / |q|, q = (1, 0, 0, 0) at
the start); :func:`solve_joint_kernel` minimises it by L-BFGS over (Z, q), one stage per rho of the
regularizer's penalty method (:func:`~nldr._penalty.penalty_method`), re-centring the rotations
after every stage. Gradient in S by the envelope theorem (:mod:`nldr._reduced`); with G_f = d reg /
d s_f: dE/dZ_f = Q_f G_f and dE/dQ_f = Z_f G_f^T.

Scaling. The observed image coordinates carry the data term's curvature 2, the depths, unobserved
coordinates and quaternions only the regularizer's (orders of magnitude smaller). Every stage runs
L-BFGS on u = v / D (the same minimisers) with D = 1 on the observed image coordinates and
sqrt((2 + c_z) / c_z), sqrt((2 + c_z) / c_q) on the other coordinates and on the quaternions, c_z and c_q
the curvatures of the stage's energy along its gradient restricted to each block
(:func:`block_curvature`; docs/PERFORMANCE.md).

Multiple starts. Energy (1) has several local minima (per-frame depth reversals among them);
:func:`joint_kernel_multistart` keeps the lowest energy at the last rho (no ground truth) among a few
schedules and starts.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .._penalty import RegularizerResult, penalty_method
from .._reduced import RankHint, kernel_factor, lbfgs_minimize, reduced_value_grad
from .._schedule import isolation_safe_rho0, penalty_schedule
from .._threads import blas_threads_for
from .._validation import check_count, check_positive
from ..data_terms import huber_loss
from ._basin_search import lowest_energy
from ._reprojection import check_cameras, check_shapes, check_tracks
from ._rotations import complete_rotations, quaternion_rotation

__all__ = [
    "JointKernelResult",
    "joint_value_grad",
    "kernel_energy",
    "block_curvature",
    "solve_joint_kernel",
    "joint_kernel_multistart",
]


class _NoData:
    """A zero data term of the given shape (the reprojection error of (2) is added separately)."""

    def __init__(self, shape):
        self.shape = shape

    def value(self, S):
        return 0.0

    def gradient(self, S):
        return np.zeros(self.shape)


def _loss(E, delta) -> float:
    """The reprojection loss of masked residuals E: squared (delta None) or Huber."""
    return float(np.vdot(E, E)) if delta is None else float(huber_loss(E, delta).sum())


def joint_value_grad(Z, q, Q0, W3, m3, gamma, tau, rho, center=False, hint=None, delta=None, spectrum=False):
    """Energy (2) of the module docstring and its gradients; no validation.

    Z (F, 3, P) are the shapes in the cameras' frames, q (F, 4) the local quaternions of Q_f =
    A(q_f) Q0_f (Q0 (F, 3, 3)), W3 (F, 2, P) the tracks (zero where unobserved), m3 (F, 1, P) the
    visibility as 0/1 weights, ``delta`` the Huber threshold (None: squared loss), ``hint`` a
    :class:`~nldr._reduced.RankHint`. Returns ``(value, grad_Z (F, 3, P), grad_q (F, 4))``, and with
    ``spectrum`` also the kernel's kept spectrum ``(lam, U, l)``.
    """
    F, _, P = Z.shape
    A, dA = quaternion_rotation(q, jacobian=True)
    Q = A @ Q0
    S = Q.transpose(0, 2, 1) @ Z  # (F, 3, P), s_f = Q_f^T z_f
    reg, G, kept = reduced_value_grad(
        S.reshape(F, 3 * P), _NoData((F, 3 * P)), gamma, tau, rho, center, "auto", hint
    )
    G = G.reshape(F, 3, P)
    E = m3 * (W3 - Z[:, :2])
    grad_Z = Q @ G
    value = _loss(E, delta) + float(reg)
    grad_Z[:, :2] -= 2 * (E if delta is None else np.clip(E, -delta, delta))
    grad_Q = Z @ G.transpose(0, 2, 1)  # dE/dQ_f = Z_f G_f^T
    grad_A = grad_Q @ Q0.transpose(0, 2, 1)
    grad_q = np.einsum("fij,fijk->fk", grad_A, dA)
    return (value, grad_Z, grad_q, kept) if spectrum else (value, grad_Z, grad_q)


def kernel_energy(
    W2d, mask, R, X, *, gamma: float, tau: float, rho: float, center: bool = False, delta=None
) -> float:
    """The paper's energy (1) at cameras R (F, 2, 3) and shapes X (F, 3P): the reprojection error
    over the observed points (Huber with threshold ``delta`` if given) plus the regularizer with C
    eliminated in closed form, at penalty weight rho. Comparable across solves that end their
    schedules at the same rho (the multistart chooses by it, without ground truth)."""
    W, vis = check_tracks(W2d, mask)
    F, P = vis.shape
    X = check_shapes(X, F, P)
    Q = complete_rotations(check_cameras(R, F))
    Z = Q @ X.reshape(F, 3, P)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (F, 1))
    delta = None if delta is None else check_positive(delta, "delta")
    value, _, _ = joint_value_grad(
        Z, q, Q, W.reshape(F, 2, P), vis[:, None, :].astype(float), check_positive(gamma, "gamma"),
        check_positive(tau, "tau"), check_positive(rho, "rho"), bool(center), delta=delta,
    )  # fmt: skip
    return value


def block_curvature(value_grad, v, grad, block, step: float) -> float:
    """Curvature d^T H d / d^T d of ``value_grad`` at v along d = ``grad`` restricted to ``block``.

    By a forward difference of gradients, (g(v + h d) - g(v)) . d / h with |d| = 1 and h = ``step``
    (exact for a quadratic up to rounding); 0.0 if the gradient vanishes on the block.

    ``value_grad``: v -> (value, gradient); ``v``, ``grad`` (n,): the point and the gradient there;
    ``block`` bool (n,). The value may be <= 0 where the energy is not convex along d.
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
class JointKernelResult(RegularizerResult):
    """Result of :func:`solve_joint_kernel`: a :class:`~nldr.regularizer.RegularizerResult` (``x`` the
    shapes (F, 3P) in the world frame, ``fun`` energy (1) at the last rho, ``C``, the stage and energy
    histories) with the cameras.

    Attributes
    ----------
    R : array (F, 2, 3)
        Cameras.
    """

    R: np.ndarray


def solve_joint_kernel(
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
    delta: float | None = None,
) -> JointKernelResult:
    """Minimise the paper's energy (1) over cameras and shapes together, by the penalty method.

    For rho = rho0, rho0 rho_growth, ... <= rho_max (:func:`~nldr._schedule.penalty_schedule`,
    isolation guard included as in :func:`~nldr.regularizer.minimize_regularized`), L-BFGS on the
    scaled (2) of the module docstring over the camera-frame shapes Z and local quaternions q, from the
    previous stage's cameras and shapes; the stages run in :func:`~nldr._penalty.penalty_method`.

    Parameters
    ----------
    W2d, mask : arrays (F, 2P) and (F, P) or None
        Centred tracks and visibility (:mod:`nldr.nrsfm._layout`).
    R0, X0 : arrays (F, 2, 3) and (F, 3P)
        Starting cameras and shapes (e.g. a TNH's).
    gamma, tau : float > 0
        RBF inverse squared width and trace-norm weight.
    rho0, rho_growth, rho_max, center, isolation_guard
        Penalty schedule (Table 4's defaults), kernel centring and the isolation guard, as in
        :func:`~nldr.regularizer.minimize_regularized`.
    max_inner, tol, gtol : int, float > 0, float > 0
        L-BFGS's iterations per stage, relative energy decrease and (scaled) gradient tolerances.
    delta : float > 0, optional
        Huber threshold of the reprojection error, in the unit of the tracks (None: squared loss).

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
    delta = None if delta is None else check_positive(delta, "delta")
    floor = isolation_safe_rho0(tau) if isolation_guard else None
    rhos = penalty_schedule(rho0, rho_growth, rho_max, floor=floor)
    max_inner = check_count(max_inner, "max_inner")
    tol, gtol = check_positive(tol, "tol"), check_positive(gtol, "gtol")
    W3, m3 = W.reshape(F, 2, P), vis[:, None, :].astype(float)
    identity = np.tile([1.0, 0.0, 0.0, 0.0], (F, 1))
    n_z = F * 3 * P
    observed = np.zeros((F, 3, P), dtype=bool)
    observed[:, :2] = vis[:, None, :]
    observed = observed.ravel()
    hint = RankHint()

    # The penalty method's variable: the camera-frame shapes Z and the rotations Q, packed in one vector.
    def unpack(state):
        return state[:n_z].reshape(F, 3, P), state[n_z:].reshape(F, 3, 3)

    def stage(state, rho, energies):
        Z, Q = unpack(state)

        def value_grad(v):
            Zv, qv = v[:n_z].reshape(F, 3, P), v[n_z:].reshape(F, 4)
            value, gZ, gq = joint_value_grad(Zv, qv, Q, W3, m3, gamma, tau, rho, center, hint, delta)
            return value, np.concatenate([gZ.ravel(), gq.ravel()])

        v0 = np.concatenate([Z.ravel(), identity.ravel()])
        D = _stage_scaling(value_grad, v0, observed, n_z)
        u, nit, ok, why = lbfgs_minimize(
            lambda u: _scaled(value_grad, D, u), v0 / D, max_inner, tol, gtol, energies
        )
        v = D * u
        Q = quaternion_rotation(v[n_z:].reshape(F, 4))[0] @ Q  # re-centre: q back to the identity
        return np.concatenate([v[:n_z], Q.ravel()]), nit, ok, why

    def stage_end(state, rho):
        Z, Q = unpack(state)
        value, _, _, (_, U, l) = joint_value_grad(
            Z, identity, Q, W3, m3, gamma, tau, rho, center, hint, delta, spectrum=True
        )
        return value, kernel_factor(l, U), int(np.count_nonzero(l))

    Z0 = Q @ X0.reshape(F, 3, P)
    with blas_threads_for(F):  # one BLAS thread on small problems (nldr._threads)
        res = penalty_method(np.concatenate([Z0.ravel(), Q.ravel()]), rhos, stage, stage_end, start=start)
    Z, Q = unpack(res.x)
    fields = {**vars(res), "x": (Q.transpose(0, 2, 1) @ Z).reshape(F, 3 * P), "R": Q[:, :2].copy()}
    return JointKernelResult(**{**fields, "wall_time": time.perf_counter() - start})


def _scaled(value_grad, D, u):
    value, grad = value_grad(D * u)
    return value, D * grad


def joint_kernel_multistart(
    W2d, mask, R0, X0, gammas, *, tau: float, multistart: bool = True, tie_rtol: float = 1e-4, **options
):
    """:func:`solve_joint_kernel` for every width of ``gammas``, each keeping the lowest energy (1) at
    the last rho (:func:`kernel_energy`; no ground truth) among its starts. Energies within
    ``tie_rtol`` (relative) of the lowest count as one minimum and go to the earlier start of the list
    below (:func:`~nldr.nrsfm._basin_search.lowest_energy`), so that the start kept does not
    hang on the last bit of the arithmetic.

    With ``multistart`` the starts of a width are

    1. the full schedule from (R0, X0) (the only start without ``multistart``);
    2. the same schedule without its first stage, from (R0, X0);
    3. the last stage alone from every other width's solution after 1-2 (one round).

    Parameters
    ----------
    W2d, mask, R0, X0, tau
        As in :func:`solve_joint_kernel`.
    gammas : dict
        Label -> RBF inverse squared width.
    multistart : bool, default True
    tie_rtol : float >= 0, default 1e-4
    **options
        Further keyword arguments of :func:`solve_joint_kernel` (the schedule, tolerances, ``delta``).

    Returns
    -------
    dict : label -> (JointKernelResult, energy); the result's ``nit`` counts the iterations of all
    starts run for that width, its ``message`` names the start kept.
    """
    rho0 = options.pop("rho0", 1e-3)
    rho_growth, rho_max = options.setdefault("rho_growth", 10.0), options.setdefault("rho_max", 10.0)
    energy_options = {k: options[k] for k in ("center", "delta") if k in options}
    tie_rtol = check_positive(tie_rtol, "tie_rtol", allow_zero=True)
    best, spent, tried = {}, dict.fromkeys(gammas, 0), {width: {} for width in gammas}

    def consider(width, label, R, X, first_rho):
        res = solve_joint_kernel(W2d, mask, R, X, gamma=gammas[width], tau=tau, rho0=first_rho, **options)
        energy = kernel_energy(
            W2d, mask, res.R, res.x, gamma=gammas[width], tau=tau, rho=rho_max, **energy_options
        )
        res.message = f"{label} (energy {energy:.10g}): {res.message}"
        spent[width] += res.nit
        tried[width][label] = (res, energy)
        order = list(tried[width])  # the order the starts ran in, the list above
        kept = lowest_energy([(k, e) for k, (_, e) in tried[width].items()], tie_rtol, order)
        best[width] = tried[width][kept]

    second = rho0 * rho_growth
    for width in gammas:
        consider(width, "full schedule", R0, X0, rho0)
        if multistart and second <= rho_max * (1 + 1e-12):
            consider(width, "schedule from its second stage", R0, X0, second)
    if multistart:
        first = {width: res for width, (res, _) in best.items()}
        for width in gammas:
            for other, res in first.items():
                if other != width:
                    consider(width, f"last stage from the {other} solution", res.R, res.x, rho_max)
    for width, (res, _) in best.items():
        res.nit = spent[width]
    return best
