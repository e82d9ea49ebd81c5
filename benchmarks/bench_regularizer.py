"""Benchmark of the regularizer solvers on the paper's oil-flow completion protocol (Table 2).

Protocol: the first 100 rows of the oil-flow training set (100 x 12); each entry deleted
independently with probability p (seeded masks); start from mean imputation (column mean of the
observed values); RBF kernel exp(-0.075 d^2), uncentred; tau = 0.1; error = sum of squared errors over
the whole 100 x 12 matrix. Both solvers run on the same masks, BLAS pinned to one thread: "reduced",
the production solver (:func:`nldr.regularizer.minimize_regularized`), and "alternation", the paper's
Algorithm 1 as printed (:func:`nldr.reference.regularizer.minimize_regularized_alternation`).

A second measurement times one Levenberg-Marquardt S-step (the alternation's pre-image step) with the
analytic sparse Jacobian against the same solver with a finite-difference Jacobian (built here, on the
analytic Jacobian's sparsity pattern; tests/test_regularizer.py checks the two agree).

Writes, under ``--out`` (default results/benchmarks/):

- ``regularizer_oil.csv``: one row per method x p x seed (error, mean-imputation error, time, ...);
- ``regularizer_jacobian.csv``: one row per jacobian x p x seed (time and final cost of one S-step).

Usage::

    .venv/bin/python benchmarks/bench_regularizer.py --masks 10 --jobs 2
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from nldr.data_terms import MaskedLeastSquares
from nldr.datasets import load_oil
from nldr.reference.regularizer import (
    finite_difference_pre_image_step,
    minimize_regularized_alternation,
    pre_image_step,
)
from nldr.regularizer import minimize_regularized, optimal_kernel_factor

SOLVERS = {"reduced": minimize_regularized, "alternation": minimize_regularized_alternation}

GAMMA = 0.075
TAU = 0.1
N_ROWS = 100
PAPER = {0.05: (2.3, 2.0), 0.10: (6.0, 3.0), 0.25: (22.0, 7.0), 0.50: (70.0, 11.0)}  # Table 2, "Ours"
TARGET = {0.05: 2.8, 0.10: 6.75, 0.25: 23.75, 0.50: 72.75}


def load(data_dir) -> np.ndarray:
    """The first N_ROWS oil-flow training rows (fetched into resources/ or from $NLDR_DATA_MIRROR)."""
    return load_oil("train", data_dir)[0][:N_ROWS]


def make_mask(shape, p: float, seed: int) -> np.ndarray:
    """True where observed; seeded by (seed, 100 p) so every p has its own independent masks."""
    return np.random.default_rng([seed, round(100 * p)]).random(shape) >= p


def mean_imputation(X: np.ndarray, mask: np.ndarray) -> np.ndarray:
    return np.where(mask, X, np.nanmean(np.where(mask, X, np.nan), axis=0))


def run_solver(args) -> dict:
    path, method, p, seed, options = args
    X = load(path)
    mask = make_mask(X.shape, p, seed)
    S0 = mean_imputation(X, mask)
    cpu = time.process_time()
    with threadpool_limits(1):
        res = SOLVERS[method](MaskedLeastSquares(X, mask), S0, gamma=GAMMA, tau=TAU, **options)
    cpu = time.process_time() - cpu
    return {
        "method": method,
        "p": p,
        "seed": seed,
        "sse": float(np.sum((res.x - X) ** 2)),
        "sse_mean_imputation": float(np.sum((S0 - X) ** 2)),
        "wall_time": res.wall_time,
        "cpu_time": cpu,
        "success": res.success,
        "n_stages": res.n_stages,
        "nit": res.nit,
        "final_rank": int(res.rank_history[-1]),
        "message": res.message,
    }


def run_jacobian(args) -> list[dict]:
    """Time one LM S-step at rho = 100 from mean imputation with each Jacobian."""
    path, p, seed, rho = args
    X = load(path)
    mask = make_mask(X.shape, p, seed)
    S0 = mean_imputation(X, mask)
    term = MaskedLeastSquares(X, mask)
    rows = []
    with threadpool_limits(1):
        C = optimal_kernel_factor(S0, gamma=GAMMA, tau=TAU, rho=rho)
        B = C.T @ C
        steps = {"analytic": pre_image_step, "finite-difference": finite_difference_pre_image_step}
        for jacobian, step in steps.items():
            start = time.perf_counter()
            S = step(S0, C, term, gamma=GAMMA, rho=rho, max_iter=50)
            elapsed = time.perf_counter() - start
            K = np.exp(-GAMMA * np.sum((S[:, None, :] - S[None, :, :]) ** 2, axis=-1))
            cost = term.value(S) + rho / 2 * np.sum((K - B) ** 2)
            rows.append(
                {"jacobian": jacobian, "p": p, "seed": seed, "rho": rho, "time": elapsed, "cost": cost}
            )
    return rows


def summarise(df: pd.DataFrame) -> pd.DataFrame:
    g = df.groupby(["method", "p"])
    out = pd.DataFrame(
        {
            "sse_mean": g["sse"].mean(),
            "sse_std": g["sse"].std(ddof=0),
            "mean_imputation": g["sse_mean_imputation"].mean(),
            "time_median": g["wall_time"].median(),
            "time_max": g["wall_time"].max(),
            "cpu_median": g["cpu_time"].median(),
            "cpu_max": g["cpu_time"].max(),
            "success": g["success"].sum(),
            "n": g["sse"].size(),
        }
    ).reset_index()
    out["paper"] = out["p"].map(lambda p: f"{PAPER[p][0]:g}±{PAPER[p][1]:g}")
    out["target"] = out["p"].map(TARGET)
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--data-dir", default=None, help="data folder (default resources/)")
    parser.add_argument("--out", default="results/benchmarks", help="output directory")
    parser.add_argument("--masks", type=int, default=10, help="masks per p for the reduced method")
    parser.add_argument("--alternation-masks", type=int, default=None, help="masks per p (default --masks)")
    parser.add_argument("--p", type=float, nargs="+", default=[0.05, 0.10, 0.25, 0.50])
    parser.add_argument("--methods", nargs="+", default=["reduced", "alternation"])
    parser.add_argument("--jacobian-masks", type=int, default=3, help="masks per p for the Jacobian timing")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (each pinned to 1 BLAS thread)")
    args = parser.parse_args(argv)

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    n_alt = args.masks if args.alternation_masks is None else args.alternation_masks
    tasks = [
        (args.data_dir, method, p, seed, {})
        for method in args.methods
        for p in args.p
        for seed in range(args.masks if method == "reduced" else n_alt)
    ]
    jac_tasks = [(args.data_dir, p, seed, 100.0) for p in args.p for seed in range(args.jacobian_masks)]
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        rows = list(pool.map(run_solver, tasks))
        jac_rows = [row for rows_ in pool.map(run_jacobian, jac_tasks) for row in rows_]

    df = pd.DataFrame(rows)
    df.to_csv(out / "regularizer_oil.csv", index=False)
    jac = pd.DataFrame(jac_rows)
    jac.to_csv(out / "regularizer_jacobian.csv", index=False)

    pd.set_option("display.width", 160)
    print(summarise(df).to_string(index=False, float_format=lambda v: f"{v:.2f}"))
    if not jac.empty:
        wide = jac.pivot_table(index=["p", "seed"], columns="jacobian", values=["time", "cost"])
        ratio = wide["time"]["finite-difference"] / wide["time"]["analytic"]
        print("\nLM S-step (rho = 100) time, finite-difference / analytic Jacobian:")
        print(
            f"  median {ratio.median():.1f}x (range {ratio.min():.1f}-{ratio.max():.1f}); analytic median "
            f"{wide['time']['analytic'].median():.3f} s, finite-difference median "
            f"{wide['time']['finite-difference'].median():.3f} s; max relative cost difference "
            f"{np.max(np.abs(wide['cost']['finite-difference'] / wide['cost']['analytic'] - 1)):.1e}"
        )


if __name__ == "__main__":
    main()
