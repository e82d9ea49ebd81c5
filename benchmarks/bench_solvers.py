"""Before/after timings of the regularizer: one C-step + S-gradient, one LM S-step, one solve per table.

"Before" is the original implementation, still reachable as the option ``eigensolver="full"`` (every eigenpair
of the kernel, dE/dK = U diag(rho gap) U^T in O(n^3)); "after" is the default ``eigensolver="auto"``
(only the eigenpairs above the cubic's threshold when that pays, dE/dK = rho (K - C^T C) in
O(n^2 r)). Each row also records a result of each (energy or error), to show they agree.

Rows (BLAS pinned to one thread, median of ``--repeats`` runs for the short items):

- ``evaluation``: one reduced energy + gradient (a C-step and the S-gradient) on oil flow (n = 100 and
  n = 1000, the state after the first stage) and on drink, every frame (n = 1102, the ground truth);
- ``lm_s_step``: one Levenberg-Marquardt pre-image step (the literal Algorithm 1's S-step), oil n = 100;
- ``solve_table2``: "Ours" on one Table 2 mask (p = 0.25, seed 2016), n = 100 and n = 1000;
- ``solve_table3``: the kernel regularizer (d_med) on pickup, every 10th frame, full data, from TNH.

Writes ``results/benchmarks/solvers.csv``. Usage: ``.venv/bin/python benchmarks/bench_solvers.py``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from nldr._baselines import mean_impute
from nldr.data_terms import MaskedLeastSquares
from nldr.datasets import load_mocap, load_oil
from nldr.experiments._mocap import WIDTHS
from nldr.experiments._table2 import random_mask
from nldr.nrsfm import OrthographicReprojection, trace_norm_heuristic
from nldr.nrsfm._layout import stack_to_rows
from nldr.reference.regularizer import pre_image_step
from nldr.regularizer import minimize_regularized, optimal_kernel_factor, reduced_energy


def timed(fn, repeats: int):
    times, out = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times)), out


def compare(rows, item, n, fn, repeats, summary):
    """fn(eigensolver) -> result; summary(result) -> float recorded beside the time."""
    t_before, r_before = timed(lambda: fn("full"), repeats)
    t_after, r_after = timed(lambda: fn("auto"), repeats)
    row = {
        "item": item,
        "n": n,
        "before_s": t_before,
        "after_s": t_after,
        "speedup": t_before / t_after,
        "before_result": summary(r_before),
        "after_result": summary(r_after),
    }
    rows.append(row)
    print(
        f"{item:14s} n={n:5d}  before {t_before:8.4f} s  after {t_after:8.4f} s  x{row['speedup']:.2f}  "
        f"result {row['before_result']:.8g} / {row['after_result']:.8g}"
    )


def oil_problem(data_dir, n_rows: int):
    """The first n_rows oil rows, Table 2's mask (p = 0.25, seed 2016), mean imputation, data term."""
    X = load_oil("train", data_dir)[0][:n_rows]
    mask = random_mask(X.shape, 0.25, 2016)
    S0 = mean_impute(X, mask)
    return X, mask, S0, MaskedLeastSquares(X, mask)


def pickup_problem(data_dir):
    """Table 3's kernel problem on pickup (every 10th frame, full data): data term, TNH start, d_med gamma."""
    seq = load_mocap("pickup", data_dir).subsample(10)
    W2d = stack_to_rows(seq.W, dim=2)
    X0 = trace_norm_heuristic(W2d, seq.R, method="cvxpy").x
    return OrthographicReprojection(W2d, seq.R), X0, WIDTHS["d_med"](X0)


def main(data_dir, out: Path, repeats: int) -> pd.DataFrame:
    rows: list[dict] = []
    with threadpool_limits(1):
        for n in (100, 1000):
            X, mask, S0, term = oil_problem(data_dir, n)
            # the state after the first stage, where the later stages spend their evaluations
            S1 = minimize_regularized(term, S0, gamma=0.075, tau=0.1, rho_max=1.0).x
            compare(
                rows,
                "evaluation",
                n,
                lambda e, S1=S1, term=term: reduced_energy(
                    S1, term, gamma=0.075, tau=0.1, rho=1e2, eigensolver=e
                ),
                repeats if n == 100 else max(3, repeats // 10),
                lambda r: r[0],
            )
        seq = load_mocap("drink", data_dir)
        W2d, X_gt = stack_to_rows(seq.W, dim=2), stack_to_rows(seq.S, dim=3)
        drink = OrthographicReprojection(W2d, seq.R)
        gamma = WIDTHS["d_med"](X_gt)
        compare(
            rows,
            "evaluation",
            X_gt.shape[0],
            lambda e: reduced_energy(X_gt, drink, gamma=gamma, tau=1e-4, rho=1e-2, eigensolver=e),
            3,
            lambda r: r[0],
        )

        X, mask, S0, term = oil_problem(data_dir, 100)
        C = optimal_kernel_factor(S0, gamma=0.075, tau=0.1, rho=1.0)
        t_lm, S_lm = timed(lambda: pre_image_step(S0, C, term, gamma=0.075, rho=1.0), repeats)
        rows.append(
            {
                "item": "lm_s_step",
                "n": 100,
                "before_s": t_lm,
                "after_s": t_lm,
                "speedup": 1.0,
                "before_result": float(np.sum((S_lm - X) ** 2)),
                "after_result": float(np.sum((S_lm - X) ** 2)),
            }
        )
        print(f"lm_s_step      n=  100  {t_lm:.4f} s (unchanged: no eigendecomposition)")

        for n in (100, 1000):
            X, mask, S0, term = oil_problem(data_dir, n)
            compare(
                rows,
                "solve_table2",
                n,
                lambda e, S0=S0, term=term: minimize_regularized(
                    term, S0, gamma=0.075, tau=0.1, options={"eigensolver": e}
                ),
                3 if n == 100 else 1,
                lambda r, X=X: float(np.sum((r.x - X) ** 2)),
            )

        data, X0, gamma = pickup_problem(data_dir)
        compare(
            rows,
            "solve_table3",
            X0.shape[0],
            lambda e: minimize_regularized(
                data, X0, gamma=gamma, tau=1e-4, rho0=1e-3, rho_max=10.0,
                options={"eigensolver": e, "scale": 1.0},  # Table 3's units
            ),
            3,
            lambda r: r.stage_energy[-1],
        )
    table = pd.DataFrame(rows)
    out.mkdir(parents=True, exist_ok=True)
    table.to_csv(out / "solvers.csv", index=False)
    return table


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-dir", default="resources")
    parser.add_argument("--out", type=Path, default=Path("results/benchmarks"))
    parser.add_argument("--repeats", type=int, default=30)
    args = parser.parse_args()
    main(args.data_dir, args.out, args.repeats)
