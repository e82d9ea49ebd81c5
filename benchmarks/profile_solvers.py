"""Profile one Table 2 solve and one Table 3 kernel solve (where does the time go?).

Table 2: "Ours" on the first 100 oil-flow rows, p = 0.25, mask seed 2016 (the pipeline's mask).
Table 3: the kernel regularizer (d_med width) on pickup, every 10th frame, full data, started from
the exact-fit TNH (solved first, not profiled).

Writes ``results/benchmarks/profile_table2.txt`` and ``profile_table3.txt``: the top functions by
own time and by cumulative time (cProfile), plus the wall time. BLAS is pinned to one thread.

Usage: .venv/bin/python benchmarks/profile_solvers.py [--data-dir resources]
"""

from __future__ import annotations

import argparse
import cProfile
import io
import pstats
import time
from pathlib import Path

from bench_solvers import oil_problem, pickup_problem  # same problems as the before/after benchmark
from threadpoolctl import threadpool_limits

from nldr.regularizer import minimize_regularized


def profile(fn, path: Path, title: str, top: int = 18) -> float:
    prof = cProfile.Profile()
    start = time.perf_counter()
    prof.enable()
    fn()
    prof.disable()
    wall = time.perf_counter() - start
    out = io.StringIO()
    out.write(f"{title}\nwall time {wall:.3f} s (under cProfile)\n\n== by own time ==\n")
    pstats.Stats(prof, stream=out).strip_dirs().sort_stats("tottime").print_stats(top)
    out.write("\n== by cumulative time ==\n")
    pstats.Stats(prof, stream=out).strip_dirs().sort_stats("cumulative").print_stats(top)
    path.write_text(out.getvalue())
    print(f"{title}: {wall:.2f} s -> {path}")
    return wall


def main(data_dir, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    _, _, S0, term = oil_problem(data_dir, 100)
    with threadpool_limits(1):
        profile(
            lambda: minimize_regularized(term, S0, gamma=0.075, tau=0.1),
            out / "profile_table2.txt",
            "Table 2: Ours, oil flow 100 x 12, p = 0.25, seed 2016",
        )
        data, X0, gamma = pickup_problem(data_dir)
        profile(
            lambda: minimize_regularized(
                data, X0, gamma=gamma, tau=1e-4, rho0=1e-3, rho_growth=10.0, rho_max=10.0,
                options={"scale": 1.0},  # Table 3's units
            ),
            out / "profile_table3.txt",
            f"Table 3: kernel d_med on pickup (every 10th frame, {X0.shape[0]} frames), full data",
        )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", default="resources")
    parser.add_argument("--out", type=Path, default=Path("results/benchmarks"))
    args = parser.parse_args()
    main(args.data_dir, args.out)
