"""Benchmark of hold-out selection of (tau, gamma) on the paper's Table 2 protocol, before and after.

Protocol: the first 100 oil-flow training rows (100 x 12), masks from
:func:`nldr.experiments._table2.random_mask` (private: imported so that these are Table 2's masks;
seeds ``--seed0``, +1, ...), mean-imputation start, uncentred
kernel, the paper's schedule (rho0 1, growth 10, rho_max 1e4), one BLAS thread, CPU seconds
(``time.process_time``). Per mask it times one solve at the paper's values (gamma 0.075, tau 0.1) and
one :class:`nldr.model_selection.HoldoutSearch` of the regularizer per variant on the default grid (9
taus, 3 gammas):

- ``before``: 5 folds partitioning the observed entries, smallest mean error;
- ``after``: the selection experiment's search (5 Monte-Carlo folds hiding 10 % each, the
  one-standard-error rule preferring the smallest tau then the widest kernel, tau paths stopped at 1.5
  times their best, looser fold tolerances).

It reports the SSE over the whole matrix of the paper's values, of each variant's refit, and of the
grid point with the smallest SSE against ground truth (an ORACLE: it sees the truth, so it is only a
reference, never a method), and the cost of a selection in solves' worth (selection CPU / solve CPU).

Writes ``--out``/model_selection_seed<seed0>.csv (one row per mask and variant) and prints a summary.
``--quick``: one mask at p = 0.05.

Usage::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_model_selection.py --p 0.05 0.5 --masks 3
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from _common import check_blas, parser, timed, write_csv
from sklearn.base import clone

from nldr.datasets import load_oil
from nldr.experiments._table2 import random_mask
from nldr.impute import KernelRegularizerImputer
from nldr.model_selection import HoldoutSearch, median_gamma
from nldr.model_selection._folds import DEFAULT_TAUS, GAMMA_MULTIPLES

PAPER = {"gamma": 0.075, "tau": 0.1}
#: the regularizer in the data's units, the paper's schedule (the solver's defaults), exact kernel
OURS = KernelRegularizerImputer(standardize=False, method="exact")
VARIANTS = {
    "before": {"n_folds": 5, "holdout": None, "rule": "min", "path": "tau"},
    "after": {
        "n_folds": 5,
        "holdout": 0.1,
        "rule": "one_se",
        "prefer": ("tau", "gamma"),
        "path": "tau",
        "stop_factor": 1.5,
        "fold_params": {"tol": 1e-7, "gtol": 1e-4},
    },
}


def run_mask(X, p, seed, variants):
    mask = random_mask(X.shape, p, seed)
    W = np.where(mask, X, np.nan)

    def sse(S):
        return float(np.sum((S - X) ** 2))

    solve_cpu, paper = timed(lambda: clone(OURS).set_params(**PAPER).fit_transform(W), clock="cpu")
    gammas = np.asarray(GAMMA_MULTIPLES) * median_gamma(W)
    grid = {"gamma": [float(g) for g in gammas], "tau": list(DEFAULT_TAUS)}
    rows = []
    for name in variants:
        search = HoldoutSearch(OURS, grid, random_state=seed, **VARIANTS[name])
        select_cpu, X_hat = timed(lambda search=search: search.fit_transform(W), clock="cpu")
        rows.append(
            {
                "p": p,
                "seed": seed,
                "variant": name,
                "solve_cpu": solve_cpu,
                "select_cpu": select_cpu,
                "solves": select_cpu / solve_cpu,
                "sse_paper": sse(paper),
                "sse_cv": sse(X_hat),
                "tau_cv": search.best_params_["tau"],
                "gamma_cv": search.best_params_["gamma"],
            }
        )
    # ORACLE: every grid point fitted on all observed entries (as the refit) and scored against the
    # truth: the search with ground truth as its one fold, hiding exactly the missing entries.
    truth = HoldoutSearch(OURS, grid, folds=[~mask], scoring=lambda X, X_hat, h: sse(X_hat), refit=False)
    truth.fit(X)
    best = truth.best_params_
    for row in rows:
        row.update(sse_oracle=truth.best_score_, tau_oracle=best["tau"], gamma_oracle=best["gamma"])
        row["cv_over_oracle"] = row["sse_cv"] / truth.best_score_
    return rows


def main():
    ap = parser(__doc__)
    ap.add_argument("--masks", type=int, default=3)
    ap.add_argument("--seed0", type=int, default=2016, help="first mask seed (Table 2 uses 2016 on)")
    ap.add_argument("--p", type=float, nargs="+", default=[0.05, 0.5])
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    args = ap.parse_args()
    if args.quick:
        args.p, args.masks = [0.05], 1
    check_blas()
    X = load_oil("train", args.data_dir)[0][:100]
    rows = []
    for p in args.p:
        for seed in range(args.seed0, args.seed0 + args.masks):
            rows.extend(run_mask(X, p, seed, args.variants))
            for row in rows[-len(args.variants) :]:
                print({k: round(v, 4) if isinstance(v, float) else v for k, v in row.items()}, flush=True)
    frame = pd.DataFrame(rows)
    write_csv(frame, args.out, f"model_selection_seed{args.seed0}.csv")
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
