"""The imputer's no-argument defaults (``KernelRegularizerImputer()``): error, speed and tuning.

Run as ``OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py SUBCOMMAND [options]``. Oil-flow
rows, Table 2's masks (:func:`nldr.experiments._table2.random_mask`, private: imported so that these
are the pipeline's masks; mask k at p uses seed 2016 + k), SSE over the whole matrix unless said
otherwise, CPU seconds by ``time.process_time`` (the machine may be shared: compare methods within one
session).

``compare``: per mask of the first ``--rows`` training rows, ``default`` (``KernelRegularizerImputer()``,
its own hold-out tuning included in its CPU seconds), ``paper`` (the paper's Table 2 settings written
out: raw columns, gamma 0.075, tau 0.1, exact) and ``missForest100`` (100 trees, its
``max_features`` in {1/3, 1} chosen by :class:`nldr.model_selection.HoldoutSearch` over
the pipeline's grid (:func:`nldr.impute._grids.baseline_grid`, private: the tables' own search
grids) on ``--folds`` folds, seed = the mask's seed, refitted). Appends one
row per (mask, method) to ``--out``/defaults.csv (rows already there are skipped), then prints mean,
sample sd and count of the SSE per (rows, p, method).

``oracle``: per mask at one p, ``KernelRegularizerImputer().fit`` (its search over the width multiples
and ``--taus``), then every candidate of that grid refitted with fixed ``gamma`` and ``tau``. The
per-mask minimum over the candidates uses the ground truth: an **oracle**, the best any rule on this
grid could do, not a method. Prints one line per mask and the means.

``fit``: ``KernelRegularizerImputer().fit_transform`` on the first ``--rows`` training rows at each p
(mask seed 2016), its tuning included, and the same fit untuned (``gamma`` and ``tau`` set to the
values the tuning chose), so the tuning's cost is the difference.

``speed``: side by side in one process, per mask: ``KernelRegularizerImputer()`` and missForest (100
trees, 5 sweeps, standardised input) at ``max_features`` 1/3 and 1, one after the other, on the first
``--rows`` rows (the training split up to 1000, else :func:`nldr.datasets.load_oil_rows`: the three
splits, 3000 is every row): CPU seconds and SSE of each.

``path``: the solver paths on the first n training rows (``--sizes``), ``--masks`` masks at each p:
``method="exact"`` against ``"auto"``, untuned (the median rule, tau 0.1, standardised): SSE and CPU
seconds (above 150 rows "auto" is the approximate Nystroem path).

``heavy``: a synthetic heavy-tailed table, 303 x 22 (3 latent normals; each column a random direction
of them plus noise 0.3 through exp(1.2 x), sinh(1.5 x) or x + x^2 / 2 in turn, scaled to sds from 0.6
to 11,800; 20 % MCAR; table and mask from ``default_rng(seed)``): ``gamma=None, tau=0.1`` on
``method="exact"``, ``"auto"`` and ``"nystroem-warm"`` (100 random landmarks), the default, and
missForest (1/3): RMSE over the hidden entries in units of each column's sd.

``start``: the default's solve (untuned: the median rule's width times ``--mults`` / 0.25, tau
``--taus``) on the first ``--rows`` training rows (``--heldout``: oil rows 1000-1999 of
:func:`nldr.datasets.load_oil_rows`, the validation split, which no benchmark cell uses) from each of
``--starts``: "mean" (``init="mean"``) or "knn<k>" (``init="knn"`` with the module constant
``INIT_NEIGHBOURS`` set to k); ``--exact`` solves with ``method="exact"`` instead of "auto". Per mask:
SSE, the exact energy at ``rho_max`` of the solve's S (:func:`nldr.regularizer.reduced_energy`: which
minimum the path reached), L-BFGS iterations and CPU seconds; then means per (p, start, multiple, tau).
Ground truth scores every candidate: the best per mask is an **oracle**.

``transform``: fit on the 1000 training rows (complete), then complete the first 200 validation rows
with a share p of their entries hidden (mask seed 2016 + k): SSE on the hidden entries of ours and of
scikit-learn's ``KNNImputer`` (its defaults, and its ``n_neighbors``/``weights`` chosen by the
hold-out search of ``baseline_grid`` on the training rows with the same share
hidden), and ours' milliseconds per new row.

``ard``: per-column widths, chosen by the hold-out error. ARD is the RBF kernel
``exp(-gamma sum_j a_j^2 (s_ij - s_kj)^2)`` on the standardised columns, solved as the isotropic kernel
on the columns scaled by ``a_j`` (so the data term's weight of column j is ``a_j^2`` too). Per mask:
``default`` as above; ``ard``: from a = 1, one pass of coordinate search over the columns (a_j times
0.5 or 2, kept when it lowers the mean squared hold-out error, original units, on the same folds as the
default's tuning), gamma and tau at the default's choice, then the solve on every observed entry with
the chosen a. Appends rows to ``--out``/ard.csv; prints mean, sd and count per p.

``leads``: two leads for the error gap, on the benchmark's own cells, masks and input
(:mod:`nldr.experiments._benchmark`, private: its data sets, ``draw_mask`` and standardisation; RMSE over
the hidden entries in each column's full-data sd). ``--lead indicators``: per MAR and MNAR cell, the
default ("ours") on the masked matrix and on it with the missingness indicators of its incomplete columns
appended (standardised, fully observed); prints the mean RMSE of each, the mean difference, its
standard error and the masks it improved. ``--lead blend``: oil1000 MCAR, the default, missForest
(``max_features`` 1/3) and the mean of their completions; prints the SSE of each.

``oracle`` and ``ard`` read the default's tuning grid and folds from :mod:`nldr.impute._regularizer`
(private): they measure that internal choice.

Usage::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py compare --rows 100 --masks 10
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py compare --rows 1000 --masks 3 --methods default
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py oracle --p 0.5
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py fit --rows 1000
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py speed --rows 1000 --masks 3
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py speed --rows 3000 --p 0.25 --masks 3
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py path --sizes 150 300 --masks 3
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py heavy --seeds 1 2 3
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py start --masks 10 --starts mean knn5 knn10 knn20
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py start --masks 3 --starts mean knn10 --exact
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py start --starts knn10 --mults 0.125 0.25 0.5 1 \
        --taus 0.03 0.1 0.3
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py transform --masks 3
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py ard --rows 100 --masks 5
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py leads --lead indicators --masks 10
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_defaults.py leads --lead blend --masks 3
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from _common import append_row, check_blas, common_options, done, key, parser, timed
from sklearn.impute import KNNImputer

from nldr._baselines._masked import observed_standardisation
from nldr.datasets import load_oil, load_oil_rows
from nldr.experiments._table2 import random_mask
from nldr.impute import KernelRegularizerImputer
from nldr.impute import _regularizer as tuning
from nldr.impute._grids import baseline_grid, missforest_imputer
from nldr.model_selection import HoldoutSearch, holdout_folds

METHODS = ("default", "paper", "missForest100")
SEED = 2016


def masked(X, p, seed):
    """``(X with the hidden entries NaN, the mask)`` of Table 2's mask at p and seed."""
    mask = random_mask(X.shape, p, seed)
    return np.where(mask, X, np.nan), mask


