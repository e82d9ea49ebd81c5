"""Benchmark: trace-norm heuristic (TNH) with ground-truth cameras on the CMU mocap sequences.

The protocol of the paper's Table 3 (linear columns): every 10th frame from the first, 41 points,
original units (the stored copies are multiplied back by ``scale``), ground-truth cameras ``Rs``;
TNH in its exact-fit form (the paper's tau = 1e-7) through cvxpy's conic solvers
(``trace_norm_heuristic(..., method="cvxpy")``); e3D as in :mod:`nldr.nrsfm._metrics`; full data
and 50% of the (frame, point) observations removed at random (seeded).

Usage (from the repository root)::

    .venv/bin/python benchmarks/bench_tnh.py                       # SCS, full + 2 missing-data seeds
    .venv/bin/python benchmarks/bench_tnh.py --solvers SCS CLARABEL --clarabel-timeout 120
    .venv/bin/python benchmarks/bench_tnh.py --sequences pickup --eps 1e-5 1e-7 --seeds

A CLARABEL solve runs in a child process that is terminated after ``--clarabel-timeout`` seconds.
"""

from __future__ import annotations

import argparse
import csv
import multiprocessing as mp
import sys
import time

import numpy as np
from threadpoolctl import threadpool_limits

from nldr.datasets import load_mocap
from nldr.nrsfm import trace_norm_heuristic
from nldr.nrsfm._layout import random_visibility_mask, stack_to_rows
from nldr.nrsfm._metrics import e3d

# Paper, Table 3, "Linear" (TNH) columns: no missing data, 50% missing data.
PAPER_TNH = {
    "drink": (0.0227, 0.0313),
    "pickup": (0.0487, 0.0936),
    "yoga": (0.0344, 0.0828),
    "stretch": (0.0418, 0.0911),
}


def _solve(W2d, R, mask, tau, solver, options, threads):
    with threadpool_limits(threads):
        return trace_norm_heuristic(
            W2d, R, mask, tau=tau, method="cvxpy", solver=solver, solver_options=options
        )


def _child(queue, args):
    try:
        queue.put(("ok", _solve(*args)))
    except Exception as exc:  # report any failure to the parent instead of hanging it
        queue.put(("error", f"{type(exc).__name__}: {exc}"))


def solve_with_timeout(args, timeout):
    """Run :func:`_solve` in a child process; return (result or None, message)."""
    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_child, args=(queue, args))
    child.start()
    try:
        kind, payload = queue.get(timeout=timeout)
    except Exception:  # queue.Empty: the solve did not finish in time
        child.terminate()
        child.join()
        return None, f"timeout > {timeout:g} s"
    child.join()
    return (payload, "") if kind == "ok" else (None, payload)


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sequences", nargs="+", default=list(PAPER_TNH))
    parser.add_argument("--solvers", nargs="+", default=["SCS"], help="SCS and/or CLARABEL")
    parser.add_argument(
        "--eps",
        nargs="+",
        type=float,
        default=[None],
        help="SCS eps_abs = eps_rel values (default: the library default)",
    )
    parser.add_argument(
        "--tau", type=float, default=None, help="penalised TNH with this tau (default exact fit)"
    )
    parser.add_argument(
        "--seeds", nargs="*", type=int, default=[0, 1], help="missing-data seeds (none: skip)"
    )
    parser.add_argument("--missing", type=float, default=0.5, help="fraction of observations removed")
    parser.add_argument("--clarabel-timeout", type=float, default=120.0)
    parser.add_argument("--step", type=int, default=10, help="keep every step-th frame")
    parser.add_argument("--threads", type=int, default=1, help="BLAS threads per solve")
    parser.add_argument("--data-dir", default=None, help="data folder (default resources/)")
    parser.add_argument("--csv", default=None, help="also write the rows to this CSV file")
    args = parser.parse_args(argv)

    rows = []
    header = (
        f"{'sequence':8} {'F':>4} {'setting':12} {'solver':8} {'eps':>7} {'e3D':>8} {'aligned':>8} "
        f"{'paper':>7} {'time[s]':>8} {'iters':>6} {'max|r|':>8} status"
    )
    print(header, flush=True)
    for name in args.sequences:
        seq = load_mocap(name, data_dir=args.data_dir).subsample(args.step)
        F, P = seq.n_frames, seq.n_points
        W2d, X_gt = stack_to_rows(seq.W, 2), stack_to_rows(seq.S)
        settings = [("full", np.ones((F, P), dtype=bool), 0)]
        settings += [
            (f"miss seed {s}", random_visibility_mask(F, P, args.missing, random_state=s), 1)
            for s in args.seeds
        ]
        for setting, mask, paper_col in settings:
            for solver in args.solvers:
                solver = solver.upper()
                for eps in args.eps if solver == "SCS" else [None]:
                    options = None if eps is None else {"eps_abs": eps, "eps_rel": eps}
                    call = (W2d, seq.R, mask, args.tau, solver, options, args.threads)
                    start = time.perf_counter()
                    if solver == "CLARABEL":
                        result, message = solve_with_timeout(call, args.clarabel_timeout)
                    else:
                        result, message = _solve(*call), ""
                    wall = time.perf_counter() - start
                    row = {
                        "sequence": name,
                        "n_frames": F,
                        "setting": setting,
                        "solver": solver,
                        "eps": "" if eps is None else eps,
                        "tau": args.tau or 0.0,
                        "paper_e3d": PAPER_TNH.get(name, (np.nan, np.nan))[paper_col],
                        "wall_time": wall,
                    }
                    if result is None:
                        row |= {
                            "e3d": np.nan,
                            "e3d_aligned": np.nan,
                            "n_iter": "",
                            "max_abs_residual": np.nan,
                            "status": message,
                        }
                    else:
                        row |= {
                            "e3d": e3d(result.x, X_gt, P),
                            "e3d_aligned": e3d(result.x, X_gt, P, align=True),
                            "n_iter": result.nit,
                            "max_abs_residual": result.max_abs_residual,
                            "status": result.message,
                            "solve_time": result.wall_time,
                        }
                    rows.append(row)
                    print(
                        f"{name:8} {F:>4} {setting:12} {solver:8} {str(row['eps']):>7} "
                        f"{row['e3d']:8.4f} {row['e3d_aligned']:8.4f} {row['paper_e3d']:7.4f} {wall:8.1f} "
                        f"{str(row['n_iter']):>6} {row['max_abs_residual']:8.1e} {row['status']}",
                        flush=True,
                    )
    if args.csv:
        fields = sorted({key for row in rows for key in row})
        with open(args.csv, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=fields)
            writer.writeheader()
            writer.writerows(rows)
    return rows


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
