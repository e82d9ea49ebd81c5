"""BLAS threads for small problems.

On problems of a few hundred samples a multi-threaded BLAS spends more time synchronising its threads
than computing, and on a machine whose other cores are busy a thread waits for a core at every call:
a 100 x 12 Table 2 solve took 120.8 s with two OpenBLAS threads in a notebook on a busy machine,
against 0.8-1.2 s with one (issue 20). So the solvers run on one BLAS thread below
:data:`SMALL_PROBLEM_ROWS` samples, whatever the process's setting, and leave larger problems to the
caller's setting. ``NLDR_AUTO_THREADS=0`` in the environment turns this off.
"""

from __future__ import annotations

import os
from contextlib import nullcontext

from threadpoolctl import threadpool_limits

__all__ = ["SMALL_PROBLEM_ROWS", "blas_threads_for"]

#: Below this many samples (kernel rows) the solvers use one BLAS thread (docs/PERFORMANCE.md#threads).
SMALL_PROBLEM_ROWS = 400


def blas_threads_for(n_samples: int):
    """Context manager: one BLAS thread if ``n_samples < SMALL_PROBLEM_ROWS`` (unless
    ``NLDR_AUTO_THREADS=0``), else no change."""
    if n_samples < SMALL_PROBLEM_ROWS and os.environ.get("NLDR_AUTO_THREADS", "1") != "0":
        return threadpool_limits(1, user_api="blas")
    return nullcontext()
