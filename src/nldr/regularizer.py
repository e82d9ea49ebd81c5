"""Inference with the non-linear dimensionality regularizer (the paper's Algorithm 1).

Problem. For a data term f (any :class:`~nldr.data_terms.DataTerm`), an RBF kernel
``K(S)_ij = exp(-gamma ||s_i - s_j||^2)`` (optionally double-centred) and tau > 0, the penalty method
minimises, for an increasing sequence of penalty weights rho,

    E_rho(S, C) = f(S) + rho/2 ||K(S) - C^T C||_F^2 + tau ||C||_*                          (1)

warm-starting every stage from the previous one. The C-step of Algorithm 1 has a closed form
(Theorem 3.1), so C is eliminated and the reduced energy E_rho(S) = min_C E_rho(S, C) is minimised
over S alone by L-BFGS, with the gradient given by the envelope theorem (maintenance note below).
Algorithm 1 as printed (closed-form C-step, then a Levenberg-Marquardt S-step, repeated) is
:func:`nldr.reference.regularizer.minimize_regularized_alternation`, kept as a reference: it is
block-coordinate descent on two strongly coupled blocks and stops far from the minimum this solver
reaches (docs/REPRODUCTION.md#table-2-solver).

The reduced energy E_rho(S) = min_C E_rho(S, C), its envelope-theorem gradient and the L-BFGS stage
live in :mod:`nldr._reduced` (maintenance note there).

Maintenance note (the isolation guard: why unobserved coordinates can escape, and the first rho that
stops it). With the uncentred RBF kernel, trace K = n whatever S is. While every eigenvalue lies at or
below the threshold lambda_star(tau, rho) (see :mod:`nldr._spectral`), C = 0 and the regularizer is
rho/2 ||K||_F^2 = rho/2 (n + sum_{i != j} K_ij^2): it rewards moving samples apart, and coordinates
that the data term does not hold (unobserved entries) are pushed outwards until K = I, where the
energy is n rho/2 and its gradient vanishes (exp(-gamma d^2) ~ 0), so later stages cannot pull them
back although they would prefer to (at rho = 1e4 the dispersed state costs far more than the fitted
one). An isolated sample contributes the eigenvalue exactly 1 (its row of K is a unit vector). If the
first stage already keeps an eigenvalue of 1 (lambda_star(tau, rho0) <= 1), an isolated sample costs
phi(1) ~ tau, more than the tau / (2 sqrt(lambda_1)) it costs inside a cluster of leading eigenvalue
lambda_1 > 1/4, and dispersal no longer pays. lambda_star = 3 (b^2/2)^(1/3) <= 1 with b = tau/(2 rho)
holds iff b <= sqrt(2/27), i.e. rho >= tau sqrt(27/8) (:func:`isolation_safe_rho0`); later stages have a
larger rho and a lower threshold. The option ``isolation_guard`` (on by default) raises rho0 to that value.
It changes nothing when rho0 >= tau sqrt(27/8) already, which holds for every table of the paper
(Table 2: tau = 0.1, rho0 = 1 >= 0.184; Tables 3-4: tau = 1e-4, rho0 = 1e-3 >= 1.8e-4), so their
results stay bit for bit.

Maintenance note (scale: why the stopping tests take their units from rho0). For data scaled by s,
the exactly equivalent problem has gamma / s^2 and tau, rho (every stage's) times s^2: K is
unchanged, so the energy (1) is s^2 times the original and its minimisers s times the original's.
L-BFGS-B is not invariant to that on its own: its energy test divides by max(|E|, 1), its gradient
test is absolute, and its first step has length 1 in the units of S. So every stage runs L-BFGS on
x = S / scale with the energy E / scale^2 (:func:`nldr._reduced.lbfgs_minimize`), where scale is
the option ``scale`` or, by default, sqrt(rho0): rho0 multiplies a dimensionless mismatch, so it is
an energy of the problem and sqrt(rho0) one of its lengths, and it scales by s^2 with the problem.
Then the equivalent problem takes the same iterates (up to rounding), and every test is relative:
``(E_k - E_{k+1}) / max(|E_k|, |E_{k+1}|, rho0) <= tol``, ``max |dE/dS| <= gtol sqrt(rho0)``,
and the plateau test likewise. At rho0 = 1 (the paper's completion schedule) scale is 1 and every
number is the unscaled run's, bit for bit. The isolation guard's floor tau sqrt(27/8) scales with
tau, so it needs no unit. What the default does not fix: parameters left at values meant for
another scale (tau = 0.1 on data in raw units); the paper's completion parameters assume data of
unit scale (oil flow: entries in [-0.26, 2.17], RMS 0.75). A solve whose estimate is its start
unchanged reports INACCURATE and says why instead of "converged".
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Mapping

import numpy as np

from ._nystroem import landmark_indices, landmark_map, nystroem_factor, nystroem_value_grad, pivoted_landmarks
from ._options import ExactOptions, NystroemOptions, NystroemWarmOptions, solver_options
from ._penalty import RegularizerResult, penalty_method
from ._reduced import (
    RankHint,
    kernel_factor,
    lbfgs_minimize,
    lbfgs_stage,
    rbf,
    reduced_value_grad,
)
from ._schedule import isolation_safe_rho0, penalty_schedule
from ._spectral import check_eigensolver
from ._threads import blas_threads_for
from ._validation import as_float_matrix, check_positive
from .data_terms import DataTerm, check_start
from .kernels import center_kernel

__all__ = [
    "RegularizerResult",
    "minimize_regularized",
    "reduced_energy",
    "LongSolveWarning",
    "ExactOptions",
    "NystroemOptions",
    "NystroemWarmOptions",
]


# --------------------------------------------------------------------------------------------------
# Kernel, energies
# --------------------------------------------------------------------------------------------------


def _check_problem(data_term, S, gamma, tau, name_S="S"):
    return check_start(data_term, S, name_S), check_positive(gamma, "gamma"), check_positive(tau, "tau")


#: From this many samples a solve on the exact kernel throughout warns about its cost
#: (:class:`LongSolveWarning`): one evaluation is an n x n eigenproblem, about n^3, and a default
#: solve there takes minutes (measured: docs/PERFORMANCE.md#long-solves).
LONG_SOLVE_ROWS = 1500
#: The cost of a default exact solve on 1000 oil-flow rows (seconds of CPU time), scaled by n^3 for
#: the warning's estimate (measured: docs/PERFORMANCE.md#long-solves).
_SECONDS_AT_1000_ROWS = 52.0


class LongSolveWarning(UserWarning):
    """A solve on the exact kernel at a size where it takes minutes; the message names the faster path."""


def _warn_long_solve(n: int) -> None:
    minutes = _SECONDS_AT_1000_ROWS * (n / 1000.0) ** 3 / 60.0
    warnings.warn(
        f"minimize_regularized: {n} samples on the exact kernel: expect about {minutes:.0f} CPU minutes "
        "(growing as n^3; docs/PERFORMANCE.md#long-solves). "
        "method='nystroem-warm' reaches an exact answer faster (e.g. options "
        "{'last_landmarks': 200, 'exact_tol': 1e-5}); method='nystroem' (e.g. options {'landmarks': 300}) "
        "is approximate and cheaper still. verbose=True prints each stage as it ends",
        LongSolveWarning,
        stacklevel=3,
    )


def _check_center(center) -> bool:
    if not isinstance(center, bool | np.bool_):
        raise ValueError(f"center must be True or False (double-centre the kernel or not); got {center!r}")
    return bool(center)


def reduced_energy(
    S,
    data_term: DataTerm,
    *,
    gamma: float,
    tau: float,
    rho: float,
    center: bool = False,
    eigensolver: str = "auto",
):
    """Reduced energy E_rho(S) = min_C E_rho(S, C) and its gradient with respect to S.

    Parameters
    ----------
    S : array, shape (n_samples, n_features)
        Samples as rows; must match ``data_term.shape``.
    data_term : DataTerm
        The data term f.
    gamma : float > 0
        RBF inverse squared width.
    tau : float > 0
        Trace-norm weight.
    rho : float > 0
        Penalty weight.
    center : bool, default=False
        Use the double-centred kernel H K H.
    eigensolver : {"auto", "partial", "krylov", "full"}, default="auto"
        "full": every eigenpair of K (the reference). "partial": only those above the cubic's
        threshold, the only ones C keeps (MRRR). "krylov": the same ones by Lanczos. "auto": partial
        for n >= 300. Same value up to rounding.

    Returns
    -------
    value : float
        ``f(S) + sum_i min_l [rho/2 (lambda_i(K(S)) - l^2)^2 + tau l]``.
    gradient : array, shape (n_samples, n_features)
        Envelope-theorem gradient (see the module's maintenance note).
    """
    S, gamma, tau = _check_problem(data_term, S, gamma, tau)
    rho = check_positive(rho, "rho")
    eigensolver = check_eigensolver(eigensolver)
    value, grad, _ = reduced_value_grad(S, data_term, gamma, tau, rho, _check_center(center), eigensolver)
    return float(value), grad


def _regularized_energy(
    S, C, data_term: DataTerm, *, gamma: float, tau: float, rho: float, center: bool = False
) -> float:
    """The full energy ``f(S) + rho/2 ||K(S) - C^T C||_F^2 + tau ||C||_*`` at a given (S, C).

    Parameters
    ----------
    S : array, shape (n_samples, n_features)
    C : array, shape (r, n_samples)
        Any kernel factor (``C^T C`` is n x n).
    data_term : DataTerm
    gamma, tau, rho : float > 0
    center : bool, default=False

    Returns
    -------
    energy : float
    """
    S, gamma, tau = _check_problem(data_term, S, gamma, tau)
    rho = check_positive(rho, "rho")
    C = as_float_matrix(C, "C")
    if C.shape[1] != S.shape[0]:
        raise ValueError(f"C must have {S.shape[0]} columns (one per sample); got shape {C.shape}")
    K = rbf(S, gamma)
    if center:
        K = center_kernel(K)
    nuclear = float(np.linalg.svd(C, compute_uv=False).sum())
    return float(data_term.value(S) + 0.5 * rho * np.sum((K - C.T @ C) ** 2) + tau * nuclear)


# --------------------------------------------------------------------------------------------------
# The penalty method
# --------------------------------------------------------------------------------------------------


def _run_stages(
    S, data_term, gamma, tau, center, rhos, opts, plan, start, callback, verbose, variables, scale
):
    """One L-BFGS solve per penalty weight, warm-started; the closed-form C after each. No validation.

    ``opts`` is the method's options record (:mod:`nldr._options`); ``plan`` is None (the exact kernel
    throughout) or ``(landmarks, approximate_stages, last_landmarks, plateau)``: the first
    ``approximate_stages`` stages use the Nystroem kernel on ``landmarks`` landmarks
    (``last_landmarks`` for the last of them), the rest are exact with the plateau test ``plateau``
    (:func:`nldr._reduced.lbfgs_minimize`). ``rhos`` may repeat a weight (a Nystroem stage and then
    the exact stage at the same rho). ``scale``: the unit of S of every stage's stopping tests.
    """
    hint = RankHint()
    tols, max_inner, gtol = opts.tols, opts.max_inner, opts.gtol
    eigensolver = getattr(opts, "eigensolver", "auto")
    m, n_approx, m_last, plateau = plan if plan is not None else (None, 0, None, None)
    done = [0]  # stages finished so far (stage_end closes each)
    if plan is not None:
        idx = _landmarks(S, m, gamma, opts)
        idx_last = idx if m_last is None else _landmarks(S, m_last, gamma, opts)
        frozen = {}

    def nystroem_here():
        return done[0] < n_approx

    def stage(S, rho, energies):
        tol = tols[1] if rho == rhos[-1] else tols[0]
        if not nystroem_here():  # exact kernel; L-BFGS on S, or on Y with S = variables.to_samples(Y)
            args = (S, data_term, gamma, tau, rho, center, max_inner, tol, gtol, energies, eigensolver, hint)
            return lbfgs_stage(*args, variables, plateau=plateau, scale=scale)  # plateau: warm path only
        frozen["Z"] = Z = S[idx_last if done[0] == n_approx - 1 else idx].copy()  # fixed during the stage
        frozen["P"] = P = landmark_map(Z, gamma)

        def value_grad(S):
            return nystroem_value_grad(S, Z, P, data_term, gamma, tau, rho, center)

        return lbfgs_minimize(value_grad, S, max_inner, tol, gtol, energies, scale=scale)

    def stage_end(S, rho):
        nystroem, done[0] = nystroem_here(), done[0] + 1
        if nystroem:
            Z, P = frozen["Z"], frozen["P"]
            value, _ = nystroem_value_grad(S, Z, P, data_term, gamma, tau, rho, center)
            l, U = nystroem_factor(S, Z, P, gamma, tau, rho, center)
            return value, kernel_factor(l, U), int(l.size)
        value, _, (lam, U, l) = reduced_value_grad(S, data_term, gamma, tau, rho, center, eigensolver, hint)
        return value, kernel_factor(l, U), int(np.count_nonzero(l))

    return penalty_method(S, rhos, stage, stage_end, start=start, callback=callback, verbose=verbose)


def _landmarks(S, m, gamma, opts) -> np.ndarray:
    """The landmark indices of a solve from its start S, by ``opts.landmark_rule``."""
    if opts.landmark_rule == "pivoted":
        return pivoted_landmarks(S, m, gamma)
    return landmark_indices(S.shape[0], m, opts.landmark_seed)


def _stage_plan(method, opts, n, rhos):
    """``(rhos, plan)`` for :func:`_run_stages` from the method, its options, n and the schedule."""
    if method == "exact" or opts.landmarks >= n:
        return rhos, None  # every sample a landmark: the exact kernel costs less
    if method == "nystroem":
        return rhos, (opts.landmarks, len(rhos), None, None)
    if opts.exact_stages >= len(rhos):
        return rhos, None  # every stage exact: the exact solver throughout
    first_exact = len(rhos) - opts.exact_stages  # solved twice: on the Nystroem kernel, then exactly
    plan = (opts.landmarks, first_exact + 1, opts.last_landmarks, opts.exact_tol)
    return rhos[: first_exact + 1] + rhos[first_exact:], plan


def minimize_regularized(
    data_term: DataTerm,
    S0,
    *,
    gamma: float,
    tau: float,
    method: str = "exact",
    options: Mapping | None = None,
    center: bool = False,
    rho0: float = 1.0,
    rho_growth: float = 10.0,
    rho_max: float = 1e4,
    callback=None,
    verbose: bool = False,
    variables=None,
) -> RegularizerResult:
    """Minimise ``f(S) + rho/2 ||K(S) - C^T C||_F^2 + tau ||C||_*`` by the penalty method.

    For rho = rho0, rho0 * rho_growth, ... up to rho_max (:func:`penalty_schedule`), minimise the
    reduced energy min_C E_rho(S, C) over S by L-BFGS, starting from the previous stage's S
    (Algorithm 1 of Garg, Eriksson and Reid, 2016, with its C-step done in closed form inside every
    evaluation; see the module docstring).

    Parameters
    ----------
    data_term : DataTerm
        The data term f(S) (e.g. :class:`~nldr.data_terms.MaskedLeastSquares`).
    S0 : array, shape data_term.shape = (n_samples, n_features)
        Initial estimate, samples as rows (e.g. mean imputation for matrix completion).
    gamma : float > 0
        RBF inverse squared width, ``K_ij = exp(-gamma ||s_i - s_j||^2)``.
    tau : float > 0
        Trace-norm weight (the paper uses 0.1 for matrix completion on oil flow).
    method : {"exact", "nystroem", "nystroem-warm"}, default="exact"
        How the kernel is evaluated:

        - "exact": the kernel itself in every stage (the default and the reference).
        - "nystroem": opt-in approximation. The kernel is replaced by its Nystroem approximation on
          ``options["landmarks"]`` landmark samples (chosen once from the start S0 by
          ``options["landmark_rule"]``, re-read from S at the start of every stage; module
          :mod:`nldr._nystroem`). One evaluation then costs O(n m^2) instead of O(n^2 r) plus an
          n x n eigensolver, but the minimiser is not the exact one (its SSE against the exact
          solve: docs/PERFORMANCE.md). ``landmarks >= n_samples``: the exact kernel.
        - "nystroem-warm": opt-in faster path to an exact answer. With k = ``options["exact_stages"]``,
          the stages up to the k-th last run on the Nystroem kernel (``landmarks`` landmarks, default
          100), then the last k stages with the exact kernel, the first of them warm-started from the
          Nystroem answer at the same rho (so one stage more: ``n_stages`` and ``rho_history`` show
          both). The returned ``x``, ``fun`` and ``C`` are the exact solver's, meeting its stopping
          test at rho_max, but possibly in another local minimum than the default path's (CPU, energy
          and SSE against it: docs/PERFORMANCE.md). With k >= the number of stages, or
          ``landmarks >= n_samples``: the exact solver throughout. Narrow kernels: a sample far from
          every landmark pays its unspanned residual (:mod:`nldr._nystroem`), so its unobserved
          entries do not escape (1000 oil rows, gamma 0.29: SSE 144 against 142 on "exact").
    options : mapping, optional
        The method's options; an option the method does not take is a ValueError naming the method
        and listing its options. Every method takes the stopping options:

        - ``max_inner`` (int, default 3000): per-stage limit of L-BFGS iterations.
        - ``tol`` (float > 0, default 1e-10): stage convergence (the L-BFGS ``ftol``): relative energy
          decrease per iteration, ``(E_k - E_{k+1}) / max(|E_k|, |E_{k+1}|, scale^2) <= tol``.
        - ``gtol`` (float > 0, default 1e-6): L-BFGS also stops when the largest gradient entry is
          at most ``gtol * scale`` (the gradient in units of energy / length).
        - ``scale`` (float > 0, default None): the unit of length of these tests (and of L-BFGS's
          first step), in the units of S; energies are in ``scale^2``. None means ``sqrt(rho0)``,
          which scales with the problem: for data scaled by s, the exactly equivalent problem
          (gamma / s^2; tau, rho0, rho_max times s^2) takes the same iterates up to rounding (module
          maintenance note on scale). At rho0 = 1 it is 1, scipy's own tests.
        - ``stage_tol`` (float > 0, default None): ``tol`` of every stage but the last; None means
          ``tol``. The earlier stages only provide the next one's start: a looser one saves
          iterations, but a start further from the previous minimum can lead to another local minimum
          (measured: docs/PERFORMANCE.md#stage-tol).
        - ``isolation_guard`` (bool, default True): start the schedule at
          ``max(rho0, isolation_safe_rho0(tau))`` (and end it no lower), so that the first stage
          cannot push unobserved coordinates away from the data (module maintenance note). It changes
          nothing when rho0 is already >= tau sqrt(27/8), as in every table of the paper; False runs
          the given schedule as it is (to study the escape).

        "exact" also takes ``eigensolver`` ({"auto", "partial", "krylov", "full"}, default "auto"):
        the C-step's decomposition. Only eigenpairs above the cubic's threshold survive, so "partial"
        computes just those (LAPACK MRRR) and forms dE/dK = rho (K - C^T C) from them; "krylov" finds
        the same ones by Lanczos (ARPACK), cheaper when they are few; "full" decomposes the whole
        kernel (the reference); "auto" uses "full" below n = 300; from there "krylov" while the
        previous evaluation kept at most :data:`KRYLOV_AUTO_FRACTION` of the spectrum, "partial" up to
        a quarter, else "full". All agree to rounding (tests/test_regularizer.py,
        tests/test_spectral_krylov.py).

        "nystroem" also takes ``landmarks`` (int >= 1, required), ``landmark_rule`` ("random", the
        default: a uniform draw; "pivoted": the pivots of greedy pivoted Cholesky on the kernel of S0,
        :func:`nldr._nystroem.pivoted_landmarks`, deterministic and including isolated samples) and
        ``landmark_seed`` (int >= 0, default 0, the seed of the "random" draw).

        "nystroem-warm" also takes ``landmarks`` (default 100), ``landmark_rule`` and
        ``landmark_seed`` (as "nystroem"),
        ``eigensolver`` (of its exact stages), ``exact_stages`` (k above, int >= 1, default 1; 1000
        oil rows: k = 2 needed at p = 0.05, PERFORMANCE.md), ``exact_tol`` (float > 0, default None:
        the exact stages after the Nystroem ones also stop once the energy fell by at most
        ``exact_tol``, relative, per iteration on average over the last 10 iterations; the answer then
        need not meet the ``tol`` test, its energy gap to the converged one on 1000 oil rows:
        docs/PERFORMANCE.md) and ``last_landmarks`` (int >= 1, default None: the number of landmarks
        of the last Nystroem stage, chosen by the same rule; None means ``landmarks``).
    center : bool, default=False
        Double-centre the kernel (H K H). The uncentred kernel reproduces the paper's Table 2.
    rho0, rho_growth, rho_max : float, defaults 1.0, 10.0, 1e4
        The penalty schedule (:func:`penalty_schedule`): first weight, factor between stages (> 1),
        last weight (>= rho0).
    callback : callable, optional
        Called after every stage with a :class:`StageInfo` (stage index, rho, iterations, energy,
        rank, converged, seconds, a copy of S). If it returns a true value (``True``, ``np.True_``,
        1, ...; None and False go on), the solver stops there and
        returns that stage's estimate with status :data:`~nldr.result.INACCURATE` (the schedule was
        not completed) and the stopping stage named in ``message``; after the last stage it
        changes nothing.
    verbose : bool, default=False
        Print one line per penalty stage: rho, iterations, energy, rank and seconds.
    variables : object, optional
        A fixed invertible linear change of variables S = A(Y) in which L-BFGS runs (a
        preconditioner: the minimisers are the same, the conditioning is not). It provides
        ``to_samples(Y) -> S``, ``to_variables(S) -> Y`` (the inverse) and
        ``gradient_to_variables(G) -> A^T(G)``, all on arrays of S's shape (e.g.
        :class:`nldr.nrsfm.CameraFrameVariables`). None (default): L-BFGS on S. Only with
        ``method="exact"``.

    Returns
    -------
    RegularizerResult
        ``x`` (the estimate S, shape (n_samples, n_features)), ``C``, histories, ``status`` and
        ``message`` (an iteration limit is reported, never silent), counts and wall time.

    Raises
    ------
    ValueError
        If ``data_term`` is not a DataTerm, ``S0`` has the wrong shape or non-finite entries, a
        parameter is out of range, ``method`` is unknown or ``options`` holds an option the method
        does not take (the message names it).

    Warns
    -----
    LongSolveWarning
        From :data:`LONG_SOLVE_ROWS` samples when every stage runs on the exact kernel: the expected
        CPU time and the faster methods (before any evaluation).
    """
    start = time.perf_counter()
    S, gamma, tau = _check_problem(data_term, S0, gamma, tau, name_S="S0")
    center = _check_center(center)
    opts = solver_options(method, options)
    floor = isolation_safe_rho0(tau) if opts.isolation_guard else None
    rhos = penalty_schedule(rho0, rho_growth, rho_max, floor=floor)
    scale = float(np.sqrt(float(rho0))) if opts.scale is None else opts.scale
    if callback is not None and not callable(callback):
        raise ValueError(f"callback must be callable or None; got {type(callback).__name__}")
    if variables is not None and (method != "exact" or not hasattr(variables, "gradient_to_variables")):
        raise ValueError("variables must be a change of variables (see the docstring), with method='exact'")
    rhos, plan = _stage_plan(method, opts, S.shape[0], rhos)
    if plan is None and S.shape[0] >= LONG_SOLVE_ROWS:
        _warn_long_solve(S.shape[0])
    with blas_threads_for(S.shape[0]):  # one BLAS thread on small problems (nldr._threads)
        return _run_stages(
            S.copy(), data_term, gamma, tau, center, rhos, opts, plan, start, callback, bool(verbose),
            variables, scale,
        )  # fmt: skip
