"""Benchmark: the closed-form robust KPCA against the eigendecomposition it needs.

Usage: python benchmarks/bench_closed_form.py [N ...]   (default N = 500 1000 2000)
Writes results/benchmarks/closed_form.csv: per N the median wall time of numpy.linalg.eigh and of
closed_form_rank_penalty on the same centred RBF kernel, and their ratio. BLAS pinned to 1 thread so
the figure does not depend on what else runs.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from nldr.kernels import center_kernel, rbf_kernel
from nldr.robust_kpca import closed_form_rank_penalty


def median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def main(sizes: list[int]) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    rows = []
    with threadpool_limits(1):
        for n in sizes:
            K = center_kernel(rbf_kernel(rng.normal(size=(n, 12)), 0.075))
            repeats = 5 if n <= 1000 else 3
            t_eigh = median_time(lambda K=K: np.linalg.eigh(K), repeats)
            t_cf = median_time(lambda K=K: closed_form_rank_penalty(K, 1.0, 1.0), repeats)
            rows.append({"n": n, "eigh_s": t_eigh, "closed_form_s": t_cf, "ratio": t_cf / t_eigh})
            print(f"N={n:5d}  eigh {t_eigh:7.3f} s  closed form {t_cf:7.3f} s  ratio {t_cf / t_eigh:.3f}")
    out = pd.DataFrame(rows)
    path = Path("results/benchmarks/closed_form.csv")
    path.parent.mkdir(parents=True, exist_ok=True)
    out.to_csv(path, index=False)
    return out


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [500, 1000, 2000])
