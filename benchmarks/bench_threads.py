"""BLAS threads: the library's default against one and two threads, idle and busy (PERFORMANCE.md#threads).

One completion per case: ``KernelRegularizerImputer(random_state=0)`` (defaults otherwise: standardised
columns, the hold-out search of width and tau, then the solver path ``method="auto"`` picks by
size: exact up to 150 rows, the Nystroem warm start up to 1499, every stage on 200 landmarks from
1500; a fixed ``random_state``, so that every fit is the same computation) on the first n oil-flow
rows (train, then validation, then test split) with 25 % of the entries missing (Table 2's mask of
seed 2016, :func:`nldr.experiments._table2.random_mask`, private: the pipeline's masks).
From 1000 rows the penalty schedule of every solve (the search's and the final one) is cut to two
stages (rho 1 and 10) of at most 15 inner iterations, to keep the benchmark cheap on a shared
machine; the matrices, hence what a thread buys per operation, are the full problem's. The search's
fold solves run on one thread in every setting (:func:`nldr._threads.single_blas_thread`). The
rule itself is private (:mod:`nldr._threads`): the ``default`` setting reads the count it chose
(:func:`nldr._threads.blas_threads`), which is what this script measures.

Thread settings, each in a fresh process so that nothing carries over:

- ``1``, ``2``: ``NLDR_AUTO_THREADS=0`` (the library leaves BLAS alone) and
  ``threadpool_limits(k, user_api="blas")`` around the fit (every loaded OpenBLAS: numpy's and scipy's);
- ``default``: no limit from the caller, no environment variable: the library's own choice
  (:mod:`nldr._threads`), with OpenBLAS starting at its default (one thread per core).

Machine states: ``idle`` (nothing started by this script; the machine may be shared, so "idle" is only
as idle as the others leave it: the load average is printed beside each row) and ``busy`` (one
competing single-threaded numpy matmul loop, started here and stopped by its pid after each case).

Each (state, n, threads) is timed ``--repeats`` times in one fresh process (the first fit included:
imports and data loading are outside the timings); a process still running after ``--cap`` wall
seconds is stopped and its unfinished fits are shown as ``inf`` (slower than the cap). The table
gives the median wall seconds, their spread (min-max), the median CPU seconds of the fit alone, and
the load average before and after; ``--out``/threads.csv keeps every fit's timings. The script sets
the threads of its child processes itself, so ``OPENBLAS_NUM_THREADS`` need not be set.
``--quick``: 100 rows, one fit per setting, idle only.

    python benchmarks/bench_threads.py [--sizes 100 1000 3000] [--repeats 3]
"""

from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
import time

from _common import check_blas, parser, write_csv

SETTINGS = ("1", "2", "default")

CHILD = r"""
import json, sys
import numpy as np
setting, n, repeats = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
data_dir = sys.argv[4] or None
sys.path.insert(0, sys.argv[5])  # benchmarks/, for _common
from _common import cpu_and_wall
from threadpoolctl import threadpool_limits
from nldr.datasets import load_oil_rows
from nldr.experiments._table2 import random_mask
from nldr.impute import KernelRegularizerImputer
from nldr import _threads

X = load_oil_rows(n, data_dir)
mask = random_mask(X.shape, 0.25, 2016)
W = np.where(mask, X, np.nan)
kw = {}
if n >= 1000:  # two penalty stages, few inner iterations: the full problem's matrices, fewer steps
    kw = {"schedule": {"rho0": 1.0, "rho_max": 10.0}, "options": {"max_inner": 15}}
model = KernelRegularizerImputer(random_state=0, **kw)  # the same landmarks in every fit
if setting == "default":
    chosen = _threads.blas_threads(n)
    limit = None
else:
    chosen = int(setting)
    limit = threadpool_limits(chosen, user_api="blas")
for _ in range(repeats):
    cpu, wall, X_hat = cpu_and_wall(lambda: model.fit_transform(W))
    sse = float(np.sum((X_hat - X) ** 2))
    if setting == "default":
        chosen = _threads.blas_threads(n)
    print(json.dumps({"wall": wall, "cpu": cpu, "sse": sse, "chosen": chosen}), flush=True)
"""

