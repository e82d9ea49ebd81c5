"""Benchmark of hold-out selection of (tau, gamma) on the paper's Table 2 protocol.

Protocol: the first 100 oil-flow training rows (100 x 12), p = 0.25, masks from
:func:`nldr.experiments.table2.random_mask` (seeds 2016, ...), mean-imputation start, uncentred kernel,
one BLAS thread. Per mask it times one solve at the paper's values (gamma 0.075, tau 0.1) and one
:func:`nldr.model_selection.select_regularizer` with its defaults, and reports the SSE over the whole
matrix of: the paper's values, the CV-selected values (the refit), and the grid point with the smallest
SSE against ground truth (an ORACLE: it sees the truth, so it is only a bound, never a method).

Writes ``results/benchmarks/model_selection.csv`` (one row per mask) and prints a summary.

Usage::

    .venv/bin/python benchmarks/bench_model_selection.py --masks 3
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from nldr.baselines import mean_impute
from nldr.data_terms import MaskedLeastSquares
from nldr.datasets import load_oil
from nldr.experiments.table2 import random_mask
from nldr.model_selection import select_regularizer
from nldr.regularizer import minimize_regularized

PAPER = {"gamma": 0.075, "tau": 0.1}


def run_mask(X, p, seed):
    mask = random_mask(X.shape, p, seed)
    W = np.where(mask, X, np.nan)
    term, S0 = MaskedLeastSquares(W, mask), mean_impute(W, mask)

    def sse(S):
        return float(np.sum((S - X) ** 2))

    start = time.perf_counter()
    paper = minimize_regularized(term, S0, **PAPER)
    solve_time = time.perf_counter() - start
    start = time.perf_counter()
    sel = select_regularizer(W, mask)
    select_time = time.perf_counter() - start
    # ORACLE: every grid point solved on all observed entries and scored against the truth.
    oracle = min(
        (sse(minimize_regularized(term, S0, gamma=g, tau=t, isolation_guard=True).x), t, g)
        for t, g in zip(sel.cv_results_["tau"], sel.cv_results_["gamma"], strict=True)
    )
    return {
        "p": p,
        "seed": seed,
        "solve_time": solve_time,
        "select_time": select_time,
        "select_over_solve": select_time / solve_time,
        "sse_paper": sse(paper.x),
        "sse_cv": sse(sel.result_.x),
        "tau_cv": sel.tau_,
        "gamma_cv": sel.gamma_,
        "sse_oracle": oracle[0],
        "tau_oracle": oracle[1],
        "gamma_oracle": oracle[2],
        "n_candidates": len(sel.cv_results_),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--masks", type=int, default=3)
    parser.add_argument("--p", type=float, default=0.25)
    parser.add_argument("--data", default="/work/shared/data")
    parser.add_argument("--out", default="results/benchmarks")
    args = parser.parse_args()
    X = load_oil("train", args.data)[0][:100]
    rows = []
    with threadpool_limits(1):
        for seed in range(2016, 2016 + args.masks):
            rows.append(run_mask(X, args.p, seed))
            print({k: round(v, 4) if isinstance(v, float) else v for k, v in rows[-1].items()}, flush=True)
    frame = pd.DataFrame(rows)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    frame.to_csv(out / "model_selection.csv", index=False)
    ratio = frame["select_over_solve"]
    print(f"selection / solve: {ratio.mean():.1f} +- {ratio.std(ddof=1):.1f} solves' worth")
    for column, label in (("sse_paper", "paper"), ("sse_cv", "CV-selected"), ("sse_oracle", "ORACLE grid")):
        print(f"SSE {label:12s} {frame[column].mean():7.3f} +- {frame[column].std(ddof=1):.3f}")


if __name__ == "__main__":
    main()
