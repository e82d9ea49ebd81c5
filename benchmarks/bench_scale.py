"""CPU seconds and SSE of oil-flow completion against the number of rows: the regularizer and the peers.

Protocol (Table 2's, on more rows): the first n rows of the oil-flow data (the training file, then for
n > 1000 the validation and test files appended, :func:`nldr.datasets.load_oil_rows`; 3000 rows = all
three files); each entry hidden with probability p, mask k at p with seed 2016 + k (Table 2's masks,
:func:`nldr.experiments._table2.random_mask`, private: imported so that these are the pipeline's
masks); SSE over the whole matrix; CPU seconds by ``time.process_time``, BLAS on one thread.
Methods (``--methods``, default ``Ours``):

- ``Ours``: :class:`nldr.impute.KernelRegularizerImputer` at Table 2's settings (raw columns, gamma
  0.075, tau 0.1, uncentred, ``method="exact"``; the solver's schedule rho 1 -> 1e4, x10, from mean
  imputation). ``--options`` overrides its keyword arguments as JSON, e.g.
  ``'{"options": {"eigensolver": "full"}}'``, or
  ``'{"method": "nystroem-warm", "options": {"landmarks": 100, "exact_stages": 2}}'`` (Nystroem stages,
  then the exact solver's last two stages), or
  ``'{"method": "nystroem-warm", "options": {"last_landmarks": 200, "exact_tol": 3e-6}}'``;
- ``Nystroem``: ``Ours`` with ``method="nystroem"``, ``options={"landmarks": --landmarks}`` (the
  opt-in approximation of the kernel; random_state 0);
- ``mean`` (column means of the observed entries) and ``PPCA`` (:class:`nldr.impute.PPCAImputer`,
  q = 9), for reference;
- the peers ``KNNImputer``, ``IterativeImputer``, ``SoftImpute``, ``missForest``, their knob chosen by
  :class:`nldr.model_selection.HoldoutSearch` on ``--folds`` hold-out folds of the observed entries
  (seed = the mask's seed) over the pipeline's grids (:func:`nldr.impute._grids.baseline_grid`,
  private: the tables' own search grids, imported so that these are the same), then refitted on every observed
  entry (``cpu`` counts the search and the refit, ``cpu_fit`` one fit at the chosen knob);
  IterativeImputer has no knob and is fitted once.

``--label`` names the rows: to time a previous implementation, run this script with ``PYTHONPATH``
pointing at that commit's ``src`` and another label. Appends one row per (label, n, p, mask, method)
to ``--out``/scale.csv (label, n, p, seed, key, method, cpu, cpu_fit, nit, converged, sse, energy,
rank, options), skipping rows already there, so a run can be stopped and resumed; then prints mean,
sd and count of SSE and CPU per (n, p, method) of the label.

Usage::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_scale.py --n 100 300 1000 --masks 3 --label after
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_scale.py --n 100 300 1000 3000 \\
        --methods mean PPCA Ours Nystroem KNNImputer IterativeImputer SoftImpute missForest
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_scale.py --n 100 --p 0.05 0.1 0.25 0.5 --masks 10 \\
        --folds 5 --methods Ours KNNImputer IterativeImputer SoftImpute missForest
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
from _common import append_row, check_blas, done, key, parser, timed
from sklearn.base import clone

from nldr.datasets import load_oil_rows
from nldr.experiments._table2 import random_mask
from nldr.impute import KernelRegularizerImputer, PPCAImputer
from nldr.impute._grids import baseline_grid
from nldr.model_selection import HoldoutSearch

PEERS = ("KNNImputer", "IterativeImputer", "SoftImpute", "missForest")
METHODS = ("Ours", "Nystroem", "mean", "PPCA", *PEERS)
#: Table 2's "Ours", the paper's settings written out
TABLE2 = {"standardize": False, "gamma": 0.075, "tau": 0.1, "center": False, "method": "exact"}
SEED = 2016
CSV = "scale.csv"
COLUMNS = (
    "label", "n", "p", "seed", "key", "method", "cpu", "cpu_fit", "nit", "converged", "sse", "energy", "rank",
    "params", "options",
)  # fmt: skip


def complete(method: str, W, seed: int, options: dict, landmarks: int, folds: int) -> dict:
    """One method on the masked matrix W (NaN missing): the completion, its CPU seconds and details."""
    if method == "mean":
        cpu, X_hat = timed(lambda: np.where(np.isnan(W), np.nanmean(W, axis=0), W), clock="cpu")
        return {"X_hat": X_hat, "method": "mean", "cpu": cpu, "cpu_fit": cpu}
    if method in ("Ours", "Nystroem", "PPCA"):
        if method == "PPCA":
            est = PPCAImputer(n_components=9)
        elif method == "Ours":
            est = KernelRegularizerImputer(**{**TABLE2, **options})
        else:
            nystroem = {"method": "nystroem", "options": {"landmarks": landmarks}, "random_state": 0}
            est = KernelRegularizerImputer(**{**TABLE2, **nystroem})
        cpu, X_hat = timed(lambda: est.fit_transform(W), clock="cpu")
        res = est.result_
        label = f"Ours (Nystroem {landmarks})" if method == "Nystroem" else method
        row = {"X_hat": X_hat, "method": label, "cpu": cpu, "cpu_fit": cpu, "nit": int(res.nit)}
        row["converged"] = bool(res.success)
        if method != "PPCA":
            row |= {"energy": float(res.fun), "rank": int(res.rank_history[-1])}
        return row
    estimator, grid = baseline_grid(method, W)
    if not grid:
        cpu, X_hat = timed(lambda: clone(estimator).fit_transform(W), clock="cpu")
        return {"X_hat": X_hat, "method": method, "cpu": cpu, "cpu_fit": cpu}
    search = HoldoutSearch(estimator, grid, n_folds=folds, random_state=seed)
    cpu, X_hat = timed(lambda: search.fit_transform(W), clock="cpu")
    best = clone(estimator).set_params(**search.best_params_)
    cpu_fit, _ = timed(lambda: best.fit_transform(W), clock="cpu")
    params = repr(search.best_params_)
    return {"X_hat": X_hat, "method": f"{method} (CV)", "cpu": cpu, "cpu_fit": cpu_fit, "params": params}


def main(argv=None) -> None:
    ap = parser(__doc__)
    ap.add_argument("--n", type=int, nargs="+", default=[100, 300, 1000], help="rows")
    ap.add_argument("--p", type=float, nargs="+", default=[0.25], help="missing shares")
    ap.add_argument("--masks", type=int, default=3, help="masks per (n, p): seeds 2016, 2017, ...")
    ap.add_argument("--first-mask", type=int, default=0)
    ap.add_argument("--methods", nargs="+", default=["Ours"], choices=METHODS)
    ap.add_argument("--options", default="{}", help="JSON keyword arguments of Ours' estimator")
    ap.add_argument("--landmarks", type=int, default=300, help="landmarks of the Nystroem method")
    ap.add_argument("--folds", type=int, default=3, help="hold-out folds of the peers' search")
    ap.add_argument("--label", default="current")
    args = ap.parse_args(argv)
    if args.quick:
        args.n, args.p, args.masks = [100], [0.25], 1
    check_blas()
    options = json.loads(args.options)
    seen = done(args.out, CSV, ["label", "n", "p", "seed", "key"])
    for n in args.n:
        X = load_oil_rows(n, args.data_dir)
        for p in args.p:
            for k in range(args.first_mask, args.first_mask + args.masks):
                seed = SEED + k
                W = np.where(random_mask(X.shape, p, seed), X, np.nan)
                for method in args.methods:
                    name = f"Nystroem {args.landmarks}" if method == "Nystroem" else method
                    if key((args.label, n, p, seed, name)) in seen:
                        continue
                    out = complete(method, W, seed, options, args.landmarks, args.folds)
                    X_hat = out.pop("X_hat")
                    row = {"label": args.label, "n": n, "p": p, "seed": seed, "key": name, **out}
                    row |= {"sse": float(np.sum((X_hat - X) ** 2)), "options": json.dumps(options)}
                    append_row({c: row.get(c) for c in COLUMNS}, args.out, CSV)
                    print(
                        f"{args.label} n={n} p={p:g} seed={seed} {row['method']:24s} {row['cpu']:8.2f} CPU s "
                        f"SSE {row['sse']:.6f}  {row.get('params') or ''}",
                        flush=True,
                    )
    table = pd.read_csv(args.out / CSV)
    table = table[table["label"] == args.label]
    summary = table.groupby(["n", "p", "method"]).agg(
        sse=("sse", "mean"), sse_sd=("sse", "std"), masks=("sse", "size"), cpu=("cpu", "mean")
    )
    print(summary.round(3).to_string())


if __name__ == "__main__":
    main()
