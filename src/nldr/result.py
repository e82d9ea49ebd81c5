"""One result convention for every solver in nldr, modelled on ``scipy.optimize.OptimizeResult``.

Every solver returns a dataclass derived from :class:`SolverResult`. The common fields mean the same
thing everywhere:

``x``
    The estimate (an array; its shape is documented by each solver).
``fun``
    The objective the solver minimised, evaluated at ``x`` (each solver's docstring names it).
``success``
    True exactly when ``status == CONVERGED``: the solver met its own stopping tolerance.
``status``
    :data:`CONVERGED` (0), :data:`MAX_ITER` (1: an iteration limit was reached first) or
    :data:`INACCURATE` (2: stopped for another reason, e.g. a conic solver's ``optimal_inaccurate``
    or a line search that could not make progress). ``message`` says which.
``message``
    Why the solver stopped, in words.
``nit``
    Iterations of the solver's main loop (each solver's docstring says which loop).
``wall_time``
    Seconds of wall-clock time inside the solver.

Solver-specific fields (the kernel factor ``C``, cameras ``R``, energy histories, ...) follow in
each subclass. The ``repr`` is one short line; print a field to see an array.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CONVERGED", "MAX_ITER", "INACCURATE", "STATUS_NAMES", "SolverResult"]

CONVERGED = 0
MAX_ITER = 1
INACCURATE = 2
STATUS_NAMES = {CONVERGED: "converged", MAX_ITER: "iteration limit", INACCURATE: "inaccurate"}


@dataclass(kw_only=True, repr=False)
class SolverResult:
    """Common fields of every solver result (see the module docstring for their meaning)."""

    x: np.ndarray
    fun: float
    status: int
    message: str
    nit: int
    wall_time: float

    @property
    def success(self) -> bool:
        """True when the solver met its stopping tolerance (``status == CONVERGED``)."""
        return self.status == CONVERGED

    def __repr__(self) -> str:
        shape = "x".join(str(s) for s in np.shape(self.x))
        fun = f"{self.fun:.6g}" if isinstance(self.fun, int | float | np.floating) else repr(self.fun)
        return (
            f"{type(self).__name__}(success={self.success}, status={self.status}, "
            f"fun={fun}, nit={self.nit}, wall_time={self.wall_time:.3g}s, x=<{shape}>, "
            f"message={self.message!r})"
        )


def status_from(converged: bool) -> int:
    """:data:`CONVERGED` when ``converged`` else :data:`MAX_ITER` (the common case of a loop that
    either met its tolerance or ran out of iterations)."""
    return CONVERGED if converged else MAX_ITER


