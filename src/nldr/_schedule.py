"""The penalty weights of the regularizer's stages and the isolation guard's floor (re-exported by
:mod:`nldr.regularizer`, whose maintenance note on the isolation guard explains the floor)."""

from __future__ import annotations

import numpy as np

from ._validation import check_positive

__all__ = ["penalty_schedule", "isolation_safe_rho0", "MAX_PENALTY_STAGES"]

#: Most stages a schedule may have (the paper's have 3 to 5; growth 1.01 from 1 to 1e4 needs 927).
MAX_PENALTY_STAGES = 1000


def penalty_schedule(rho0: float, rho_growth: float, rho_max: float, *, floor=None) -> list[float]:
    """The penalty weights of the stages: rho0, rho0 rho_growth, rho0 rho_growth^2, ... <= rho_max.

    Parameters
    ----------
    rho0 : float > 0
        First penalty weight.
    rho_growth : float > 1
        Factor between consecutive weights.
    rho_max : float >= rho0
        Last admissible weight (a weight within a relative 1e-12 above it still counts, against
        rounding in the products).
    floor : float > 0, optional
        If rho0 < floor: from floor to max(rho_max, floor) (the isolation guard, :func:`isolation_safe_rho0`).

    Returns
    -------
    rhos : list of float
        One weight per stage, increasing; never empty.

    Raises
    ------
    ValueError
        For a parameter out of range, or a schedule of more than :data:`MAX_PENALTY_STAGES` stages
        (counted before any is built).
    """
    rho0 = check_positive(rho0, "rho0")
    rho_growth = check_positive(rho_growth, "rho_growth")
    if rho_growth <= 1.0:
        raise ValueError(f"rho_growth must be > 1 so that the penalty increases; got {rho_growth!r}")
    rho_max = check_positive(rho_max, "rho_max")
    if rho_max < rho0:
        raise ValueError(f"rho_max must be >= rho0 = {rho0!r}; got {rho_max!r}")
    if floor is not None and rho0 < check_positive(floor, "floor"):
        rho0, rho_max = floor, max(rho_max, floor)
    expected = np.log(rho_max * (1.0 + 1e-12) / rho0) / np.log(rho_growth)
    if not expected < MAX_PENALTY_STAGES:  # also inf / nan from a growth a hair above 1
        raise ValueError(
            f"rho_growth={rho_growth!r} takes about {expected:.3g} stages from rho0={rho0:g} to "
            f"rho_max={rho_max:g}; at most {MAX_PENALTY_STAGES} are allowed: raise rho_growth (the paper "
            "uses 10) or narrow the range"
        )
    rhos, rho = [], rho0
    while rho <= rho_max * (1.0 + 1e-12):
        rhos.append(rho)
        rho *= rho_growth
    return rhos


def isolation_safe_rho0(tau: float) -> float:
    """Smallest penalty weight whose threshold keeps an isolated sample's eigenvalue: tau sqrt(27/8).

    At rho >= tau sqrt(27/8) the cubic's threshold lambda_star(tau, rho) is <= 1, so the first stage of
    the penalty method no longer rewards pushing unobserved coordinates away from the data (see the
    maintenance note on the isolation guard in :mod:`nldr.regularizer`).

    Parameters
    ----------
    tau : float > 0
        Trace-norm weight.

    Returns
    -------
    rho : float
    """
    return check_positive(tau, "tau") * np.sqrt(27.0 / 8.0)
