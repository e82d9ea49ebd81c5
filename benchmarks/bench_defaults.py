"""The imputer's no-argument defaults against the paper's settings and missForest (100 trees, CV).

Protocol: the first ``--rows`` oil-flow training rows, Table 2's masks
(:func:`nldr.experiments._table2.random_mask`, mask k at p uses seed 2016 + k), CPU seconds by
``time.process_time``; run with ``OPENBLAS_NUM_THREADS=1`` in the environment (the machine may be
shared: CPU seconds, not wall time, and compare methods within one session). Per mask:

- ``default``: ``KernelRegularizerImputer()`` with no arguments (its own hold-out tuning included in
  its CPU seconds), ``random_state`` left at its default;
- ``paper``: the paper's Table 2 settings written out (raw columns, gamma 0.075, tau 0.1, exact);
- ``missForest100``: missForest with 100 trees (``missforest_imputer(n_estimators=100)``), its
  ``max_features`` in {1/3, 1} chosen by :class:`nldr.model_selection.HoldoutSearch` on ``--folds``
  hold-out folds of the observed entries (seed = the mask's seed), refitted on every observed entry.
  (Per-column widths are tried by ``bench_ard.py``.)

Appends one row per (mask, method) to ``--out`` as it goes (rows already there are skipped), then
prints mean, sample sd and count of the SSE per (rows, p, method).

Usage::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py --rows 100 --masks 10
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py --rows 1000 --masks 3 --methods default
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from nldr.datasets import load_oil
from nldr.experiments._table2 import random_mask
from nldr.impute import KernelRegularizerImputer
from nldr.impute._grids import missforest_imputer
from nldr.model_selection import HoldoutSearch

METHODS = ("default", "paper", "missForest100")


def estimator(method: str, seed: int, folds: int):
    if method == "default":
        return KernelRegularizerImputer()
    if method == "paper":
        return KernelRegularizerImputer(standardize=False, gamma=0.075, tau=0.1, center=False, method="exact")
    if method == "missForest100":
        forest = missforest_imputer(n_estimators=100)
        grid = {"estimator__max_features": [1 / 3, 1.0]}
        return HoldoutSearch(forest, grid, n_folds=folds, random_state=seed)
    raise ValueError(f"method must be one of {METHODS}; got {method!r}")


def describe(method, fitted) -> str:
    if isinstance(fitted, HoldoutSearch):
        return repr(fitted.best_params_)
    if isinstance(fitted, KernelRegularizerImputer):
        return f"gamma={fitted.gamma_:.4g} tau={fitted.tau_:.4g} method={fitted.method_}"
    return ""


def main():
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rows", type=int, default=100)
    parser.add_argument("--p", type=float, nargs="+", default=[0.1, 0.25, 0.5])
    parser.add_argument("--masks", type=int, default=10)
    parser.add_argument("--first-mask", type=int, default=0)
    parser.add_argument("--seed", type=int, default=2016)
    parser.add_argument("--folds", type=int, default=3)
    parser.add_argument("--methods", nargs="+", default=list(METHODS))
    parser.add_argument("--data", default=None)
    parser.add_argument("--out", default="results/benchmarks/defaults.csv")
    args = parser.parse_args()
    X = load_oil("train", args.data)[0][: args.rows]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    for p in args.p:
        for k in range(args.first_mask, args.first_mask + args.masks):
            seed = args.seed + k
            mask = random_mask(X.shape, p, seed)
            W = np.where(mask, X, np.nan)
            for method in args.methods:
                done = pd.read_csv(out) if out.exists() else None
                if (
                    done is not None
                    and (
                        (done["n_rows"] == args.rows)
                        & np.isclose(done["p"], p)
                        & (done["seed"] == seed)
                        & (done["method"] == method)
                    ).any()
                ):
                    continue
                fitted = estimator(method, seed, args.folds)
                start = time.process_time()
                X_hat = fitted.fit_transform(W)
                cpu = time.process_time() - start
                sse = float(np.sum((X_hat - X) ** 2))
                row = {
                    "n_rows": args.rows,
                    "p": p,
                    "seed": seed,
                    "method": method,
                    "sse": sse,
                    "cpu": cpu,
                    "params": describe(method, fitted),
                }
                print(
                    f"n={args.rows} p={p:g} seed={seed} {method:14s} sse={sse:9.3f} cpu={cpu:7.2f}s "
                    f"{row['params']}",
                    flush=True,
                )
                pd.DataFrame([row]).to_csv(out, mode="a", header=not out.exists(), index=False)
    table = pd.read_csv(out)
    table = table[table["n_rows"] == args.rows]
    summary = table.groupby(["p", "method"]).agg(
        sse=("sse", "mean"), sse_sd=("sse", "std"), masks=("sse", "size"), cpu=("cpu", "mean")
    )
    print(summary.round(3).to_string())


if __name__ == "__main__":
    main()
