"""The penalty method's outer loop and its result (the regularizer's Algorithm 1; re-exported by
:mod:`nldr.regularizer`, shared with the reference alternation :mod:`nldr.reference.regularizer`)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ._reduced import StageInfo
from .result import CONVERGED, INACCURATE, MAX_ITER, SolverResult

__all__ = ["RegularizerResult", "penalty_method"]


@dataclass(kw_only=True, repr=False)
class RegularizerResult(SolverResult):
    """Outcome of :func:`minimize_regularized` (and of the reference alternation).

    Attributes
    ----------
    x : array, shape (n_samples, n_features)
        The estimate S, in the units of the data term's variable (samples as rows).
    fun : float
        Energy (1) at ``x`` and the optimal C, at the last stage's rho (``stage_energy[-1]``).
    status : int
        :data:`~nldr.result.CONVERGED` when every stage met its tolerance, else
        :data:`~nldr.result.MAX_ITER` (a stage reached its iteration limit first), or
        :data:`~nldr.result.INACCURATE` when the callback stopped the schedule or the estimate is the
        start unchanged (no stage moved it; ``message`` says why). An L-BFGS stage that stops on an
        abnormal line search counts as converged (at these tolerances that is rounding noise at the
        minimum).
    message : str
        Why the solver stopped; names every stage that did not converge.
    nit : int
        Total inner iterations over all stages (L-BFGS iterations, or sweeps of the alternation).
    wall_time : float
        Seconds spent in the solver.
    C : array, shape (n_samples, n_samples)
        Kernel factor ``diag(l) U^T`` of the last stage (closed-form C-step at ``x``).
    energy_history : array, shape (nit,)
        Energy (1) after every inner iteration, at the rho of its stage; values of different stages
        are not comparable.
    stage_of_iteration : array of int, shape (nit,)
        Index of the rho stage each entry of ``energy_history`` belongs to.
    stage_energy : array, shape (n_stages,)
        Energy (1) at the end of each stage.
    rho_history : array, shape (n_stages,)
        Penalty weight of each stage.
    rank_history : array of int, shape (n_stages,)
        Rank of C at the end of each stage.
    n_stages : int
        Number of rho stages run.
    """

    C: np.ndarray
    energy_history: np.ndarray
    stage_of_iteration: np.ndarray
    stage_energy: np.ndarray
    rho_history: np.ndarray
    rank_history: np.ndarray
    n_stages: int


def penalty_method(
    S, rhos, stage, stage_end, *, start: float, callback=None, verbose=False
) -> RegularizerResult:
    """The penalty method's outer loop (Algorithm 1), shared by every solver of the regularizer.

    For each rho of ``rhos``, ``stage(S, rho, energies) -> (S, nit, ok, why)`` minimises the energy at
    that rho from the previous stage's S, appending one energy per inner iteration to ``energies``;
    ``stage_end(S, rho) -> (value, C, rank)`` then gives the stage's final energy, kernel factor and
    rank. ``start`` is ``time.perf_counter()`` at the solver's entry. After each stage a
    :class:`StageInfo` is printed if ``verbose`` and passed to ``callback``; a callback returning a
    true value (``bool(value)``) ends the loop (status INACCURATE: the schedule was not completed).
    A solve that returns its start unchanged has status INACCURATE and says why. No validation.
    """
    energies: list[float] = []
    stage_index: list[int] = []
    stage_energy, ranks, failures, reasons = [], [], [], []
    nit, stopped, planned, S_start = 0, None, len(rhos), S.copy()
    for k, rho in enumerate(rhos):
        before, t0 = len(energies), time.perf_counter()
        S, stage_nit, ok, why = stage(S, rho, energies)
        stage_index.extend([k] * (len(energies) - before))
        nit += stage_nit
        value, C, rank = stage_end(S, rho)
        stage_energy.append(value)
        ranks.append(rank)
        reasons.append(why)
        if not ok:
            failures.append(f"stage {k} (rho={rho:g}): {why}")
        if verbose or callback is not None:
            info = StageInfo(
                stage=k, n_stages=len(rhos), rho=float(rho), nit=int(stage_nit), energy=float(value),
                rank=int(rank), converged=bool(ok), seconds=time.perf_counter() - t0, x=S.copy(),
            )  # fmt: skip
            if verbose:
                print(f"minimize_regularized {info}", flush=True)
            if callback is not None and _stops(callback(info)) and k + 1 < len(rhos):
                stopped, rhos = k, rhos[: k + 1]
                break
    unchanged = np.array_equal(S, S_start)
    if stopped is not None:
        message = (
            f"stopped by the callback after stage {stopped} (rho={rhos[-1]:g}) of {planned}: the schedule "
            "was not completed"
        )
        if failures:
            message += "; iteration limit reached in " + "; ".join(failures)
    elif failures:
        message = "iteration limit reached in " + "; ".join(failures)
    elif unchanged:
        message = (
            f"the estimate is the start unchanged: no penalty stage moved it (rho {rhos[0]:g} to "
            f"{rhos[-1]:g}; the first stage stopped with: {reasons[0]}). If the data are not in the "
            "units the parameters assume, rescale them: for data scaled by s the equivalent problem has "
            "gamma / s^2, and tau, rho0, rho_max times s^2 (docs/REPRODUCTION.md#units)"
        )
    else:
        message = f"all {len(rhos)} penalty stages converged (rho {rhos[0]:g} to {rhos[-1]:g})"
    status = MAX_ITER if failures and stopped is None else CONVERGED
    if stopped is not None or (unchanged and not failures):
        status = INACCURATE
    return RegularizerResult(
        x=S,
        fun=float(stage_energy[-1]),
        status=status,
        message=message,
        nit=nit,
        wall_time=time.perf_counter() - start,
        C=C,
        energy_history=np.asarray(energies, dtype=np.float64),
        stage_of_iteration=np.asarray(stage_index, dtype=np.int64),
        stage_energy=np.asarray(stage_energy, dtype=np.float64),
        rho_history=np.asarray(rhos, dtype=np.float64),
        rank_history=np.asarray(ranks, dtype=np.int64),
        n_stages=len(rhos),
    )


def _stops(value) -> bool:
    """A callback's return value as a stop request: any true value (True, np.True_, 1, ...)."""
    try:
        return bool(value)
    except (TypeError, ValueError):
        raise ValueError(
            f"callback must return a truth value (True to stop, None or False to go on); got {value!r}"
        ) from None
