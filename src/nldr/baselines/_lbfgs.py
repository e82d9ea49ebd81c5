"""The outcome of an outer loop of L-BFGS solves (PKPCA, RKPCA), in the nldr.result convention."""

from __future__ import annotations

from ..result import CONVERGED, INACCURATE, MAX_ITER

__all__ = ["outer_loop_outcome"]

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
