"""The default's tau and width choice against the grid's per-mask oracle, first 100 oil-flow rows.

For each of Table 2's masks (seeds 2016 + k, k < ``--masks``) at missing share ``p``:
``KernelRegularizerImputer().fit`` (its hold-out search chooses among the width multiples
:data:`~nldr.impute._regularizer.TUNE_GAMMA_MULTIPLES` and the taus ``--taus``), then every candidate
refitted with fixed ``gamma`` and ``tau``. SSE over the whole matrix (Table 2's error). The per-mask
minimum over the candidates uses the ground truth: an **oracle**, the best any rule on this grid
could do, not a method. Prints one line per mask and the means; writes nothing.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults_oracle.py --p 0.5
"""

from __future__ import annotations

import argparse

import numpy as np

from nldr.datasets import load_oil
from nldr.experiments._table2 import random_mask
from nldr.impute import KernelRegularizerImputer
from nldr.impute._regularizer import MEDIAN_RULE_MULTIPLE, TUNE_GAMMA_MULTIPLES, TUNE_TAUS


def main():
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--p", type=float, default=0.5)
    parser.add_argument("--rows", type=int, default=100)
    parser.add_argument("--masks", type=int, default=10)
    parser.add_argument("--taus", type=float, nargs="+", default=list(TUNE_TAUS))
    parser.add_argument("--data", default=None)
    args = parser.parse_args()
    X = load_oil("train", args.data)[0][: args.rows]
    defaults, oracles, grid = [], [], {}
    for k in range(args.masks):
        W = np.where(random_mask(X.shape, args.p, 2016 + k), X, np.nan)
        est = KernelRegularizerImputer().fit(W)
        defaults.append(float(np.sum((est.completed_ - X) ** 2)))
        median_rule = est.cv_results_["params"][0]["gamma"] * MEDIAN_RULE_MULTIPLE / TUNE_GAMMA_MULTIPLES[0]
        sse = {}
        for m in TUNE_GAMMA_MULTIPLES:
            for tau in args.taus:
                fixed = KernelRegularizerImputer(gamma=m * median_rule / MEDIAN_RULE_MULTIPLE, tau=tau).fit(W)
                sse[(m, tau)] = float(np.sum((fixed.completed_ - X) ** 2))
                grid.setdefault((m, tau), []).append(sse[(m, tau)])
        oracles.append(min(sse.values()))
        chosen = (est.gamma_ * MEDIAN_RULE_MULTIPLE / median_rule, est.tau_)
        print(
            f"seed {2016 + k}: default {defaults[-1]:.2f} (width x{chosen[0]:g}, tau {chosen[1]:g}), "
            f"oracle {oracles[-1]:.2f} {min(sse, key=sse.get)}",
            flush=True,
        )
    spread = np.std(defaults, ddof=1)
    print(f"default {np.mean(defaults):.2f} ± {spread:.2f}; per-mask oracle {np.mean(oracles):.2f}")
    for (m, tau), values in grid.items():
        print(f"  fixed width x{m:g}, tau {tau:g}: {np.mean(values):.2f}")


if __name__ == "__main__":
    main()
