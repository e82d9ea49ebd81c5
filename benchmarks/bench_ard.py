"""Per-column widths (ARD) for the regularizer, chosen by the hold-out error: do they pay?

ARD here is the RBF kernel ``exp(-gamma sum_j a_j^2 (s_ij - s_kj)^2)`` on the standardised columns,
solved as the isotropic kernel on the columns scaled by ``a_j`` (so the data term's weight of column j is
``a_j^2`` too; see docs/REPRODUCTION.md, "The imputer's defaults"). Per mask (first ``--rows`` oil-flow
training rows, Table 2's masks, seed 2016 + k):

1. ``default``: ``KernelRegularizerImputer()`` (its gamma and tau tuned by its own hold-out);
2. ``ard``: from a = 1, one pass of coordinate search over the columns: a_j times 0.5 or 2, kept when it
   lowers the mean squared hold-out error (original units) on the same folds as the default's tuning
   (2 Monte-Carlo folds hiding 10 % of the observed entries, seed 0), gamma and tau at the default's
   choice; then the solve on every observed entry with the chosen a.

Both are scored by the SSE over the whole matrix (Table 2's error); ground truth is only used to score.
Appends rows to ``--out``; prints mean, sd and count per p.

Usage::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_ard.py --rows 100 --masks 5
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
from nldr.impute import _regularizer as module
from nldr.model_selection import holdout_folds


def solve(Z, mask, a, gamma, tau):
    """The isotropic solve on the columns scaled by a; the estimate in standardised units."""
    est = KernelRegularizerImputer(standardize=False, gamma=gamma, tau=tau, method="exact")
    return est.fit_transform(np.where(mask, Z * a, np.nan)) / a


def run_mask(X, p, seed):
    mask = random_mask(X.shape, p, seed)
    W = np.where(mask, X, np.nan)
    start = time.process_time()
    default = KernelRegularizerImputer().fit(W)
    cpu_default = time.process_time() - start
    mean, sd = default.mean_, default.scale_
    Z = np.where(mask, (W - mean) / sd, np.nan)
    gamma, tau = default.gamma_, default.tau_
    folds = holdout_folds(mask, module.TUNE_FOLDS, 0, holdout=module.TUNE_HOLDOUT)

    def score(a):
        errors = []
        for hidden in folds:
            S = solve(Z, mask & ~hidden, a, gamma, tau) * sd + mean
            errors.append(np.mean((S - X)[hidden] ** 2))
        return float(np.mean(errors))

    start = time.process_time()
    a = np.ones(X.shape[1])
    best = score(a)
    for j in range(X.shape[1]):
        for factor in (0.5, 2.0):
            trial = a.copy()
            trial[j] *= factor
            value = score(trial)
            if value < best:
                a, best = trial, value
                break
    X_ard = solve(Z, mask, a, gamma, tau) * sd + mean
    cpu_ard = time.process_time() - start + cpu_default
    return [
        {
            "p": p,
            "seed": seed,
            "method": "default",
            "sse": float(np.sum((default.completed_ - X) ** 2)),
            "cpu": cpu_default,
            "a": "",
        },
        {
            "p": p,
            "seed": seed,
            "method": "ard",
            "sse": float(np.sum((X_ard - X) ** 2)),
            "cpu": cpu_ard,
            "a": " ".join(f"{v:g}" for v in a),
        },
    ]


def main():
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rows", type=int, default=100)
    parser.add_argument("--p", type=float, nargs="+", default=[0.1, 0.25, 0.5])
    parser.add_argument("--masks", type=int, default=5)
    parser.add_argument("--data", default=None)
    parser.add_argument("--out", default="results/benchmarks/ard.csv")
    args = parser.parse_args()
    X = load_oil("train", args.data)[0][: args.rows]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    for p in args.p:
        for k in range(args.masks):
            done = pd.read_csv(out) if out.exists() else None
            if done is not None and (np.isclose(done["p"], p) & (done["seed"] == 2016 + k)).any():
                continue
            rows = run_mask(X, p, 2016 + k)
            for row in rows:
                print(
                    f"p={p:g} seed={row['seed']} {row['method']:8s} sse={row['sse']:8.3f} "
                    f"cpu={row['cpu']:6.1f}s "
                    f"{row['a']}",
                    flush=True,
                )
            pd.DataFrame(rows).to_csv(out, mode="a", header=not out.exists(), index=False)
    table = pd.read_csv(out)
    print(
        table.groupby(["p", "method"])
        .agg(sse=("sse", "mean"), sd=("sse", "std"), masks=("sse", "size"), cpu=("cpu", "mean"))
        .round(3)
        .to_string()
    )


if __name__ == "__main__":
    main()
