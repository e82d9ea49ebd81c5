"""BLAS threads: the library's default against one and two threads, idle and busy (PERFORMANCE.md#threads).

One completion per case: ``KernelRegularizerImputer()`` (its defaults: standardised columns, the median
width, the exact path up to 150 rows and the Nystroem warm start above) on the first n oil-flow rows
(train, then validation, then test split) with 25 % of the entries missing (mask seed 2016). At
1000 rows the penalty schedule is cut to two stages (rho 1 and 10) of at most 40 inner iterations,
at 3000 rows to one stage (rho 1) of at most 3, to keep the benchmark cheap on a shared machine; the
matrices, hence what a thread buys per operation, are the full problem's.

Thread settings, each in a fresh process so that nothing carries over:

- ``1``, ``2``: ``NLDR_AUTO_THREADS=0`` (the library leaves BLAS alone) and
  ``threadpool_limits(k, user_api="blas")`` around the fit (every loaded OpenBLAS: numpy's and scipy's);
- ``default``: no limit from the caller, no environment variable: the library's own choice
  (:mod:`nldr._threads`), with OpenBLAS starting at its default (one thread per core).

Machine states: ``idle`` (nothing started by this script; the machine may be shared, so "idle" is only
as idle as the others leave it: the load average is printed beside each row) and ``busy`` (one
competing single-threaded numpy matmul loop, started here and stopped by its pid after each case).

Each (state, n, threads) is timed ``--repeats`` times, interleaved (1, 2, default, 1, 2, default, ...)
so that a drift in the machine's load hits every setting alike; the table gives the median wall
seconds, their spread (min-max) and the median CPU seconds of the fit alone.

    .venv/bin/python benchmarks/bench_threads.py [--sizes 100 1000 3000] [--repeats 3]

Costs about 7 CPU minutes on the sizes above, and the competitor's core while the busy cases run.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

SETTINGS = ("1", "2", "default")

CHILD = r"""
import json, sys, time
import numpy as np
setting, n = sys.argv[1], int(sys.argv[2])
from threadpoolctl import threadpool_info, threadpool_limits
from nldr.datasets import load_oil_rows
from nldr.experiments.table2 import random_mask
from nldr.impute import KernelRegularizerImputer
from nldr import _threads

X = load_oil_rows(n)
mask = random_mask(X.shape, 0.25, 2016)
W = np.where(mask, X, np.nan)
kw = {}
if n >= 1000:  # two penalty stages, few inner iterations: the full problem's matrices, fewer steps
    kw = {"schedule": {"rho0": 1.0, "rho_max": 10.0}, "options": {"max_inner": 40}}
if n >= 3000:  # one stage of 3 inner iterations (each solve step of the exact stage: a 3000 x 3000 eigh)
    kw = {"schedule": {"rho0": 1.0, "rho_max": 1.0}, "options": {"max_inner": 3}}
model = KernelRegularizerImputer(**kw)
seen = set()
if setting == "default":
    chosen = _threads.blas_threads(n)
    limit = None
else:
    chosen = int(setting)
    limit = threadpool_limits(chosen, user_api="blas")
wall0, cpu0 = time.perf_counter(), time.process_time()
X_hat = model.fit_transform(W)
wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
blas = sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})
sse = float(np.sum((X_hat - X) ** 2))
print(json.dumps({"wall": wall, "cpu": cpu, "sse": sse, "chosen": chosen, "libs": len(blas)}))
"""

COMPETITOR = r"""
import os
os.sched_setaffinity(0, {0})
import numpy as np
a = np.random.default_rng(0).random((300, 300))
while True:
    a = (a @ a) / 300.0
"""


def run_case(setting: str, n: int) -> dict:
    drop = ("OPENBLAS_", "OMP_", "MKL_", "NLDR_AUTO")  # OpenBLAS starts at its default: a thread per core
    env = {k: v for k, v in os.environ.items() if not k.startswith(drop)}
    if setting != "default":
        env["NLDR_AUTO_THREADS"] = "0"
    out = subprocess.run(
        [sys.executable, "-c", CHILD, setting, str(n)], capture_output=True, text=True, env=env, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


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
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 3000])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--states", nargs="+", default=["idle", "busy"], choices=["idle", "busy"])
    parser.add_argument("--out", type=Path, default=None, help="also write the raw timings (JSON lines)")
    args = parser.parse_args()
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
                times = {s: [] for s in SETTINGS}
                load = []
                for _ in range(args.repeats):
                    for setting in SETTINGS:
                        load.append(os.getloadavg()[0])
                        row = run_case(setting, n)
                        times[setting].append(row)
                        raw.append({"state": state, "n": n, "setting": setting, **row})
            finally:
                if competitor is not None:
                    stop(competitor)
            for setting in SETTINGS:
                walls = [r["wall"] for r in times[setting]]
                cpus = [r["cpu"] for r in times[setting]]
                chosen = sorted({r["chosen"] for r in times[setting]})
                sse = sorted({round(r["sse"], 4) for r in times[setting]})
                print(
                    f"| {state} | {n} | {setting} | {','.join(map(str, chosen))} | "
                    f"{statistics.median(walls):.2f} ({min(walls):.2f}-{max(walls):.2f}) | "
                    f"{statistics.median(cpus):.2f} | {', '.join(map(str, sse))} | "
                    f"{min(load):.1f}-{max(load):.1f} |",
                    flush=True,
                )
    if args.out:
        args.out.write_text("".join(json.dumps(r) + "\n" for r in raw))


if __name__ == "__main__":
    main()
