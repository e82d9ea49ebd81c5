"""The regularizer's solvers, timed: eigensolver paths, profiles, and the literal Algorithm 1.

Run as ``OPENBLAS_NUM_THREADS=1 python benchmarks/bench_solvers.py SUBCOMMAND [options]``.

``eigensolver``: the option ``eigensolver="full"`` (every eigenpair of the kernel, dE/dK =
U diag(rho gap) U^T in O(n^3); the original implementation, "before") against the default
``eigensolver="auto"`` (only the eigenpairs above the cubic's threshold when that pays, dE/dK =
rho (K - C^T C) in O(n^2 r); "after"). Each row also records a result of each (energy or error), to
show they agree. Wall seconds, median of ``--repeats`` runs for the short items. Rows:

- ``evaluation``: one reduced energy + gradient (a C-step and the S-gradient) on oil flow (n = 100 and
  n = 1000, the state after the first stage) and on drink, every frame (n = 1102, the ground truth);
- ``lm_s_step``: one Levenberg-Marquardt pre-image step (the literal Algorithm 1's S-step), oil n = 100;
- ``solve_table2``: "Ours" on one Table 2 mask (p = 0.25, seed 2016), n = 100 and n = 1000;
- ``solve_table3``: the kernel regularizer (d_med) on pickup, every 10th frame, full data, from TNH.

Writes ``--out``/solvers.csv. ``--quick``: the oil items at n = 100 only.

``profile``: cProfile of one Table 2 solve ("Ours" on the first 100 oil-flow rows, p = 0.25, mask
seed 2016) and one Table 3 kernel solve (d_med width, pickup, every 10th frame, full data, from the
exact-fit TNH, which is solved first and not profiled). Writes ``--out``/profile_table2.txt and
profile_table3.txt: the top functions by own and by cumulative time, and the wall time.
``--quick``: Table 2 only.

``alternation``: the reduced solver (:func:`nldr.regularizer.minimize_regularized`, the production
solver) against the paper's Algorithm 1 as printed
(:func:`nldr.reference.regularizer.minimize_regularized_alternation`) on the first 100 oil-flow rows,
each entry deleted independently with probability p (masks seeded by (k, 100 p), k < ``--masks``),
mean-imputation start, RBF width 0.075, uncentred, tau = 0.1; SSE over the whole matrix and CPU
seconds. Then one LM S-step at rho = 100 from mean imputation with the analytic sparse Jacobian
against a finite-difference one on the same sparsity pattern (tests/test_regularizer.py checks the
two agree). Writes ``--out``/regularizer_oil.csv and regularizer_jacobian.csv and prints a summary.
``--quick``: one mask at p = 0.25.

Table 2's masks are :func:`nldr.experiments._table2.random_mask` (private: the pipeline's protocol,
imported so that these are the same masks).
"""

from __future__ import annotations

import cProfile
import io
import pstats

import numpy as np
import pandas as pd
from _common import check_blas, common_options, parser, timed, write_csv

from nldr.data_terms import MaskedLeastSquares
from nldr.datasets import load_mocap, load_oil
from nldr.experiments._table2 import random_mask
from nldr.kernels import d_med_width, rbf_kernel
from nldr.nrsfm import OrthographicReprojection, stack_to_rows
from nldr.nrsfm._reconstruct import trace_norm_heuristic
from nldr.reference.regularizer import (
    finite_difference_pre_image_step,
    minimize_regularized_alternation,
    pre_image_step,
)
from nldr.regularizer import minimize_regularized, reduced_energy
from nldr.robust_kpca import closed_form_rank_penalty

GAMMA, TAU = 0.075, 0.1  # Table 2, "Ours"


def mean_imputation(X: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Every missing entry replaced by its column's observed mean (Table 2's start)."""
    return np.where(mask, X, np.nanmean(np.where(mask, X, np.nan), axis=0))


def oil_problem(data_dir, n_rows: int):
    """The first n_rows oil rows, Table 2's mask (p = 0.25, seed 2016), mean imputation, data term."""
    X = load_oil("train", data_dir)[0][:n_rows]
    mask = random_mask(X.shape, 0.25, 2016)
    return X, mask, mean_imputation(X, mask), MaskedLeastSquares(X, mask)


def pickup_problem(data_dir):
    """Table 3's kernel problem on pickup (every 10th frame, full data): data term, TNH start, d_med gamma."""
    seq = load_mocap("pickup", data_dir).subsample(10)
    W2d = stack_to_rows(seq.W, dim=2)
    X0 = trace_norm_heuristic(W2d, None, seq.R, method="cvxpy").x
    return OrthographicReprojection(W2d, None, seq.R), X0, d_med_width(X0)