def sse(X_hat, X) -> float:
    return float(np.sum((X_hat - X) ** 2))


# ---------------------------------------------------------------------------------------------- compare


def estimator(method: str, W, seed: int, folds: int):
    if method == "default":
        return KernelRegularizerImputer()
    if method == "paper":
        return KernelRegularizerImputer(standardize=False, gamma=0.075, tau=0.1, center=False, method="exact")
    if method == "missForest100":
        return HoldoutSearch(*baseline_grid("missForest", W, n_trees=100), n_folds=folds, random_state=seed)
    raise ValueError(f"method must be one of {METHODS}; got {method!r}")


def describe(fitted) -> str:
    if isinstance(fitted, HoldoutSearch):
        return repr(fitted.best_params_)
    return f"gamma={fitted.gamma_:.4g} tau={fitted.tau_:.4g} method={fitted.method_}"


def run_compare(args):
    if args.quick:
        args.p, args.masks = [0.25], 1
    X = load_oil("train", args.data_dir)[0][: args.rows]
    seen = done(args.out, "defaults.csv", ["n_rows", "p", "seed", "method"])
    for p in args.p:
        for k in range(args.first_mask, args.first_mask + args.masks):
            seed = args.seed + k
            W, _ = masked(X, p, seed)
            for method in args.methods:
                if key((args.rows, p, seed, method)) in seen:
                    continue
                fitted = estimator(method, W, seed, args.folds)
                cpu, X_hat = timed(lambda fitted=fitted, W=W: fitted.fit_transform(W), clock="cpu")
                row = {"n_rows": args.rows, "p": p, "seed": seed, "method": method, "sse": sse(X_hat, X)}
                row |= {"cpu": cpu, "params": describe(fitted)}
                print(
                    f"n={args.rows} p={p:g} seed={seed} {method:14s} sse={row['sse']:9.3f} cpu={cpu:7.2f}s "
                    f"{row['params']}",
                    flush=True,
                )
                append_row(row, args.out, "defaults.csv")
    table = pd.read_csv(args.out / "defaults.csv")
    table = table[table["n_rows"] == args.rows]
    summary = table.groupby(["p", "method"]).agg(
        sse=("sse", "mean"), sse_sd=("sse", "std"), masks=("sse", "size"), cpu=("cpu", "mean")
    )
    print(summary.round(3).to_string())