COMPETITOR = r"""
import os
os.sched_setaffinity(0, {0})
import numpy as np
a = np.random.default_rng(0).random((300, 300))
while True:
    a = (a @ a) / 300.0
"""


def run_case(setting: str, n: int, repeats: int, cap: float, data_dir) -> list[dict]:
    """``repeats`` fits in one fresh process; a process still running after ``cap`` wall seconds is
    stopped and its unfinished fits count as ``> cap`` (wall: inf)."""
    drop = ("OPENBLAS_", "OMP_", "MKL_", "NLDR_AUTO")  # OpenBLAS starts at its default: a thread per core
    env = {k: v for k, v in os.environ.items() if not k.startswith(drop)}
    if setting != "default":
        env["NLDR_AUTO_THREADS"] = "0"
    here = os.path.dirname(os.path.abspath(__file__))
    cmd = [sys.executable, "-c", CHILD, setting, str(n), str(repeats), data_dir or "", here]
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, env=env, check=True, timeout=cap).stdout
    except subprocess.TimeoutExpired as exc:
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
    rows = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
    censored = {"wall": math.inf, "cpu": math.nan, "sse": math.nan, "chosen": -1}
    return rows + [censored] * (repeats - len(rows))


def start_competitor() -> subprocess.Popen:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    return subprocess.Popen([sys.executable, "-c", COMPETITOR], env=env)


def stop(proc: subprocess.Popen) -> None:
    proc.terminate()
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def main() -> None:
    ap = parser(__doc__, repeats=3)
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 3000])
    ap.add_argument("--cap", type=float, default=150.0, help="wall seconds per setting's process")
    ap.add_argument("--states", nargs="+", default=["idle", "busy"], choices=["idle", "busy"])
    args = ap.parse_args()
    if args.quick:
        args.sizes, args.repeats, args.states = [100], 1, ["idle"]
    check_blas(measures_threads=True)
    raw = []
    print(f"{os.cpu_count()} CPUs; load average at start {os.getloadavg()[0]:.1f}")
    print("| state | rows | threads | chosen | wall s median (min-max) | CPU s median | SSE | load |")
    print("|---|---|---|---|---|---|---|---|")
    for state in args.states:
        for n in args.sizes:
            competitor = start_competitor() if state == "busy" else None
            try:
                if competitor is not None:
                    time.sleep(1.0)  # let it reach its loop
                times, load = {}, [os.getloadavg()[0]]
                for setting in SETTINGS:
                    times[setting] = run_case(setting, n, args.repeats, args.cap, args.data_dir)
                    load.append(os.getloadavg()[0])
                    raw += [{"state": state, "n": n, "setting": setting, **r} for r in times[setting]]
            finally:
                if competitor is not None:
                    stop(competitor)
            for setting in SETTINGS:
                walls = [r["wall"] for r in times[setting]]
                cpus = [r["cpu"] for r in times[setting]]
                chosen = sorted({r["chosen"] for r in times[setting] if r["chosen"] > 0})
                sse = sorted({round(r["sse"], 4) for r in times[setting] if r["sse"] == r["sse"]})
                print(
                    f"| {state} | {n} | {setting} | {','.join(map(str, chosen))} | "
                    f"{statistics.median(walls):.2f} ({min(walls):.2f}-{max(walls):.2f}) | "
                    f"{statistics.median(cpus):.2f} | {', '.join(map(str, sse))} | "
                    f"{min(load):.1f}-{max(load):.1f} |",
                    flush=True,
                )
    write_csv(raw, args.out, "threads.csv")


if __name__ == "__main__":
    main()
