"""CPU seconds and SSE against the number of oil-flow rows, for Ours and the peers (issue 16, item 2).

Protocol (Table 2's on more rows, as benchmarks/bench_scale.py): the first n rows of the training,
then validation, then test files (n = 3000: all three); p = 0.25 by default; mask k uses seed 2016 + k
(:func:`nldr.experiments._table2.random_mask`); one BLAS thread; CPU seconds by ``time.process_time``.
Methods (``--methods``):

- ``Ours``: the exact regularizer at Table 2's settings (gamma 0.075, tau 0.1, uncentred,
  rho 1 -> 1e4, mean-imputation start);
- ``Ours (Nystroem m)``: the same with ``method="nystroem"``, ``options={"landmarks": m}``
  (``--landmarks``, seed 0), the opt-in approximation of the kernel;
- the peers with their knob chosen by 3-fold hold-out CV on the observed entries
  (:class:`nldr.model_selection.HoldoutSearch` over :func:`~nldr.impute.baseline_grid`, Table
  2's rows; ``cpu`` counts CV and refit);
- ``mean`` and ``PPCA`` (q = 9) for reference.

Appends one row per (n, mask, method) to ``--out``/scaling.csv; rows already there are skipped, so a
run can be stopped and resumed.

Usage::

    python benchmarks/bench_scaling.py --n 100 300 1000 3000 --masks 3
    python benchmarks/bench_scaling.py --n 100 300 --methods Ours --masks 3
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
from sklearn.base import clone
from threadpoolctl import threadpool_limits

from nldr._baselines import mean_impute, ppca_impute
from nldr.data_terms import MaskedLeastSquares
from nldr.datasets import load_oil_rows
from nldr.experiments._table2 import PEERS, random_mask
from nldr.impute import baseline_grid
from nldr.model_selection import HoldoutSearch
from nldr.regularizer import minimize_regularized

OURS = {"gamma": 0.075, "tau": 0.1, "center": False, "rho0": 1.0, "rho_growth": 10.0, "rho_max": 1e4}
SEED = 2016


def complete(method: str, W, mask, seed: int, landmarks: int):
    """``(X_hat, label, nit, converged)`` of one method on the masked matrix."""
    if method == "mean":
        return mean_impute(W, mask), "mean", 0, True
    if method == "PPCA":
        res = ppca_impute(W, mask, n_components=9)
        return res.x, "PPCA", res.nit, res.success
    if method in ("Ours", "Nystroem"):
        extra = {} if method == "Ours" else {"method": "nystroem", "options": {"landmarks": landmarks}}
        label = "Ours" if method == "Ours" else f"Ours (Nystroem {landmarks})"
        res = minimize_regularized(MaskedLeastSquares(W, mask), mean_impute(W, mask), **OURS, **extra)
        return res.x, label, res.nit, res.success
    estimator, grid = baseline_grid(method, W)
    if not grid:
        return clone(estimator).fit_transform(W), method, 0, True
    search = HoldoutSearch(estimator, grid, n_folds=3, random_state=seed)
    result = getattr(search.fit(W).best_estimator_, "result_", None)  # None: scikit-learn's imputers
    nit, converged = (0, True) if result is None else (result.nit, result.success)
    return search.transform(W), f"{method} (CV)", nit, converged


def main(argv=None) -> None:
    fmt = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=fmt)
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--out", default="results/benchmarks")
    parser.add_argument("--n", type=int, nargs="+", default=[100, 300, 1000, 3000])
    parser.add_argument("--p", type=float, default=0.25)
    parser.add_argument("--masks", type=int, default=3, help="masks per n: seeds 2016, 2017, ...")
    parser.add_argument("--landmarks", type=int, default=300)
    parser.add_argument(
        "--methods", nargs="+", default=["mean", "PPCA", "Nystroem", *PEERS],
        help="mean, PPCA, Ours, Nystroem and the peers " + ", ".join(PEERS),
    )  # fmt: skip
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "scaling.csv"
    done = set()
    if path.exists():
        old = pd.read_csv(path)
        done = set(zip(old["n"], old["p"], old["seed"], old["key"], strict=True))
    for n in args.n:
        X = load_oil_rows(n, args.data_dir)
        for k in range(args.masks):
            seed = SEED + k
            mask = random_mask(X.shape, args.p, seed)
            W = np.where(mask, X, np.nan)
            for method in args.methods:
                key = f"Nystroem {args.landmarks}" if method == "Nystroem" else method
                if (n, args.p, seed, key) in done:
                    continue
                with threadpool_limits(1):
                    cpu = time.process_time()
                    X_hat, label, nit, converged = complete(method, W, mask, seed, args.landmarks)
                    cpu = time.process_time() - cpu
                row = {
                    "n": n, "p": args.p, "seed": seed, "key": key, "method": label, "cpu": cpu,
                    "sse": float(np.sum((X_hat - X) ** 2)), "nit": int(nit), "converged": bool(converged),
                }  # fmt: skip
                pd.DataFrame([row]).to_csv(path, mode="a", header=not path.exists(), index=False)
                print(f"n={n} seed={seed} {label:24s} {cpu:8.2f} CPU s  SSE {row['sse']:.4f}", flush=True)


if __name__ == "__main__":
    main()
