"""The regularizer against the imputers people use (issue 16), on Table 2's protocol: SSE and CPU cost.

Protocol: the first ``--rows`` oil-flow training rows, masks from
:func:`nldr.experiments._table2.random_mask` (mask k at p uses seed 2016 + k, Table 2's masks), one BLAS
thread, CPU seconds by ``time.process_time``. Per mask:

- ``Ours``: the regularizer at Table 2's settings (gamma 0.075, tau 0.1, uncentred, rho 1 -> 1e4),
  from mean imputation (Table 2's "Ours" row);
- each peer with its knob chosen by :class:`nldr.model_selection.HoldoutSearch` on 5 hold-out folds of
  the observed entries (seed = the mask's seed) over :func:`nldr.impute.baseline_grid`, then
  refitted on every observed entry; IterativeImputer has no knob and is fitted once.

``cpu`` is the whole method (CV and refit), ``cpu_fit`` one fit at the chosen knob (the refit).
Appends one row per (mask, method) to ``--out`` as it goes, so a long run can be stopped and resumed
(rows already there are skipped).

Usage::

    python benchmarks/bench_peers.py --rows 100 --p 0.05 0.1 0.25 0.5 --masks 10
    python benchmarks/bench_peers.py --rows 1000 --p 0.25 --masks 3 --out results/benchmarks/peers_1000.csv
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
from sklearn.base import clone
from threadpoolctl import threadpool_limits

from nldr.datasets import load_oil
from nldr.experiments._table2 import random_mask
from nldr.impute import KernelRegularizerImputer, baseline_grid
from nldr.model_selection import HoldoutSearch

#: Table 2's Ours, the paper's settings written out
OURS = KernelRegularizerImputer(standardize=False, gamma=0.075, tau=0.1, center=False, method="exact")
PEERS = ("KNNImputer", "IterativeImputer", "SoftImpute", "missForest")


def timed(fn):
    start = time.process_time()
    out = fn()
    return out, time.process_time() - start


def run_mask(X, p, seed, methods, n_folds):
    mask = random_mask(X.shape, p, seed)
    W = np.where(mask, X, np.nan)
    rows = []

    def record(method, X_hat, cpu, cpu_fit, params=""):
        sse = float(np.sum((X_hat - X) ** 2))
        rows.append(
            {
                "n_rows": X.shape[0],
                "p": p,
                "seed": seed,
                "method": method,
                "sse": sse,
                "cpu": cpu,
                "cpu_fit": cpu_fit,
                "params": params,
            }
        )
        print(
            f"n={X.shape[0]} p={p:g} seed={seed} {method:18s} sse={sse:9.3f} cpu={cpu:8.2f}s {params}",
            flush=True,
        )

    if "Ours" in methods:
        ours = clone(OURS)
        X_hat, cpu = timed(lambda: ours.fit_transform(W))
        record("Ours", X_hat, cpu, cpu, f"nit={ours.result_.nit}")
    for method in methods:
        if method == "Ours":
            continue
        estimator, grid = baseline_grid(method, W)
        if not grid:
            X_hat, cpu = timed(lambda estimator=estimator: clone(estimator).fit_transform(W))
            record(method, X_hat, cpu, cpu)
            continue
        search = HoldoutSearch(estimator, grid, n_folds=n_folds, random_state=seed)
        X_hat, cpu = timed(lambda search=search: search.fit_transform(W))
        best = clone(estimator).set_params(**search.best_params_)
        _, cpu_fit = timed(lambda best=best: best.fit_transform(W))
        record(f"{method} (CV)", X_hat, cpu, cpu_fit, repr(search.best_params_))
    return rows


def main():
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rows", type=int, default=100)
    parser.add_argument("--p", type=float, nargs="+", default=[0.05, 0.1, 0.25, 0.5])
    parser.add_argument("--masks", type=int, default=10)
    parser.add_argument("--first-mask", type=int, default=0)
    parser.add_argument("--seed", type=int, default=2016)
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--methods", nargs="+", default=["Ours", *PEERS])
    parser.add_argument("--data", default="resources")
    parser.add_argument("--out", default="results/benchmarks/peers.csv")
    args = parser.parse_args()
    X, _ = load_oil("train", args.data)
    X = X[: args.rows]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    done = pd.read_csv(out) if out.exists() else pd.DataFrame(columns=["n_rows", "p", "seed"])
    with threadpool_limits(1):
        for p in args.p:
            for k in range(args.first_mask, args.first_mask + args.masks):
                seed = args.seed + k
                seen = (
                    (done["n_rows"] == args.rows)
                    & np.isclose(done["p"].astype(float), p)
                    & (done["seed"] == seed)
                )
                if seen.any():
                    continue
                frame = pd.DataFrame(run_mask(X, p, seed, args.methods, args.folds))
                frame.to_csv(out, mode="a", header=not out.exists(), index=False)
    table = pd.read_csv(out)
    table = table[table["n_rows"] == args.rows]
    summary = table.groupby(["p", "method"]).agg(
        sse=("sse", "mean"),
        sse_sd=("sse", "std"),
        masks=("sse", "size"),
        cpu=("cpu", "mean"),
        cpu_fit=("cpu_fit", "mean"),
    )
    print(summary.round(3).to_string())


if __name__ == "__main__":
    main()
