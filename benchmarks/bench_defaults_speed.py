"""Speed of the imputer's defaults, and its completion of unseen rows against KNNImputer.

Run with ``OPENBLAS_NUM_THREADS=1`` in the environment. CPU seconds by ``time.process_time``; the
machine may be shared with other jobs (the figures are then upper bounds of an idle machine's).

- ``fit``: ``KernelRegularizerImputer().fit_transform`` on the first ``--rows`` oil-flow training rows
  at missing share p (Table 2's mask, seed 2016), its hold-out tuning included, and the same fit
  untuned (``gamma`` and ``tau`` set to the values the tuning chose), so the tuning's cost is the
  difference.
- ``large``: the untuned fit (``gamma=None, tau=0.1``: the median rule) on the first ``--large`` real
  oil-flow rows of the three splits (:func:`nldr.datasets.load_oil_rows`; 3000 is every row).
- ``path``: the solver paths of ``method="auto"`` on the first n oil rows (``--sizes``), Table 2's
  masks 2016 + k (``--masks``) at each p: ``method="exact"`` against ``"nystroem-warm"`` (100
  landmarks, seed 0), untuned (the median rule, tau 0.1, standardised): SSE and CPU seconds.
- ``transform``: fit on the 1000 training rows (complete), then complete the first 200 validation rows
  with a share p of their entries hidden (mask seed 2016 + k): SSE on the hidden entries of ours and of
  scikit-learn's ``KNNImputer`` (its defaults, and its ``n_neighbors``/``weights`` chosen by the
  hold-out search of :func:`nldr.impute.baseline_grid` on the training rows with the same
  share hidden), and ours' milliseconds per new row.

Usage::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults_speed.py fit --rows 1000
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults_speed.py large --large 3000
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults_speed.py path --sizes 150 300 --masks 3
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults_speed.py transform --masks 3
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from sklearn.impute import KNNImputer

from nldr.datasets import load_oil, load_oil_rows
from nldr.experiments._table2 import random_mask
from nldr.impute import KernelRegularizerImputer, baseline_grid
from nldr.model_selection import HoldoutSearch


def timed(fn):
    start = time.process_time()
    out = fn()
    return out, time.process_time() - start


def run_fit(args):
    X = load_oil("train", args.data)[0][: args.rows]
    for p in args.p:
        W = np.where(random_mask(X.shape, p, 2016), X, np.nan)
        tuned = KernelRegularizerImputer(**args.params)
        X_hat, cpu = timed(lambda tuned=tuned, W=W: tuned.fit_transform(W))
        fixed = KernelRegularizerImputer(gamma=tuned.gamma_, tau=tuned.tau_, **args.params)
        X_fix, cpu_fixed = timed(lambda fixed=fixed, W=W: fixed.fit_transform(W))
        print(
            f"fit n={args.rows} p={p:g}: default {cpu:.1f} CPU s (SSE {np.sum((X_hat - X) ** 2):.2f}; "
            f"gamma {tuned.gamma_:.4g}, tau {tuned.tau_:g}, {tuned.method_}), untuned at the chosen values "
            f"{cpu_fixed:.1f} CPU s (SSE {np.sum((X_fix - X) ** 2):.2f}), tuning {cpu - cpu_fixed:.1f} CPU s",
            flush=True,
        )


def run_large(args):
    X = load_oil_rows(args.large, args.data)
    W = np.where(random_mask(X.shape, 0.25, 2016), X, np.nan)
    est = KernelRegularizerImputer(gamma=None, tau=0.1, random_state=0, **args.params)
    X_hat, cpu = timed(lambda: est.fit_transform(W))
    print(
        f"large n={args.large} p=0.25: untuned {cpu:.1f} CPU s, SSE {np.sum((X_hat - X) ** 2):.2f}, "
        f"{est.method_}, nit {est.result_.nit}",
        flush=True,
    )


def run_path(args):
    for n in args.sizes:
        X = load_oil("train", args.data)[0][:n]
        for p in args.p:
            for k in range(args.masks):
                W = np.where(random_mask(X.shape, p, 2016 + k), X, np.nan)
                line = []
                for method in ("exact", "nystroem-warm"):
                    est = KernelRegularizerImputer(gamma=None, tau=0.1, method=method, random_state=0)
                    X_hat, cpu = timed(lambda est=est, W=W: est.fit_transform(W))
                    line.append(f"{method} SSE {np.sum((X_hat - X) ** 2):.3f} ({cpu:.1f} CPU s)")
                print(f"path n={n} p={p:g} seed={2016 + k}: " + ", ".join(line), flush=True)


def run_transform(args):
    X_train = load_oil("train", args.data)[0]
    X_new = load_oil("validation", args.data)[0][:200]
    ours, cpu_fit = timed(lambda: KernelRegularizerImputer(**args.params).fit(X_train))
    print(
        f"transform: fit on {X_train.shape[0]} complete rows {cpu_fit:.1f} CPU s "
        f"(gamma {ours.gamma_:.4g}, tau {ours.tau_:g}, {ours.n_components_} components)",
        flush=True,
    )
    for p in args.p:
        for k in range(args.masks):
            seed = 2016 + k
            mask = random_mask(X_new.shape, p, seed)
            W = np.where(mask, X_new, np.nan)
            X_hat, cpu = timed(lambda W=W: ours.transform(W))
            sse = float(np.sum((X_hat - X_new)[~mask] ** 2))
            knn = float(np.sum((KNNImputer().fit(X_train).transform(W) - X_new)[~mask] ** 2))
            train = np.where(random_mask(X_train.shape, p, seed), X_train, np.nan)
            search = HoldoutSearch(*baseline_grid("KNNImputer", train), n_folds=3, random_state=seed).fit(
                train
            )
            cv = KNNImputer(**search.best_params_).fit(X_train).transform(W)
            knn_cv = float(np.sum((cv - X_new)[~mask] ** 2))
            print(
                f"transform p={p:g} seed={seed}: ours SSE {sse:.3f} "
                f"({1e3 * cpu / X_new.shape[0]:.2f} ms/row), "
                f"KNNImputer() {knn:.3f}, KNNImputer CV {knn_cv:.3f} {search.best_params_}",
                flush=True,
            )


def main():
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("what", choices=["fit", "large", "path", "transform"])
    parser.add_argument("--sizes", type=int, nargs="+", default=[150, 300])
    parser.add_argument("--rows", type=int, default=1000)
    parser.add_argument("--large", type=int, default=3000)
    parser.add_argument("--p", type=float, nargs="+", default=[0.1, 0.25, 0.5])
    parser.add_argument("--masks", type=int, default=3)
    parser.add_argument("--data", default=None)
    args = parser.parse_args()
    args.params = {}
    {"fit": run_fit, "large": run_large, "path": run_path, "transform": run_transform}[args.what](args)


if __name__ == "__main__":
    main()