# ---------------------------------------------------------------------------------------------- eigensolver


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


def run_eigensolver(args) -> None:
    rows: list[dict] = []
    sizes = (100,) if args.quick else (100, 1000)
    for n in sizes:
        X, mask, S0, term = oil_problem(args.data_dir, n)
        # the state after the first stage, where the later stages spend their evaluations
        S1 = minimize_regularized(term, S0, gamma=GAMMA, tau=TAU, rho_max=1.0).x
        compare(
            rows,
            "evaluation",
            n,
            lambda e, S1=S1, term=term: reduced_energy(
                S1, term, gamma=GAMMA, tau=TAU, rho=1e2, eigensolver=e
            ),
            args.repeats if n == 100 else max(3, args.repeats // 10),
            lambda r: r[0],
        )
    if not args.quick:
        seq = load_mocap("drink", args.data_dir)
        W2d, X_gt = stack_to_rows(seq.W, dim=2), stack_to_rows(seq.S, dim=3)
        drink = OrthographicReprojection(W2d, None, seq.R)
        gamma = d_med_width(X_gt)
        compare(
            rows,
            "evaluation",
            X_gt.shape[0],
            lambda e: reduced_energy(X_gt, drink, gamma=gamma, tau=1e-4, rho=1e-2, eigensolver=e),
            3,
            lambda r: r[0],
        )

    X, mask, S0, term = oil_problem(args.data_dir, 100)
    C = closed_form_rank_penalty(rbf_kernel(S0, GAMMA), TAU, 1.0)  # the C-step
    t_lm, S_lm = timed(lambda: pre_image_step(S0, C, term, gamma=GAMMA, rho=1.0), args.repeats)
    sse_lm = float(np.sum((S_lm - X) ** 2))
    rows.append(
        {
            "item": "lm_s_step",
            "n": 100,
            "before_s": t_lm,
            "after_s": t_lm,
            "speedup": 1.0,
            "before_result": sse_lm,
            "after_result": sse_lm,
        }
    )
    print(f"lm_s_step      n=  100  {t_lm:.4f} s (unchanged: no eigendecomposition)")

    for n in sizes:
        X, mask, S0, term = oil_problem(args.data_dir, n)
        compare(
            rows,
            "solve_table2",
            n,
            lambda e, S0=S0, term=term: minimize_regularized(
                term, S0, gamma=GAMMA, tau=TAU, options={"eigensolver": e}
            ),
            3 if n == 100 else 1,
            lambda r, X=X: float(np.sum((r.x - X) ** 2)),
        )

    if not args.quick:
        data, X0, gamma = pickup_problem(args.data_dir)
        compare(
            rows,
            "solve_table3",
            X0.shape[0],
            lambda e: minimize_regularized(
                data, X0, gamma=gamma, tau=1e-4, rho0=1e-3, rho_max=10.0,
                options={"eigensolver": e, "scale": 1.0},  # Table 3's units
            ),  # fmt: skip
            3,
            lambda r: r.stage_energy[-1],
        )
    write_csv(rows, args.out, "solvers.csv")


# ---------------------------------------------------------------------------------------------- profile


def profile(fn, path, title: str, top: int = 18) -> float:
    prof = cProfile.Profile()
    wall, _ = timed(lambda: prof.runcall(fn))
    out = io.StringIO()
    out.write(f"{title}\nwall time {wall:.3f} s (under cProfile)\n\n== by own time ==\n")
    pstats.Stats(prof, stream=out).strip_dirs().sort_stats("tottime").print_stats(top)
    out.write("\n== by cumulative time ==\n")
    pstats.Stats(prof, stream=out).strip_dirs().sort_stats("cumulative").print_stats(top)
    path.write_text(out.getvalue())
    print(f"{title}: {wall:.2f} s -> {path}")
    return wall


def run_profile(args) -> None:
    args.out.mkdir(parents=True, exist_ok=True)
    _, _, S0, term = oil_problem(args.data_dir, 100)
    profile(
        lambda: minimize_regularized(term, S0, gamma=GAMMA, tau=TAU),
        args.out / "profile_table2.txt",
        "Table 2: Ours, oil flow 100 x 12, p = 0.25, seed 2016",
    )
    if args.quick:
        return
    data, X0, gamma = pickup_problem(args.data_dir)
    profile(
        lambda: minimize_regularized(
            data, X0, gamma=gamma, tau=1e-4, rho0=1e-3, rho_growth=10.0, rho_max=10.0,
            options={"scale": 1.0},  # Table 3's units
        ),  # fmt: skip
        args.out / "profile_table3.txt",
        f"Table 3: kernel d_med on pickup (every 10th frame, {X0.shape[0]} frames), full data",
    )


# ---------------------------------------------------------------------------------------------- alternation

SOLVERS = {"reduced": minimize_regularized, "alternation": minimize_regularized_alternation}
PAPER = {0.05: (2.3, 2.0), 0.10: (6.0, 3.0), 0.25: (22.0, 7.0), 0.50: (70.0, 11.0)}  # Table 2, "Ours"


def alternation_mask(shape, p: float, seed: int) -> np.ndarray:
    """True where observed; seeded by (seed, 100 p) so every p has its own independent masks."""
    return np.random.default_rng([seed, round(100 * p)]).random(shape) >= p


def run_solver(X, method, p, seed) -> dict:
    mask = alternation_mask(X.shape, p, seed)
    S0 = mean_imputation(X, mask)
    cpu, res = timed(
        lambda: SOLVERS[method](MaskedLeastSquares(X, mask), S0, gamma=GAMMA, tau=TAU), clock="cpu"
    )
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


def run_jacobian(X, p, seed, rho=100.0) -> list[dict]:
    """One LM S-step at rho from mean imputation with each Jacobian: wall seconds and final cost."""
    mask = alternation_mask(X.shape, p, seed)
    S0 = mean_imputation(X, mask)
    term = MaskedLeastSquares(X, mask)
    C = closed_form_rank_penalty(rbf_kernel(S0, GAMMA), TAU, rho)  # the C-step
    B = C.T @ C
    rows = []
    steps = {"analytic": pre_image_step, "finite-difference": finite_difference_pre_image_step}
    for jacobian, step in steps.items():
        elapsed, S = timed(lambda step=step: step(S0, C, term, gamma=GAMMA, rho=rho, max_iter=50))
        K = np.exp(-GAMMA * np.sum((S[:, None, :] - S[None, :, :]) ** 2, axis=-1))
        cost = term.value(S) + rho / 2 * np.sum((K - B) ** 2)
        rows.append({"jacobian": jacobian, "p": p, "seed": seed, "rho": rho, "time": elapsed, "cost": cost})
    return rows


def run_alternation(args) -> None:
    if args.quick:
        args.masks, args.alternation_masks, args.p, args.jacobian_masks = 1, 1, [0.25], 1
    X = load_oil("train", args.data_dir)[0][:100]
    n_alt = args.masks if args.alternation_masks is None else args.alternation_masks
    rows = [
        run_solver(X, method, p, seed)
        for method in args.methods
        for p in args.p
        for seed in range(args.masks if method == "reduced" else n_alt)
    ]
    jac = pd.DataFrame(
        [row for p in args.p for seed in range(args.jacobian_masks) for row in run_jacobian(X, p, seed)]
    )
    df = pd.DataFrame(rows)
    write_csv(df, args.out, "regularizer_oil.csv")
    write_csv(jac, args.out, "regularizer_jacobian.csv")

    g = df.groupby(["method", "p"])
    summary = pd.DataFrame(
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
    summary["paper"] = summary["p"].map(lambda p: f"{PAPER[p][0]:g}±{PAPER[p][1]:g}" if p in PAPER else "")
    pd.set_option("display.width", 160)
    print(summary.to_string(index=False, float_format=lambda v: f"{v:.2f}"))
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


def main(argv=None) -> None:
    ap = parser(__doc__, options=False)
    sub = ap.add_subparsers(dest="command", required=True)
    eig = common_options(sub.add_parser("eigensolver", help="full against auto eigensolver"), repeats=30)
    eig.set_defaults(run=run_eigensolver)
    prof = common_options(sub.add_parser("profile", help="cProfile of one Table 2 and one Table 3 solve"))
    prof.set_defaults(run=run_profile)
    alt = common_options(sub.add_parser("alternation", help="reduced solver against Algorithm 1"))
    alt.add_argument("--masks", type=int, default=10, help="masks per p for the reduced method")
    alt.add_argument("--alternation-masks", type=int, default=None, help="masks per p (default --masks)")
    alt.add_argument("--p", type=float, nargs="+", default=[0.05, 0.10, 0.25, 0.50])
    alt.add_argument("--methods", nargs="+", default=list(SOLVERS), choices=list(SOLVERS))
    alt.add_argument("--jacobian-masks", type=int, default=3, help="masks per p for the Jacobian timing")
    alt.set_defaults(run=run_alternation)
    args = ap.parse_args(argv)
    check_blas()
    args.run(args)


if __name__ == "__main__":
    main()
