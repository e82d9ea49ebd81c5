"""BLAS threads: the library chooses them for every solve, for every BLAS the process has loaded.

A multi-threaded BLAS pays twice where it does not help: on problems of a few hundred samples its
threads spend more time synchronising than computing, and on a machine whose other cores are busy
every call waits for the slowest thread's core (docs/PERFORMANCE.md#threads). OpenBLAS starts with
one thread per core whatever the load, so the solvers set the thread count themselves, at each call,
with ``threadpoolctl``, which reaches every BLAS loaded at that moment: numpy's OpenBLAS and the
second OpenBLAS that scipy loads (imported here, so that it is loaded before any solver asks).

The rule (:func:`blas_threads`): one thread below :data:`IDLE_CORES_MIN_ROWS` samples; from there, one
per core that is idle when the solve starts (the process's cores, less those other processes keep busy,
sampled from ``/proc/stat`` over :data:`SAMPLE_SECONDS` and reused for :data:`REUSE_SECONDS`), at
least one. The outermost call of the library decides: a public method (an imputer's ``fit`` and
``transform``, ``minimize_regularized``, ``RobustKernelPCA``'s methods) sets the count for everything
it runs, its own array arithmetic included, and the solvers it calls inside keep that count instead of
choosing again (so a hold-out search that runs its folds on one thread, :func:`single_blas_thread`,
stays on one). In the environment, ``NLDR_AUTO_THREADS=0`` leaves BLAS as the caller set it, and
``NLDR_AUTO_THREADS=small`` sets one thread below :data:`SMALL_PROBLEM_ROWS` and leaves the caller's
setting from there: the pipeline's jobs run so, on their rule's
threads, so that their results do not depend on the machine's load.
"""

from __future__ import annotations

import math
import os
import threading
import time
from contextlib import contextmanager, nullcontext

import scipy.linalg  # noqa: F401  (loads scipy's OpenBLAS now, so every limit below reaches it)
from threadpoolctl import threadpool_limits

__all__ = [
    "SMALL_PROBLEM_ROWS",
    "IDLE_CORES_MIN_ROWS",
    "SAMPLE_SECONDS",
    "REUSE_SECONDS",
    "blas_threads",
    "blas_threads_for",
    "single_blas_thread",
]

#: Below this many samples (kernel rows) the solvers use one BLAS thread whatever the mode (except
#: ``NLDR_AUTO_THREADS=0``) (docs/PERFORMANCE.md#threads).
SMALL_PROBLEM_ROWS = 400
#: From this many samples the library's own choice uses every idle core; below, one thread: between
#: the largest size where a second thread lost and the smallest where it won (measured:
#: docs/PERFORMANCE.md#threads).
IDLE_CORES_MIN_ROWS = 4000
#: How long the idle cores are sampled (seconds of wall time, no CPU) before a large solve.
SAMPLE_SECONDS = 0.1
#: A sample is reused for this long (seconds), so that a loop of solves samples once.
REUSE_SECONDS = 10.0
#: A core counts as idle when at least this share of it was idle in the sample.
IDLE_SHARE = 0.8

_last: tuple[float, int] | None = None  # (time.monotonic() of the sample, idle cores)
_chosen = threading.local()  # .depth > 0 inside a block whose thread count an outer call of ours set


def _cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux
        return os.cpu_count() or 1


def _cpu_ticks() -> tuple[int, int] | None:
    """(idle, total) clock ticks of all CPUs since boot, from /proc/stat; None where unreadable."""
    try:
        with open("/proc/stat") as fh:
            fields = fh.readline().split()
    except OSError:
        return None
    if not fields or fields[0] != "cpu":
        return None
    ticks = [int(x) for x in fields[1:9]]  # user nice system idle iowait irq softirq steal
    return ticks[3] + ticks[4], sum(ticks)


def idle_cores() -> int:
    """Cores of this process that no other process keeps busy now, at least 1.

    From ``/proc/stat`` over :data:`SAMPLE_SECONDS` while this thread sleeps (a core counts if at
    least :data:`IDLE_SHARE` of it was idle); elsewhere from the 1-minute load average. Cached for
    :data:`REUSE_SECONDS`.
    """
    global _last
    now = time.monotonic()
    if _last is not None and now - _last[0] < REUSE_SECONDS:
        return _last[1]
    cores = _cores()
    first = _cpu_ticks()
    if first is not None:
        time.sleep(SAMPLE_SECONDS)
        second = _cpu_ticks()
    if first is not None and second is not None and second[1] > first[1]:
        share = (second[0] - first[0]) / (second[1] - first[1])  # idle share of all the machine's CPUs
        idle = share * (os.cpu_count() or cores)
    else:
        try:
            idle = (os.cpu_count() or cores) - os.getloadavg()[0]
        except OSError:
            idle = 1.0
    count = max(1, min(cores, math.floor(idle + 1.0 - IDLE_SHARE)))
    _last = (time.monotonic(), count)
    return count


def blas_threads(n_samples: int) -> int:
    """The BLAS threads the solvers use on a problem of ``n_samples`` samples (kernel rows): 1 below
    :data:`IDLE_CORES_MIN_ROWS`, else :func:`idle_cores`."""
    if n_samples < IDLE_CORES_MIN_ROWS:
        return 1
    return idle_cores()


@contextmanager
def _limited(threads: int):
    """Every loaded BLAS on ``threads`` threads for the block, which inner calls then keep."""
    depth = getattr(_chosen, "depth", 0)
    _chosen.depth = depth + 1
    try:
        with threadpool_limits(threads, user_api="blas"):
            yield
    finally:
        _chosen.depth = depth


def blas_threads_for(n_samples: int):
    """Context manager: every loaded BLAS on :func:`blas_threads` threads for the block.

    Inside a block an outer call already limited (this function or :func:`single_blas_thread`), no
    change. ``NLDR_AUTO_THREADS=0``: no change; ``NLDR_AUTO_THREADS=small``: one thread below
    :data:`SMALL_PROBLEM_ROWS`, no change above.
    """
    if getattr(_chosen, "depth", 0):
        return nullcontext()
    mode = os.environ.get("NLDR_AUTO_THREADS", "1")
    if mode == "0" or (mode == "small" and n_samples >= SMALL_PROBLEM_ROWS):
        return nullcontext()
    return _limited(blas_threads(n_samples))


def single_blas_thread():
    """Context manager: every loaded BLAS on one thread for the block, kept by the library's calls
    inside it (for work that runs several solves side by side, one per core)."""
    return _limited(1)
