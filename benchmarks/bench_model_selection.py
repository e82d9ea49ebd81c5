"""Benchmark of hold-out selection of (tau, gamma) on the paper's Table 2 protocol, before and after.

Protocol: the first 100 oil-flow training rows (100 x 12), masks from
:func:`nldr.experiments.table2.random_mask` (seeds ``--seed0``, +1, ...), mean-imputation start, uncentred
kernel, the paper's schedule (rho0 1, growth 10, rho_max 1e4), one BLAS thread, CPU seconds
(``time.process_time``). Per mask it times one solve at the paper's values (gamma 0.075, tau 0.1) and
one :func:`nldr.model_selection.select_regularizer` per variant on the default grid (9 taus, 3 gammas):

- ``before``: 5 folds partitioning the observed entries, smallest mean error, tau path warm-started
  (the options before ``holdout``, ``rule`` and ``warm_gamma`` existed);
- ``after``: the defaults (5 Monte-Carlo folds hiding 10 % each, the one-standard-error rule).

It reports the SSE over the whole matrix of the paper's values, of each variant's refit, and of the
grid point with the smallest SSE against ground truth (an ORACLE: it sees the truth, so it is only a
reference, never a method), and the cost of a selection in solves' worth (selection CPU / solve CPU).

Writes ``results/benchmarks/model_selection_seed<seed0>.csv`` (one row per mask and variant) and
prints a summary.

Usage::

    .venv/bin/python benchmarks/bench_model_selection.py --p 0.05 0.5 --masks 3
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
SCHEDULE = {"rho0": 1.0, "rho_growth": 10.0, "rho_max": 1e4}
VARIANTS = {
    "before": {"n_folds": 5, "holdout": None, "rule": "min", "warm_gamma": False},
    "after": {},
}


def run_mask(X, p, seed, variants):
    mask = random_mask(X.shape, p, seed)
    W = np.where(mask, X, np.nan)
    term, S0 = MaskedLeastSquares(W, mask), mean_impute(W, mask)

    def sse(S):
        return float(np.sum((S - X) ** 2))

    start = time.process_time()
    paper = minimize_regularized(term, S0, **PAPER, **SCHEDULE)
    solve_cpu = time.process_time() - start
    rows, grid = [], None
    for name in variants:
        start = time.process_time()
        sel = select_regularizer(W, mask, random_state=seed, **VARIANTS[name], **SCHEDULE)
        select_cpu = time.process_time() - start
        grid = sel.cv_results_[["tau", "gamma"]]
        rows.append(
            {
                "p": p,
                "seed": seed,
                "variant": name,
                "solve_cpu": solve_cpu,
                "select_cpu": select_cpu,
                "solves": select_cpu / solve_cpu,
                "sse_paper": sse(paper.x),
                "sse_cv": sse(sel.result_.x),
                "tau_cv": sel.tau_,
                "gamma_cv": sel.gamma_,
            }
        )
    # ORACLE: every grid point solved on all observed entries (as the refit) and scored against the truth.
    oracle = min(
        (sse(minimize_regularized(term, S0, gamma=g, tau=t, **SCHEDULE).x), t, g)
        for t, g in zip(grid["tau"], grid["gamma"], strict=True)
    )
    for row in rows:
        row.update(sse_oracle=oracle[0], tau_oracle=oracle[1], gamma_oracle=oracle[2])
        row["cv_over_oracle"] = row["sse_cv"] / oracle[0]
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--masks", type=int, default=3)
    parser.add_argument("--seed0", type=int, default=2016, help="first mask seed (Table 2 uses 2016 on)")
    parser.add_argument("--p", type=float, nargs="+", default=[0.05, 0.5])
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--data", default="/work/shared/data")
    parser.add_argument("--out", default="results/benchmarks")
    args = parser.parse_args()
    X = load_oil("train", args.data)[0][:100]
    rows = []
    with threadpool_limits(1):
        for p in args.p:
            for seed in range(args.seed0, args.seed0 + args.masks):
                rows.extend(run_mask(X, p, seed, args.variants))
                for row in rows[-len(args.variants):]:
                    print({k: round(v, 4) if isinstance(v, float) else v for k, v in row.items()}, flush=True)
    frame = pd.DataFrame(rows)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    frame.to_csv(out / f"model_selection_seed{args.seed0}.csv", index=False)
    for (p, name), group in frame.groupby(["p", "variant"], sort=True):
        columns = ("solves", "sse_cv", "sse_oracle", "sse_paper")
        stats = {c: (group[c].mean(), group[c].std(ddof=1)) for c in columns}
        ratio = group["sse_cv"].mean() / group["sse_oracle"].mean()
        print(
            f"p={p:g} {name:6s} ({len(group)} masks): {stats['solves'][0]:.1f} +- {stats['solves'][1]:.1f} "
            f"solves' worth; SSE CV {stats['sse_cv'][0]:.2f} +- {stats['sse_cv'][1]:.2f}, ORACLE "
            f"{stats['sse_oracle'][0]:.2f} +- {stats['sse_oracle'][1]:.2f} (CV/oracle of the means "
            f"{ratio:.3f}), paper values {stats['sse_paper'][0]:.2f} +- {stats['sse_paper'][1]:.2f}"
        )


if __name__ == "__main__":
    main()