# ---------------------------------------------------------------------------------------------- oracle


def run_oracle(args):
    if args.quick:
        args.masks = 1
    X = load_oil("train", args.data_dir)[0][: args.rows]
    defaults, oracles, grid = [], [], {}
    for k in range(args.masks):
        W, _ = masked(X, args.p, SEED + k)
        est = KernelRegularizerImputer().fit(W)
        defaults.append(sse(est.completed_, X))
        multiples, base = tuning.TUNE_GAMMA_MULTIPLES, tuning.MEDIAN_RULE_MULTIPLE
        median_rule = est.cv_results_["params"][0]["gamma"] * base / multiples[0]
        scores = {}
        for m in multiples:
            for tau in args.taus:
                fixed = KernelRegularizerImputer(gamma=m * median_rule / base, tau=tau).fit(W)
                scores[(m, tau)] = sse(fixed.completed_, X)
                grid.setdefault((m, tau), []).append(scores[(m, tau)])
        oracles.append(min(scores.values()))
        chosen = (est.gamma_ * base / median_rule, est.tau_)
        print(
            f"seed {SEED + k}: default {defaults[-1]:.2f} (width x{chosen[0]:g}, tau {chosen[1]:g}), "
            f"oracle {oracles[-1]:.2f} {min(scores, key=scores.get)}",
            flush=True,
        )
    spread = np.std(defaults, ddof=1) if len(defaults) > 1 else float("nan")
    print(f"default {np.mean(defaults):.2f} ± {spread:.2f}; per-mask oracle {np.mean(oracles):.2f}")
    for (m, tau), values in grid.items():
        print(f"  fixed width x{m:g}, tau {tau:g}: {np.mean(values):.2f}")


# ---------------------------------------------------------------------------------------------- speed


def run_fit(args):
    if args.quick:
        args.rows, args.p = 100, [0.25]
    X = load_oil("train", args.data_dir)[0][: args.rows]
    for p in args.p:
        W, _ = masked(X, p, SEED)
        tuned = KernelRegularizerImputer()
        cpu, X_hat = timed(lambda tuned=tuned, W=W: tuned.fit_transform(W), clock="cpu")
        fixed = KernelRegularizerImputer(gamma=tuned.gamma_, tau=tuned.tau_)
        cpu_fixed, X_fix = timed(lambda fixed=fixed, W=W: fixed.fit_transform(W), clock="cpu")
        print(
            f"fit n={args.rows} p={p:g}: default {cpu:.1f} CPU s (SSE {sse(X_hat, X):.2f}; "
            f"gamma {tuned.gamma_:.4g}, tau {tuned.tau_:g}, {tuned.method_}), untuned at the chosen values "
            f"{cpu_fixed:.1f} CPU s (SSE {sse(X_fix, X):.2f}), tuning {cpu - cpu_fixed:.1f} CPU s",
            flush=True,
        )


def forest_fit(W, share: float) -> np.ndarray:
    """missForest (100 trees, 5 sweeps, ``max_features=share``) on W standardised by its observed
    entries, mapped back (as the benchmark feeds every method)."""
    mask = ~np.isnan(W)
    shift, scale = observed_standardisation(np.where(mask, W, 0.0), mask)
    return missforest_imputer(max_features=share).fit_transform((W - shift) / scale) * scale + shift


