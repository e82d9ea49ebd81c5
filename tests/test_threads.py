"""nldr._threads: which BLAS thread count the solvers choose, and that it reaches every loaded BLAS.

No timing here (that is benchmarks/bench_threads.py): the rule's logic, with the machine's idle share
replaced by chosen numbers.
"""

import subprocess
import sys

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from nldr import _threads


def _blas():
    return {(i["filepath"], i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"}


@pytest.fixture
def machine(monkeypatch):
    """A fake machine: ``cores`` CPUs, of which a share ``idle`` is idle in every /proc/stat sample."""
    state = {"cores": 4, "idle": 1.0, "ticks": 0, "samples": 0}

    def ticks():
        state["samples"] += 1
        state["ticks"] += 1000
        return int(state["ticks"] * state["idle"]), state["ticks"]

    monkeypatch.setattr(_threads, "_cpu_ticks", ticks)
    monkeypatch.setattr(_threads, "_cores", lambda: state["cores"])
    monkeypatch.setattr(_threads.os, "cpu_count", lambda: state["cores"])
    monkeypatch.setattr(_threads, "SAMPLE_SECONDS", 0.0)
    monkeypatch.setattr(_threads, "_last", None)
    monkeypatch.delenv("NLDR_AUTO_THREADS", raising=False)
    return state


@pytest.mark.parametrize(
    "cores, idle, expected",
    [
        (4, 1.0, 4),  # an idle machine: every core
        (2, 1.0, 2),
        (2, 0.5, 1),  # one of two cores busy: one thread
        (2, 0.45, 1),
        (2, 0.0, 1),  # every core busy: still one
        (4, 0.55, 2),  # 2.2 idle cores -> 2
        (4, 0.68, 2),  # 2.72 idle cores: the third is 72 % idle, under IDLE_SHARE (80 %): 2
        (4, 0.72, 3),  # 2.88 idle cores: the third is 88 % idle: 3
        (4, 0.95, 4),  # 3.8 idle cores: a core at least IDLE_SHARE (80 %) idle counts
    ],
)
def test_large_problems_get_one_thread_per_idle_core(machine, cores, idle, expected):
    machine.update(cores=cores, idle=idle)
    assert _threads.blas_threads(_threads.IDLE_CORES_MIN_ROWS) == expected
    assert _threads.blas_threads(_threads.IDLE_CORES_MIN_ROWS - 1) == 1  # below: one, whatever is idle
    assert _threads.blas_threads(_threads.SMALL_PROBLEM_ROWS) == 1


def test_the_sample_is_reused_for_a_while(machine, monkeypatch):
    machine.update(cores=2, idle=1.0)
    n = _threads.IDLE_CORES_MIN_ROWS
    assert _threads.blas_threads(n) == 2
    samples = machine["samples"]
    machine.update(idle=0.0)
    assert _threads.blas_threads(n) == 2  # within REUSE_SECONDS: the same answer, no new sample
    assert machine["samples"] == samples
    monkeypatch.setattr(_threads, "REUSE_SECONDS", 0.0)
    assert _threads.blas_threads(n) == 1  # stale: sampled again
    assert machine["samples"] > samples


def test_without_proc_stat_the_load_average_decides(machine, monkeypatch):
    monkeypatch.setattr(_threads, "_cpu_ticks", lambda: None)
    monkeypatch.setattr(_threads.os, "getloadavg", lambda: (2.9, 0.0, 0.0))
    machine.update(cores=4)
    assert _threads.idle_cores() == 1  # 4 - 2.9 = 1.1 idle


@pytest.mark.parametrize("rows", [100, 1000])
@pytest.mark.parametrize("mode", ["1", "small", "0"])
def test_the_limit_reaches_every_loaded_blas_at_call_time(machine, monkeypatch, rows, mode):
    """Inside blas_threads_for every loaded BLAS (numpy's and scipy's OpenBLAS) runs the chosen count,
    whatever the caller set; NLDR_AUTO_THREADS=small keeps the caller's above SMALL_PROBLEM_ROWS, =0
    everywhere."""
    monkeypatch.setenv("NLDR_AUTO_THREADS", mode)
    machine.update(cores=4, idle=0.0)  # busy: the rule says 1
    with threadpool_limits(3, user_api="blas"):
        callers = _blas()
        with _threads.blas_threads_for(rows):
            inside = _blas()
    assert {t for _, t in callers} <= {1, 3}  # each library runs 3, or 1 if it is a one-thread build
    keep = mode == "0" or (mode == "small" and rows >= _threads.SMALL_PROBLEM_ROWS)
    assert inside == (callers if keep else {(path, 1) for path, _ in callers})


def test_a_limit_set_before_import_does_not_decide_for_scipys_blas():
    """threadpool_limits(1) before `import nldr` reaches numpy's OpenBLAS only (scipy's is loaded
    later); the solver's own limit reaches both, at every size."""
    code = """
import os
from threadpoolctl import threadpool_info, threadpool_limits
threadpool_limits(1, user_api="blas")  # the caller's limit, before nldr loads scipy
before = {i["filepath"] for i in threadpool_info() if i["user_api"] == "blas"}
from nldr import _threads
_threads.idle_cores = lambda: 1  # a busy machine
after = {i["filepath"] for i in threadpool_info() if i["user_api"] == "blas"}
with threadpool_limits(2, user_api="blas"):  # what a later-loaded BLAS starts with, made explicit
    with _threads.blas_threads_for(1000):
        inside = {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}
print(len(before), len(after), sorted(inside))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    n_before, n_after, inside = out.stdout.split(maxsplit=2)
    assert int(n_after) >= int(n_before)  # importing nldr._threads loads scipy's BLAS, if it has its own
    assert inside.strip() == "[1]"


def test_the_regularizer_solves_on_the_chosen_threads(machine, monkeypatch):
    """minimize_regularized asks _threads at call time, at a size above SMALL_PROBLEM_ROWS too."""
    from nldr.data_terms import MaskedLeastSquares
    from nldr.regularizer import minimize_regularized

    seen = set()

    class Spy(MaskedLeastSquares):
        def gradient(self, S):
            seen.update(t for _, t in _blas())
            return super().gradient(S)

    machine.update(cores=4, idle=0.0)
    monkeypatch.setattr(_threads, "SMALL_PROBLEM_ROWS", 10)  # a 40-row problem counts as large
    monkeypatch.setattr(_threads, "IDLE_CORES_MIN_ROWS", 10)
    rng = np.random.default_rng(5)
    X = rng.random((40, 4))
    mask = rng.random(X.shape) > 0.2
    S0 = np.where(mask, X, np.nanmean(np.where(mask, X, np.nan), axis=0))
    with threadpool_limits(3, user_api="blas"):
        callers = {t for _, t in _blas()}
        minimize_regularized(
            Spy(np.where(mask, X, np.nan), mask),
            S0,
            gamma=1.0,
            tau=0.1,
            rho_max=10.0,
            options={"max_inner": 20},
        )
    assert seen == {1} and (3 in callers or callers == {1})


def test_an_outer_choice_holds_inside(machine):
    """Inside a block the library already limited, its inner calls keep that count: a search's
    one-thread folds stay on one thread on an idle machine, where a large solve alone would take 4."""
    machine.update(cores=4, idle=1.0)
    large = _threads.IDLE_CORES_MIN_ROWS
    with threadpool_limits(3, user_api="blas"):
        callers = _blas()
        with _threads.single_blas_thread():
            with _threads.blas_threads_for(large):  # alone: 4 threads
                inside = _blas()
        with _threads.blas_threads_for(large):
            with _threads.blas_threads_for(10):  # alone: 1 thread
                nested = _blas()
        after = _blas()
    assert inside == {(path, 1) for path, _ in callers}
    assert nested == {(path, 4 if t == 3 else 1) for path, t in callers}  # a one-thread build stays at 1
    assert after == callers  # every block restores the caller's setting


def test_an_imputer_runs_its_own_arithmetic_on_the_chosen_threads(machine, monkeypatch):
    """fit and transform set the count for the whole call, the estimator's arithmetic outside the
    solver included (here its column standardisation and its neighbour search)."""
    from nldr.impute import KernelRegularizerImputer
    from nldr.impute import _regularizer as module

    seen = {"fit": set(), "transform": set()}
    phase = {"now": "fit"}

    def spy(name):
        real = getattr(module, name)

        def wrapped(*args, **kwargs):
            seen[phase["now"]].update(t for _, t in _blas())
            return real(*args, **kwargs)

        monkeypatch.setattr(module, name, wrapped)

    spy("observed_standardisation")
    spy("nearest_rows")
    machine.update(cores=4, idle=0.0)  # busy: the rule says 1
    monkeypatch.setattr(_threads, "SMALL_PROBLEM_ROWS", 10)  # 30 rows count as large
    monkeypatch.setattr(_threads, "IDLE_CORES_MIN_ROWS", 10)
    rng = np.random.default_rng(3)
    X = rng.random((30, 4))
    W = np.where(rng.random(X.shape) > 0.2, X, np.nan)
    model = KernelRegularizerImputer(
        gamma=1.0,
        tau=0.1,
        n_neighbors=1,
        starts="mean",
        rho_max=10.0,
        max_iter=10,
    )
    with threadpool_limits(3, user_api="blas"):
        callers = {t for _, t in _blas()}
        model.fit(W)
        phase["now"] = "transform"
        new = W[:3] + 0.01
        model.transform(new)
    assert seen["fit"] == {1} and seen["transform"] == {1}
    assert 3 in callers or callers == {1}
