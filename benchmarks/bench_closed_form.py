"""Benchmark: the closed-form robust KPCA against the eigendecomposition it needs.

Usage: python benchmarks/bench_closed_form.py [N ...]   (default N = 500 1000 2000 3000 5000)

On the same centred RBF kernel (N points of a 12-dimensional standard normal, gamma = 0.075;
tau = rho = 1, so the cubic's threshold is 1.5) it times, median over repeats:

- ``eigh_full_s``: ``numpy.linalg.eigh``, every eigenpair (what the original closed form called);
- ``eigh_partial_s``: ``scipy.linalg.eigh(subset_by_value=(threshold, inf))``, only the eigenpairs
  the closed form keeps (``k`` of them);
- ``closed_form_s``: :func:`closed_form_rank_penalty` (default ``eigensolver="auto"``), and
  ``closed_form_full_s`` with ``eigensolver="full"``.

``ratio_needed`` = closed form / the decomposition it uses (partial for N >= 300), ``ratio_full`` =
closed form / the full ``eigh``. BLAS is pinned to 1 thread so the figures do not depend on what else
runs. Writes results/benchmarks/closed_form.csv.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import scipy.linalg
from threadpoolctl import threadpool_limits

from nldr.kernels import center_kernel, rbf_kernel
from nldr.robust_kpca import closed_form_rank_penalty, rank_penalty_threshold


def median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def main(sizes: list[int]) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    threshold = rank_penalty_threshold(1.0, 1.0)
    rows = []
    with threadpool_limits(1):
        for n in sizes:
            K = center_kernel(rbf_kernel(rng.normal(size=(n, 12)), 0.075))
            repeats = 5 if n <= 1000 else 3
            k = scipy.linalg.eigh(K, subset_by_value=(threshold, np.inf), eigvals_only=True).size
            t_full = median_time(lambda K=K: np.linalg.eigh(K), repeats)
            t_part = median_time(
                lambda K=K: scipy.linalg.eigh(K, subset_by_value=(threshold, np.inf), driver="evr"), repeats
            )
            t_cf = median_time(lambda K=K: closed_form_rank_penalty(K, 1.0, 1.0), repeats)
            t_cf_full = median_time(
                lambda K=K: closed_form_rank_penalty(K, 1.0, 1.0, eigensolver="full"), repeats
            )
            needed = t_part if n >= 300 else t_full
            rows.append(
                {
                    "n": n,
                    "k": k,
                    "eigh_full_s": t_full,
                    "eigh_partial_s": t_part,
                    "closed_form_s": t_cf,
                    "closed_form_full_s": t_cf_full,
                    "ratio_needed": t_cf / needed,
                    "ratio_full": t_cf / t_full,
                }
            )
            print(
                f"N={n:5d} k={k:4d}  eigh full {t_full:7.3f} s  partial {t_part:7.3f} s  "
                f"closed form {t_cf:7.3f} s (full: {t_cf_full:7.3f} s)  "
                f"ratio to needed {t_cf / needed:.3f}, to full eigh {t_cf / t_full:.3f}"
            )
    out = pd.DataFrame(rows)
    path = Path("results/benchmarks/closed_form.csv")
    path.parent.mkdir(parents=True, exist_ok=True)
    out.to_csv(path, index=False)
    return out


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [500, 1000, 2000, 3000, 5000])