def time_each(fits: dict, W) -> dict:
    """name -> (CPU seconds, completion) of each ``fits[name](W)``, run in turn."""
    return {name: timed(lambda fit=fit: fit(W), clock="cpu") for name, fit in fits.items()}


def run_speed(args):
    if args.quick:
        args.rows, args.p, args.masks = 200, [0.25], 1
    n = args.rows
    X = load_oil("train", args.data_dir)[0][:n] if n <= 1000 else load_oil_rows(n, args.data_dir)
    fits = {
        "default": lambda W: KernelRegularizerImputer().fit_transform(W),
        "missForest 1/3": lambda W: forest_fit(W, 1 / 3),
        "missForest 1": lambda W: forest_fit(W, 1.0),
    }
    for p in args.p:
        for k in range(args.masks):
            W, _ = masked(X, p, SEED + k)
            done_fits = time_each(fits, W).items()
            line = [f"{name} {cpu:.2f} CPU s, SSE {sse(X_hat, X):.3f}" for name, (cpu, X_hat) in done_fits]
            print(f"speed n={n} p={p:g} seed={SEED + k}: " + "; ".join(line), flush=True)


def heavy_table(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The synthetic heavy-tailed table (303, 22) and its mask (True = observed); module docstring."""
    rng = np.random.default_rng(seed)
    latent = rng.standard_normal((303, 3))
    columns = []
    for j, scale in enumerate(np.geomspace(0.6, 11800.0, 22)):
        direction = rng.standard_normal(3)
        t = latent @ direction / np.linalg.norm(direction) + 0.3 * rng.standard_normal(303)
        x = (np.exp(1.2 * t), np.sinh(1.5 * t), t + 0.5 * t**2)[j % 3]
        columns.append(scale * x / x.std())
    X = np.column_stack(columns)
    return X, rng.random(X.shape) > 0.2


def run_heavy(args):
    fits = {m: lambda W, m=m: KernelRegularizerImputer(gamma=None, tau=0.1, method=m).fit_transform(W)
            for m in ("exact", "auto", "nystroem-warm")}  # fmt: skip
    fits["default"] = lambda W: KernelRegularizerImputer().fit_transform(W)
    fits["missForest 1/3"] = lambda W: forest_fit(W, 1 / 3)
    for seed in args.seeds:
        X, mask = heavy_table(seed)
        sd = X.std(axis=0)
        line = []
        for name, (cpu, X_hat) in time_each(fits, np.where(mask, X, np.nan)).items():
            rmse = float(np.sqrt(np.mean(((X_hat - X) / sd)[~mask] ** 2)))
            line.append(f"{name} RMSE {rmse:.3f} ({cpu:.1f} CPU s)")
        print(f"heavy seed={seed}: " + "; ".join(line), flush=True)


def run_path(args):
    if args.quick:
        args.sizes, args.p, args.masks = [150], [0.25], 1
    for n in args.sizes:
        X = load_oil("train", args.data_dir)[0][:n]
        for p in args.p:
            for k in range(args.masks):
                W, _ = masked(X, p, SEED + k)
                line = []
                for method in ("exact", "auto"):
                    est = KernelRegularizerImputer(gamma=None, tau=0.1, method=method)
                    cpu, X_hat = timed(lambda est=est, W=W: est.fit_transform(W), clock="cpu")
                    line.append(f"{method} SSE {sse(X_hat, X):.3f} ({cpu:.1f} CPU s)")
                print(f"path n={n} p={p:g} seed={SEED + k}: " + ", ".join(line), flush=True)


def run_start(args):
    from nldr.data_terms import MaskedLeastSquares
    from nldr.impute import _regularizer as module
    from nldr.impute._defaults import MEDIAN_RULE_MULTIPLE, median_rule_gamma
    from nldr.regularizer import reduced_energy

    if args.quick:
        args.rows, args.p, args.masks, args.starts = 200, [0.25], 1, ["mean", "knn10"]
    X = load_oil_rows(2000, args.data_dir)[1000:] if args.heldout else load_oil("train", args.data_dir)[0]
    X = X[: args.rows]
    method, rows = ("exact" if args.exact else "auto"), []
    for p in args.p:
        for k in range(args.masks):
            W, mask = masked(X, p, SEED + k)
            mean, scale = observed_standardisation(np.where(mask, X, 0.0), mask)
            Z = np.where(mask, (X - mean) / scale, 0.0)
            rule = median_rule_gamma(Z)  # the standardised columns' observed means are 0: the mean fill
            for start, mult, tau in ((s, m, t) for s in args.starts for m in args.mults for t in args.taus):
                if start != "mean":
                    module.INIT_NEIGHBOURS = int(start.removeprefix("knn"))
                gamma = mult * rule / MEDIAN_RULE_MULTIPLE
                init = "mean" if start == "mean" else "knn"
                est = KernelRegularizerImputer(gamma=gamma, tau=tau, method=method, init=init)
                cpu, X_hat = timed(lambda est=est, W=W: est.fit_transform(W), clock="cpu")
                data = MaskedLeastSquares(np.where(mask, (W - est.mean_) / est.scale_, 0.0), mask)
                energy, _ = reduced_energy(est.manifold_rows_, data, gamma=gamma, tau=tau, rho=est.rho_max)
                error = sse(X_hat, X)
                rows.append({"p": p, "start": start, "mult": mult, "tau": tau, "sse": error, "cpu": cpu})
                case = f"n={X.shape[0]} p={p:g} seed={SEED + k} {method} {start} mult={mult:g} tau={tau:g}"
                found = f"SSE {error:.3f}, exact energy {energy:.6f}, {est.result_.nit} iterations"
                print(f"start {case}: {found}, {cpu:.2f} CPU s", flush=True)
    table = pd.DataFrame(rows).groupby(["p", "start", "mult", "tau"])
    summary = table.agg(sse=("sse", "mean"), sd=("sse", "std"), masks=("sse", "size"), cpu=("cpu", "mean"))
    print(summary.round(3).to_string())


def run_transform(args):
    X_train = load_oil("train", args.data_dir)[0]
    X_new = load_oil("validation", args.data_dir)[0][:200]
    if args.quick:
        X_train, args.p, args.masks = X_train[:300], [0.25], 1
    cpu_fit, ours = timed(lambda: KernelRegularizerImputer().fit(X_train), clock="cpu")
    print(
        f"transform: fit on {X_train.shape[0]} complete rows {cpu_fit:.1f} CPU s "
        f"(gamma {ours.gamma_:.4g}, tau {ours.tau_:g}, {ours.n_components_} components)",
        flush=True,
    )
    for p in args.p:
        for k in range(args.masks):
            seed = SEED + k
            W, mask = masked(X_new, p, seed)
            cpu, X_hat = timed(lambda W=W: ours.transform(W), clock="cpu")
            hidden_sse = float(np.sum((X_hat - X_new)[~mask] ** 2))
            knn = float(np.sum((KNNImputer().fit(X_train).transform(W) - X_new)[~mask] ** 2))
            train, _ = masked(X_train, p, seed)
            search = HoldoutSearch(*baseline_grid("KNNImputer", train), n_folds=3, random_state=seed)
            search.fit(train)
            cv = KNNImputer(**search.best_params_).fit(X_train).transform(W)
            knn_cv = float(np.sum((cv - X_new)[~mask] ** 2))
            print(
                f"transform p={p:g} seed={seed}: ours SSE {hidden_sse:.3f} "
                f"({1e3 * cpu / X_new.shape[0]:.2f} ms/row), "
                f"KNNImputer() {knn:.3f}, KNNImputer CV {knn_cv:.3f} {search.best_params_}",
                flush=True,
            )


# ---------------------------------------------------------------------------------------------- ard


def solve_scaled(Z, mask, a, gamma, tau):
    """The isotropic solve on the columns scaled by a; the estimate in standardised units."""
    est = KernelRegularizerImputer(standardize=False, gamma=gamma, tau=tau, method="exact")
    return est.fit_transform(np.where(mask, Z * a, np.nan)) / a


def ard_mask(X, p, seed):
    W, mask = masked(X, p, seed)
    cpu_default, default = timed(lambda: KernelRegularizerImputer().fit(W), clock="cpu")
    mean, sd = default.mean_, default.scale_
    Z = np.where(mask, (W - mean) / sd, np.nan)
    gamma, tau = default.gamma_, default.tau_
    folds = holdout_folds(mask, tuning.TUNE_FOLDS, 0, holdout=tuning.TUNE_HOLDOUT)

    def score(a):
        errors = []
        for hidden in folds:
            S = solve_scaled(Z, mask & ~hidden, a, gamma, tau) * sd + mean
            errors.append(np.mean((S - X)[hidden] ** 2))
        return float(np.mean(errors))

    def search():
        a = np.ones(X.shape[1])
        best = score(a)
        for j in range(X.shape[1]):
            for factor in (0.5, 2.0):
                trial = a.copy()
                trial[j] *= factor
                value = score(trial)
                if value < best:
                    a, best = trial, value
                    break
        return a, solve_scaled(Z, mask, a, gamma, tau) * sd + mean

    cpu_ard, (a, X_ard) = timed(search, clock="cpu")
    return [
        {
            "p": p, "seed": seed, "method": "default", "sse": sse(default.completed_, X), "cpu": cpu_default,
            "a": "",
        },
        {
            "p": p, "seed": seed, "method": "ard", "sse": sse(X_ard, X), "cpu": cpu_ard + cpu_default,
            "a": " ".join(f"{v:g}" for v in a),
        },
    ]  # fmt: skip


def run_ard(args):
    if args.quick:
        args.p, args.masks = [0.25], 1
    X = load_oil("train", args.data_dir)[0][: args.rows]
    seen = {(p, seed) for p, seed, _ in done(args.out, "ard.csv", ["p", "seed", "method"])}
    for p in args.p:
        for k in range(args.masks):
            if key((p, SEED + k)) in seen:
                continue
            for row in ard_mask(X, p, SEED + k):
                print(
                    f"p={p:g} seed={row['seed']} {row['method']:8s} sse={row['sse']:8.3f} "
                    f"cpu={row['cpu']:6.1f}s {row['a']}",
                    flush=True,
                )
                append_row(row, args.out, "ard.csv")
    table = pd.read_csv(args.out / "ard.csv")
    print(
        table.groupby(["p", "method"])
        .agg(sse=("sse", "mean"), sd=("sse", "std"), masks=("sse", "size"), cpu=("cpu", "mean"))
        .round(3)
        .to_string()
    )


# ------------------------------------------------------------------------------------------------ leads


def with_indicators(Z, mask):
    """Z with the standardised missingness indicators of its incomplete columns appended."""
    ind = (~mask[:, (~mask).any(axis=0)]).astype(float)
    shift, scale = observed_standardisation(ind, np.ones(ind.shape, dtype=bool))
    return np.hstack([Z, (ind - shift) / scale])


def run_leads(args):
    from nldr import experiments
    from nldr.experiments._benchmark import _standardise, draw_mask, load_dataset
    from nldr.experiments.notebook import load_config

    benchmark = experiments.get("benchmark")
    config = load_config(Path(__file__).resolve().parents[1])
    settings = benchmark.settings(config)
    blend = args.lead == "blend"
    cells = [job.params for job in benchmark.jobs(config)]
    cells = [P for P in cells if (P["dataset"] == "oil1000" if blend else P["mechanism"] in ("MAR", "MNAR"))]
    if args.quick:
        cells, args.masks = cells[-1:], 1
    for P in cells:
        X = load_dataset(P["spec"], args.data_dir, settings["subsample_seed"])
        scores = {}
        for k in range(args.masks):
            mask = draw_mask(X, P["mechanism"], P["p"], P["seed"] + k, slope=settings["slope"])
            Z, mean, sd = _standardise(np.where(mask, X, np.nan))
            fits = {"ours": KernelRegularizerImputer().fit_transform(Z)}
            if blend:
                fits["missForest"] = missforest_imputer(max_features=1 / 3).fit_transform(Z)
                fits["blend"] = (fits["ours"] + fits["missForest"]) / 2
                row = {name: sse(Z_hat * sd + mean, X) for name, Z_hat in fits.items()}
            else:
                augmented = with_indicators(Z, mask)
                fits["indicators"] = KernelRegularizerImputer().fit_transform(augmented)[:, : X.shape[1]]
                err = {name: (Z_hat * sd + mean - X) / X.std(axis=0) for name, Z_hat in fits.items()}
                row = {name: float(np.sqrt(np.mean(e[~mask] ** 2))) for name, e in err.items()}
            for name, value in row.items():
                scores.setdefault(name, []).append(value)
        means = "  ".join(f"{name} {np.mean(v):.4f}" for name, v in scores.items())
        cell = f"{P['dataset']} {P['mechanism']} p={P['p']:g}"
        line = f"leads {args.lead} {cell} ({args.masks} masks): {means}"
        if not blend:
            d = np.subtract(scores["indicators"], scores["ours"])
            se = d.std(ddof=1) / np.sqrt(d.size) if d.size > 1 else float("nan")
            line += f"  difference {d.mean():+.4f} (se {se:.4f}), better on {(d < 0).sum()} of {d.size}"
        print(line, flush=True)


def main(argv=None):
    ap = parser(__doc__, options=False)
    sub = ap.add_subparsers(dest="command", required=True)
    ps = ("--p", {"type": float, "nargs": "+", "default": [0.1, 0.25, 0.5], "help": "missing shares"})

    compare = common_options(sub.add_parser("compare", help="default against the paper's values, missForest"))
    compare.add_argument("--rows", type=int, default=100)
    compare.add_argument(ps[0], **ps[1])
    compare.add_argument("--masks", type=int, default=10)
    compare.add_argument("--first-mask", type=int, default=0)
    compare.add_argument("--seed", type=int, default=SEED, help="seed of mask 0")
    compare.add_argument("--folds", type=int, default=3, help="hold-out folds of missForest's search")
    compare.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    compare.set_defaults(run=run_compare)

    oracle = common_options(sub.add_parser("oracle", help="the default's choice against the grid's oracle"))
    oracle.add_argument("--p", type=float, default=0.5)
    oracle.add_argument("--rows", type=int, default=100)
    oracle.add_argument("--masks", type=int, default=10)
    oracle.add_argument("--taus", type=float, nargs="+", default=list(tuning.TUNE_TAUS))
    oracle.set_defaults(run=run_oracle)

    fit = common_options(sub.add_parser("fit", help="the default's fit, its tuning's share"))
    fit.add_argument("--rows", type=int, default=1000)
    fit.add_argument(ps[0], **ps[1])
    fit.set_defaults(run=run_fit)

    speed = common_options(sub.add_parser("speed", help="the default and missForest side by side"))
    speed.add_argument("--rows", type=int, default=1000)
    speed.add_argument(ps[0], **ps[1])
    speed.add_argument("--masks", type=int, default=3)
    speed.set_defaults(run=run_speed)

    path = common_options(sub.add_parser("path", help="exact against auto"))
    path.add_argument("--sizes", type=int, nargs="+", default=[150, 300])
    path.add_argument(ps[0], **ps[1])
    path.add_argument("--masks", type=int, default=3)
    path.set_defaults(run=run_path)

    heavy = common_options(sub.add_parser("heavy", help="a heavy-tailed table: the solver paths"))
    heavy.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    heavy.set_defaults(run=run_heavy)

    start = common_options(sub.add_parser("start", help="the solve's start: mean against nearest rows"))
    start.add_argument("--rows", type=int, default=1000)
    start.add_argument(ps[0], **ps[1])
    start.add_argument("--masks", type=int, default=3)
    start.add_argument("--starts", nargs="+", default=["mean", "knn10"], help='"mean" or "knn<k>"')
    start.add_argument("--mults", type=float, nargs="+", default=[0.25], help="width multiples")
    start.add_argument("--taus", type=float, nargs="+", default=[0.1])
    start.add_argument("--exact", action="store_true", help='method="exact" instead of "auto"')
    start.add_argument("--heldout", action="store_true", help="oil rows 1000-1999 (validation split)")
    start.set_defaults(run=run_start)

    transform = common_options(sub.add_parser("transform", help="new rows against KNNImputer"))
    transform.add_argument(ps[0], **ps[1])
    transform.add_argument("--masks", type=int, default=3)
    transform.set_defaults(run=run_transform)

    ard = common_options(sub.add_parser("ard", help="per-column widths by hold-out"))
    ard.add_argument("--rows", type=int, default=100)
    ard.add_argument(ps[0], **ps[1])
    ard.add_argument("--masks", type=int, default=5)
    ard.set_defaults(run=run_ard)

    leads = common_options(sub.add_parser("leads", help="indicator columns; a blend with missForest"))
    leads.add_argument("--lead", choices=["indicators", "blend"], required=True)
    leads.add_argument("--masks", type=int, default=10)
    leads.set_defaults(run=run_leads)

    args = ap.parse_args(argv)
    check_blas()
    args.run(args)


if __name__ == "__main__":
    main()
