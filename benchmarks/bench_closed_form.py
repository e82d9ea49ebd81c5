"""Benchmark: the closed-form robust KPCA against the eigendecomposition it needs.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_closed_form.py [N ...] [--fraction-n N]
[--fractions F ...] (default N = 100 200 300 500 1000 2000 3000 5000; --fraction-n 1000; ``--quick``:
N = 100 300, --fraction-n 300)

Part 1, by size. On the same centred RBF kernel (N points of a 12-dimensional standard normal,
gamma = 0.075; tau = rho = 1, so the cubic's threshold is 1.5) it times, median over repeats:

- ``eigh_full_s``: ``numpy.linalg.eigh``, every eigenpair (what the original closed form called);
- ``eigh_partial_s``: ``scipy.linalg.eigh(subset_by_value=(threshold, inf))``, only the eigenpairs
  the closed form keeps (``k`` of them);
- ``closed_form_s``: :func:`closed_form_rank_penalty` (default ``eigensolver="auto"``), and
  ``closed_form_full_s`` with ``eigensolver="full"``.

``ratio_needed`` = closed form / the decomposition it uses (partial for N >= 300), ``ratio_full`` =
closed form / the full ``eigh``. The small sizes show where the partial decomposition starts to pay
(``nldr._spectral.PARTIAL_MIN_N``). Writes ``--out``/closed_form.csv.

Part 2, by kept fraction. At N = ``--fraction-n``, tau is set so that a given fraction of the
eigenvalues passes the threshold, and the full and partial decompositions are timed: where the partial
one stops paying as the fraction grows (``nldr._spectral.PARTIAL_MAX_FRACTION``). Writes
``--out``/closed_form_fraction.csv.

Wall seconds (``time.perf_counter``), median over repeats, BLAS on one thread.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import scipy.linalg
from _common import check_blas, parser, timed, write_csv

from nldr.kernels import center_kernel, rbf_kernel
from nldr.robust_kpca import closed_form_rank_penalty, rank_penalty_threshold


def kernel(rng, n: int) -> np.ndarray:
    return center_kernel(rbf_kernel(rng.normal(size=(n, 12)), 0.075))


def partial_eigh(K: np.ndarray, threshold: float):
    return scipy.linalg.eigh(K, subset_by_value=(threshold, np.inf), driver="evr")


def by_size(sizes: list[int]) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    threshold = rank_penalty_threshold(1.0, 1.0)
    rows = []
    for n in sizes:
        K = kernel(rng, n)
        repeats = 20 if n <= 300 else 5 if n <= 1000 else 3
        k = scipy.linalg.eigh(K, subset_by_value=(threshold, np.inf), eigvals_only=True).size
        t_full, _ = timed(lambda K=K: np.linalg.eigh(K), repeats)
        t_part, _ = timed(lambda K=K: partial_eigh(K, threshold), repeats)
        t_cf, _ = timed(lambda K=K: closed_form_rank_penalty(K, 1.0, 1.0), repeats)
        t_cf_full, _ = timed(lambda K=K: closed_form_rank_penalty(K, 1.0, 1.0, eigensolver="full"), repeats)
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
            f"N={n:5d} k={k:4d}  eigh full {t_full:8.4f} s  partial {t_part:8.4f} s  "
            f"closed form {t_cf:8.4f} s (full: {t_cf_full:8.4f} s)  "
            f"ratio to needed {t_cf / needed:.3f}, to full eigh {t_cf / t_full:.3f}"
        )
    return pd.DataFrame(rows)


def by_fraction(n: int, fractions: list[float]) -> pd.DataFrame:
    K = kernel(np.random.default_rng(1), n)
    lam = np.linalg.eigvalsh(K)[::-1]
    repeats = 5 if n <= 1000 else 3
    t_full, _ = timed(lambda: np.linalg.eigh(K), repeats)
    rows = []
    for fraction in fractions:
        k = max(1, int(round(fraction * n)))
        threshold = 0.5 * (lam[k - 1] + lam[k])  # k eigenvalues above it
        # threshold = 3 (b^2 / 2)^(1/3) with b = tau / (2 rho), rho = 1
        tau = 2.0 * np.sqrt(2.0 * (threshold / 3.0) ** 3)
        assert np.isclose(rank_penalty_threshold(tau, 1.0), threshold)
        t_part, _ = timed(lambda threshold=threshold: partial_eigh(K, threshold), repeats)
        rows.append(
            {"n": n, "k": k, "fraction": k / n, "tau": tau, "eigh_full_s": t_full, "eigh_partial_s": t_part}
        )
        print(f"N={n:5d} k={k:5d} ({k / n:4.0%})  eigh full {t_full:8.4f} s  partial {t_part:8.4f} s")
    return pd.DataFrame(rows)


def main(argv=None) -> None:
    ap = parser(__doc__)
    ap.add_argument("sizes", nargs="*", type=int, default=[100, 200, 300, 500, 1000, 2000, 3000, 5000])
    ap.add_argument("--fraction-n", type=int, default=1000, help="N of the kept-fraction sweep")
    ap.add_argument("--fractions", nargs="+", type=float, default=[0.05, 0.1, 0.2, 0.25, 0.3, 0.4, 0.6])
    args = ap.parse_args(argv)
    if args.quick:
        args.sizes, args.fraction_n = [100, 300], 300
    check_blas()
    write_csv(by_size(args.sizes), args.out, "closed_form.csv")
    write_csv(by_fraction(args.fraction_n, args.fractions), args.out, "closed_form_fraction.csv")


if __name__ == "__main__":
    main()
