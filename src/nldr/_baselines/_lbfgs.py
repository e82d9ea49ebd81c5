"""The outer loop shared by PKPCA and RKPCA: choose the number of components q, minimise the method's
objective over the free entries by L-BFGS with q fixed, repeat until q settles.

Both methods minimise a profile objective (the model refitted to the current X inside every
evaluation, so its gradient is the fixed-model gradient by the envelope theorem: the module notes
of :mod:`.pkpca` and :mod:`.rkpca`); they differ only in the objective, which entries are free and
how q is chosen.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from ..result import CONVERGED, INACCURATE, MAX_ITER

__all__ = ["OuterLoop", "outer_loop", "outer_loop_outcome"]

#: ``scipy.optimize.minimize(method="L-BFGS-B")`` status when it stopped for a reason other than its
#: tolerances or limits, in practice a line search that could not make progress.
_LBFGS_ABNORMAL = 2


def outer_loop_outcome(
    converged: bool, inner_status: int, n_iter: int, inner_message: str
) -> tuple[int, str]:
    """``(status, message)`` of an outer loop that ran ``n_iter`` L-BFGS solves.

    CONVERGED when the loop met its test; otherwise it ran out of outer iterations, and the status
    is INACCURATE when the last L-BFGS solve (``inner_status``) stopped abnormally, MAX_ITER if not.
    """
    if converged:
        if n_iter == 0:
            return CONVERGED, inner_message
        return CONVERGED, f"converged after {n_iter} outer iterations; last L-BFGS solve: {inner_message}"
    status = INACCURATE if inner_status == _LBFGS_ABNORMAL else MAX_ITER
    return status, f"max_iter={n_iter} outer iterations ran without converging; last L-BFGS: {inner_message}"


@dataclass
class OuterLoop:
    """What :func:`outer_loop` returns: X (optimised in place), objective at the start and after each
    outer iteration, q of each iteration, total L-BFGS iterations, status, message, outer iterations,
    and the q the loop ended with."""

    X: np.ndarray
    objective: np.ndarray
    n_components_history: tuple[int, ...]
    n_inner_iter: int
    status: int
    message: str
    nit: int
    n_components: int


def outer_loop(
    X: np.ndarray,
    free: np.ndarray,
    objective: Callable[[np.ndarray, int], tuple[float, np.ndarray]],
    choose_q: Callable[[], int],
    *,
    done: bool,
    max_iter: int,
    inner_max_iter: int,
    gtol: float,
) -> OuterLoop:
    """Alternate "q = choose_q()" and "minimise objective(X, q) over X[free]" until q settles.

    ``objective(X, q) -> (value, gradient (n, d))``; ``choose_q()`` reads the current X (the array
    passed in, updated in place). ``done``: nothing to optimise (the loop reports convergence at
    once). Converged when an L-BFGS solve succeeded and the next q equals its q. No validation.
    """

    def profile(v: np.ndarray, q: int) -> tuple[float, np.ndarray]:
        X[free] = v
        value, grad = objective(X, q)
        return value, grad[free]

    q = choose_q()
    values = [objective(X, q)[0]]
    qs: list[int] = []
    n_inner = 0
    converged = done
    message = "no missing entries" if converged else ""
    inner_status = 0
    n_iter = 0
    while not converged and n_iter < max_iter:
        n_iter += 1
        res = minimize(
            profile,
            X[free],
            args=(q,),
            jac=True,
            method="L-BFGS-B",
            options={"maxiter": int(inner_max_iter), "gtol": gtol, "ftol": 1e-15},
        )
        X[free] = res.x
        n_inner += int(res.nit)
        message = str(res.message)
        inner_status = int(res.status)
        values.append(float(res.fun))
        qs.append(q)
        q = choose_q()
        converged = bool(res.success) and q == qs[-1]
    status, message = outer_loop_outcome(converged, inner_status, n_iter, message)
    return OuterLoop(
        X=X,
        objective=np.asarray(values),
        n_components_history=tuple(qs),
        n_inner_iter=n_inner,
        status=status,
        message=message,
        nit=n_iter,
        n_components=qs[-1] if qs else q,
    )
