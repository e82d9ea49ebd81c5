"""CPU seconds and SSE of one regularizer solve against the number of oil-flow rows (issue 16, item 3).

Protocol (Table 2's, on more rows): the first n rows of the oil-flow data, the training file, then for
n > 1000 the validation and test files appended (3000 rows = all three files); mask
:func:`nldr.experiments._table2.random_mask` (seed 2016 + k); mean-imputation start; masked least
squares; gamma 0.075, tau 0.1, uncentred; schedule rho0 = 1, growth 10, rho_max = 1e4. CPU seconds
with ``time.process_time`` and BLAS pinned to one thread (threadpoolctl).

``--options`` passes keyword arguments to :func:`nldr.regularizer.minimize_regularized` as JSON, e.g.
``'{"options": {"eigensolver": "full"}}'`` or
``'{"method": "nystroem-warm", "options": {"landmarks": 100, "exact_stages": 2}}'``
(Nystroem stages, then the exact solver's last two stages), or
``'{"method": "nystroem-warm", "options": {"last_landmarks": 200, "exact_tol": 3e-6}}'``
(200 landmarks in the last Nystroem stage, and the exact stage stopped on an energy plateau);
``--label`` names the row. To time a previous implementation, run this script with ``PYTHONPATH``
pointing at that commit's ``src``.

Writes (appends to) ``--out``/scale.csv: label, n, p, seed, cpu, nit, sse, sse_mean_imputation,
final energy (at rho_max), final rank, status.

Usage::

    .venv/bin/python benchmarks/bench_scale.py --n 100 300 1000 --masks 3 --label after
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from nldr._baselines import mean_impute
from nldr.data_terms import MaskedLeastSquares
from nldr.datasets import load_oil_rows
from nldr.experiments._table2 import random_mask
from nldr.regularizer import minimize_regularized

GAMMA, TAU = 0.075, 0.1
SCHEDULE = {"center": False, "rho0": 1.0, "rho_growth": 10.0, "rho_max": 1e4}
SEED = 2016


def solve(X: np.ndarray, p: float, seed: int, options: dict) -> dict:
    mask = random_mask(X.shape, p, seed)
    W = np.where(mask, X, np.nan)
    S0 = mean_impute(W, mask)
    with threadpool_limits(1):
        cpu = time.process_time()
        res = minimize_regularized(
            MaskedLeastSquares(W, mask), S0, gamma=GAMMA, tau=TAU, **SCHEDULE, **options
        )
        cpu = time.process_time() - cpu
    return {
        "n": X.shape[0],
        "p": p,
        "seed": seed,
        "cpu": cpu,
        "nit": int(res.nit),
        "sse": float(np.sum((res.x - X) ** 2)),
        "sse_mean_imputation": float(np.sum((S0 - X) ** 2)),
        "energy": float(res.fun),
        "rank": int(res.rank_history[-1]),
        "status": int(res.status),
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--out", default="results/benchmarks")
    parser.add_argument("--n", type=int, nargs="+", default=[100, 300, 1000])
    parser.add_argument("--p", type=float, nargs="+", default=[0.25])
    parser.add_argument("--masks", type=int, default=3, help="masks per (n, p): seeds 2016, 2017, ...")
    parser.add_argument("--first-mask", type=int, default=0)
    parser.add_argument("--options", default="{}", help="JSON keyword arguments of minimize_regularized")
    parser.add_argument("--label", default="current")
    args = parser.parse_args(argv)
    options = json.loads(args.options)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "scale.csv"
    for n in args.n:
        X = load_oil_rows(n, args.data_dir)
        for p in args.p:
            for k in range(args.first_mask, args.first_mask + args.masks):
                row = {"label": args.label, "options": json.dumps(options), **solve(X, p, SEED + k, options)}
                pd.DataFrame([row]).to_csv(path, mode="a", header=not path.exists(), index=False)
                print(
                    f"{args.label} n={n} p={p:g} seed={SEED + k}: {row['cpu']:.2f} CPU s, {row['nit']} it, "
                    f"SSE {row['sse']:.6f}, energy {row['energy']:.10g}, rank {row['rank']}, "
                    f"status {row['status']}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
