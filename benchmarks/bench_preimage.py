"""Benchmark: RobustKernelPCA.complete, CPU milliseconds per new row at 1000 training rows.

Usage: python benchmarks/bench_preimage.py [--rows M] [--repeats R]

Fits on the 1000 oil-flow training rows (nldr.datasets) and completes the first M test rows (default
1000) at p = 0.1, 0.25, 0.5 (one seeded mask each, table2.random_mask), for a few settings of gamma,
tau and the starts (one at the neighbours' mean, or one per neighbour averaged). Reports the median
over repeats of ``time.process_time`` per row with BLAS on one thread (the machine is shared, so CPU
time, not wall time), the rank and the SSE over the missing entries. Writes
results/benchmarks/preimage.csv. Issue 18's target: under 20 ms per row.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from nldr.datasets import load_oil
from nldr.experiments._table2 import random_mask
from nldr.robust_kpca import RobustKernelPCA

SETTINGS = [
    {"gamma": 0.3, "tau": 0.01, "n_neighbors": 5, "starts": "mean"},
    {"gamma": 1.0, "tau": 0.01, "n_neighbors": 10, "starts": "mean"},
    {"gamma": 1.0, "tau": 0.01, "n_neighbors": 5, "starts": "each"},
    {"gamma": 0.3, "tau": 0.01, "n_neighbors": 10, "starts": "each"},
]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    X_train, _ = load_oil("train")
    X_test, _ = load_oil("test")
    X_test = X_test[: args.rows]
    rows = []
    with threadpool_limits(1):
        for s in SETTINGS:
            model = RobustKernelPCA(gamma=s["gamma"], tau=s["tau"]).fit(X_train)
            for p in (0.1, 0.25, 0.5):
                mask = random_mask(X_test.shape, p, 2016)
                W = np.where(mask, X_test, np.nan)
                times = []
                for _ in range(args.repeats):
                    start = time.process_time()
                    X_hat = model.complete(W, mask, n_neighbors=s["n_neighbors"], starts=s["starts"])
                    times.append(time.process_time() - start)
                ms = 1000.0 * float(np.median(times)) / X_test.shape[0]
                sse = float(np.sum((X_hat - X_test)[~mask] ** 2))
                rows.append({**s, "p": p, "rank": model.n_components_, "ms_per_row": ms, "sse": sse})
                print(rows[-1], flush=True)
    out = Path("results/benchmarks/preimage.csv")
    out.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).to_csv(out, index=False)


if __name__ == "__main__":
    main()
