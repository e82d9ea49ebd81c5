"""Benchmark (not in the paper): the regularizer with its defaults against the imputers people use, on
oil flow and on the data sets that ship inside scikit-learn, under three missingness mechanisms.

One job = one cell: a data set (``datasets``: oil flow's first training rows, or a bundled
scikit-learn set, optionally a seeded subsample of its rows; constant columns dropped) and one
mechanism at one rate (``missingness``: MCAR, MAR or MNAR of :mod:`.missingness`). The job draws
``n_masks`` masks (mask k uses seed ``seed + k``, the same seeds in every cell) and completes each with
every method of ``methods``:

- ``Ours``: :class:`~nldr.impute.KernelRegularizerImputer` with no arguments (its defaults choose its
  own settings from the observed entries);
- the peers at their authors' recommended settings, each knob chosen by
  :class:`~nldr.model_selection.HoldoutSearch` over :func:`~nldr.impute._grids.baseline_grid`
  (``grids`` may replace a grid): ``missForest`` (100 trees), ``GP-LVM`` (GPy, latent dimension and
  inducing points), ``KNNImputer``, ``IterativeImputer`` (BayesianRidge, no knob), ``SoftImpute``;
- ``mean``: the column means, the floor.

Tuning. The peers' knobs are chosen once per cell, by ``n_folds``-fold hold-out CV on the observed
entries of the cell's first mask (folds seeded by that mask's seed), and the choice is reused on the
cell's other masks; ``Ours`` makes its own choices on every fit, from the observed entries only.
Ground truth is used for the scores alone.

Input and metric. Every method is given the masked matrix with each column standardised by its
observed entries' mean and sd (what a user can do without ground truth), and its completion is mapped
back. ``rmse`` is the root mean squared error over the hidden entries in the units of each column's
full-data sd; ``sse`` is Table 2's error, the sum of squared errors over the whole matrix in the
data's units. Per mask the methods are ranked by ``rmse`` (1 = best, ties share the mean rank).

CPU seconds (``time.process_time``; the pipeline pins BLAS to one thread) of every fit and of every
tuning are returned as arrays (``cpu_seconds`` beside the rows, ``tune_cpu_seconds`` per method), not in
the rows: the run files and the table are the same on every rerun.
"""

from __future__ import annotations

import time
from collections.abc import Mapping

import numpy as np
import pandas as pd
from sklearn.base import clone
from sklearn.impute import SimpleImputer

from .._baselines._masked import observed_standardisation
from ..datasets import load_oil
from ..impute._grids import baseline_grid
from ..model_selection import HoldoutSearch
from ._missingness import draw_mask
from .base import Experiment, Job, JobOutput, summary_stats

__all__ = [
    "Benchmark",
    "METHODS",
    "SKLEARN_SETS",
    "load_dataset",
    "make_estimators",
    "run_cell",
    "ranks",
    "summarise",
]

#: every method the benchmark knows, in table order
METHODS = ("Ours", "missForest", "GP-LVM", "KNNImputer", "IterativeImputer", "SoftImpute", "mean")
#: scikit-learn's bundled data sets (``sklearn.datasets.load_<name>``, no download)
SKLEARN_SETS = ("wine", "breast_cancer", "diabetes", "digits")
#: methods whose knobs HoldoutSearch chooses (names of baseline_grid)
_TUNED = ("missForest", "GP-LVM", "KNNImputer", "SoftImpute")


def load_dataset(spec: Mapping, data_dir, subsample_seed: int) -> np.ndarray:
    """The complete matrix of one ``datasets`` entry (without its ``name``), shape (n, d).

    ``spec["source"]`` is ``"oil"`` (the first ``n_rows`` oil-flow training rows, as Table 2) or one of
    :data:`SKLEARN_SETS`; for those, ``n_rows`` below the set's size draws that many rows without
    replacement (``numpy.random.default_rng(subsample_seed)``, kept in their original order). For
    digits, ``pool`` (2 or 4) replaces each image by the means of its pool x pool pixel blocks. Columns
    constant over the chosen rows are dropped (no method can be scored on them; digits has some).
    """
    source, n_rows = spec["source"], spec.get("n_rows")
    if source == "oil":
        X = load_oil("train", data_dir)[0]
        X = X if n_rows is None else X[:n_rows]
    elif source in SKLEARN_SETS:
        from sklearn import datasets

        X = np.asarray(getattr(datasets, f"load_{source}")().data, dtype=np.float64)
        pool = spec.get("pool", 1)
        if source == "digits" and pool > 1:  # 8 x 8 images -> (8 / pool)^2 block means
            side = 8 // pool
            X = X.reshape(-1, side, pool, side, pool).mean(axis=(2, 4)).reshape(-1, side * side)
        if n_rows is not None and n_rows < X.shape[0]:
            rows = np.sort(np.random.default_rng(subsample_seed).choice(X.shape[0], n_rows, replace=False))
            X = X[rows]
    else:
        raise ValueError(
            f"datasets: source must be 'oil' or one of {', '.join(SKLEARN_SETS)}; got {source!r}"
        )
    return X[:, X.std(axis=0) > 0]


def _gplvm():
    from ..impute._gplvm import GPLVMImputer

    return GPLVMImputer()


def make_estimators(methods, W, grids: Mapping | None = None) -> dict:
    """method -> (unfitted estimator, param grid) for the masked, standardised matrix W (NaN missing).

    ``grids`` (method -> grid) replaces :func:`~nldr.impute._grids.baseline_grid`'s grid of a method.
    """
    from ..impute import KernelRegularizerImputer

    grids = grids or {}
    out = {}
    for method in methods:
        if method == "Ours":
            out[method] = (KernelRegularizerImputer(), {})
        elif method == "mean":
            out[method] = (SimpleImputer(strategy="mean"), {})
        elif method in METHODS:
            estimator, grid = baseline_grid(method, W)
            out[method] = (estimator, dict(grids.get(method, grid)))
        else:
            raise ValueError(f"benchmark.methods: unknown method {method!r}; choose from {METHODS}")
    return out


def _standardise(W: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    mask = ~np.isnan(W)
    mean, sd = observed_standardisation(np.where(mask, W, 0.0), mask)
    return (W - mean) / sd, mean, sd


def _cpu(fn):
    start = time.process_time()
    out = fn()
    return out, time.process_time() - start


def run_cell(
    X, *, mechanism: str, p: float, seed: int, n_masks: int, methods, settings: Mapping, progress=None
):
    """Every method on ``n_masks`` masks of X under one mechanism (the module docstring's protocol).

    Returns
    -------
    rows : DataFrame, one row per (mask, method): ``mask, seed, method, rmse, sse, rank, n_hidden,
        params`` (the knob chosen on the first mask)
    arrays : dict with ``cpu_seconds`` (one per row), ``tune_methods`` and ``tune_cpu_seconds``
    """
    say = progress or (lambda line: None)
    scale = X.std(axis=0)
    rows, seconds, chosen, tune_seconds = [], [], {}, {}
    for k in range(n_masks):
        mask = draw_mask(X, mechanism, p, seed + k, slope=settings.get("slope", 2.0))
        Z, mean, sd = _standardise(np.where(mask, X, np.nan))
        estimators = make_estimators(methods, Z, settings.get("grids"))
        for method, (estimator, grid) in estimators.items():
            if k == 0:
                if grid:
                    search = HoldoutSearch(
                        estimator, grid, n_folds=settings["n_folds"], random_state=seed, refit=False
                    )
                    _, tune_seconds[method] = _cpu(lambda s=search, Z=Z: s.fit(Z))
                    chosen[method] = dict(search.best_params_)
                else:
                    chosen[method], tune_seconds[method] = {}, 0.0
            fitted = clone(estimator).set_params(**chosen[method])
            Z_hat, cpu = _cpu(lambda f=fitted, Z=Z: f.fit_transform(Z))
            X_hat = np.asarray(Z_hat) * sd + mean
            if not np.all(np.isfinite(X_hat)):
                raise FloatingPointError(f"{method} returned non-finite values ({mechanism} p={p} mask {k})")
            hidden = ~mask
            err = (X_hat - X) / scale
            rows.append(
                {
                    "mask": k,
                    "seed": seed + k,
                    "method": method,
                    "rmse": float(np.sqrt(np.mean(err[hidden] ** 2))),
                    "sse": float(np.sum((X_hat - X) ** 2)),
                    "n_hidden": int(hidden.sum()),
                    "params": repr(chosen[method]),
                }
            )
            seconds.append(cpu)
            say(f"{mechanism} p={p:g} mask {k} {method:16s} rmse={rows[-1]['rmse']:.4f} cpu {cpu:.2f}s")
    frame = pd.DataFrame(rows)
    frame["rank"] = frame.groupby("mask")["rmse"].rank(method="average")
    arrays = {
        "cpu_seconds": np.asarray(seconds, dtype=float),
        "tune_methods": np.asarray(list(tune_seconds), dtype=str),
        "tune_cpu_seconds": np.asarray(list(tune_seconds.values()), dtype=float),
    }
    return frame, arrays


def ranks(runs: pd.DataFrame) -> pd.DataFrame:
    """Per cell and method: mean RMSE and mean rank over the masks, and whether it won the cell (lowest
    mean RMSE; a tie shares the win). Columns ``dataset, mechanism, cell, method, rmse, rank, win``."""
    cells = runs.groupby(["dataset", "mechanism", "cell", "method"], sort=False)[["rmse", "rank"]].mean()
    cells = cells.reset_index()
    best = cells.groupby("cell")["rmse"].transform("min")
    cells["win"] = (cells["rmse"] <= best).astype(float)
    return cells


def _order(methods) -> list[str]:
    present = list(dict.fromkeys(methods))
    return [m for m in METHODS if m in present] + [m for m in present if m not in METHODS]


def summarise(runs: pd.DataFrame) -> pd.DataFrame:
    """The benchmark's tidy rows (setting, method, metric, value).

    Per cell (setting ``<dataset> <mechanism>``): ``rmse`` (mean, ``rmse_sd`` over masks), ``sse``
    (likewise), ``rank`` (mean over masks), ``wins`` (masks where the method had the lowest RMSE, a
    tie counted for each) and ``n_masks``. Then the summary settings ``all``, ``dataset=<name>`` and
    ``mechanism=<name>``: ``mean_rank`` (the mean over their cells of the cell's mean rank) and
    ``wins`` (cells where the method had the lowest mean RMSE).
    """
    out = []
    order = _order(runs["method"])
    best = runs.groupby(["cell", "mask"])["rmse"].transform("min")
    runs = runs.assign(win=(runs["rmse"] <= best).astype(float))
    for cell, group in runs.groupby("cell", sort=False):
        for method in order:
            g = group[group["method"] == method]
            if g.empty:
                continue
            stats = {
                **summary_stats(g["rmse"], "rmse"),
                **summary_stats(g["sse"], "sse"),
                "rank": float(g["rank"].mean()),
                "wins": float(g["win"].sum()),
                "n_masks": float(len(g)),
            }
            out += [(cell, method, metric, float(value)) for metric, value in stats.items()]
    cells = ranks(runs)
    groups = [("all", cells)]
    groups += [(f"dataset={d}", g) for d, g in cells.groupby("dataset", sort=False)]
    groups += [(f"mechanism={m}", g) for m, g in cells.groupby("mechanism", sort=False)]
    for setting, g in groups:
        for method in order:
            gm = g[g["method"] == method]
            if gm.empty:
                continue
            out.append((setting, method, "mean_rank", float(gm["rank"].mean())))
            out.append((setting, method, "wins", float(gm["win"].sum())))
    return pd.DataFrame(out, columns=["setting", "method", "metric", "value"])


class Benchmark(Experiment):
    """The regularizer's defaults against the peers on six data sets and three mechanisms."""

    name = "benchmark"
    title = "Imputation benchmark beyond oil flow: our defaults against tuned peers, MCAR, MAR and MNAR"
    notebook = "benchmark"
    figures = ("benchmark_ranks",)
    render = {"digits": 3, "metrics": ["rmse", "mean_rank"], "transpose": True}
    enumerates = ("datasets", "missingness", "n_masks", "seed")
    figure_captions = {
        "benchmark_ranks": "Benchmark (not in the paper): left, each method's RMSE per cell relative to the "
        "best method of the cell (1 = best; mean over the masks); right, each method's mean rank over "
        "all cells."
    }

    def jobs(self, config):
        s = self.settings(config)
        jobs = []
        names = [spec["name"] for spec in s["datasets"]]
        if len(set(names)) < len(names):
            raise ValueError(f"benchmark.datasets: two data sets share a name in {names}")
        for entry in s["datasets"]:
            dataset, spec = entry["name"], {k: v for k, v in entry.items() if k != "name"}
            for cell in s["missingness"]:
                mech, p = cell["mechanism"], float(cell["p"])
                if mech in spec.get("skip_mechanisms", []):
                    continue
                params = {"dataset": dataset, "spec": dict(spec), "mechanism": mech, "p": p}
                params.update({"seed": s["seed"], "n_masks": s["n_masks"]})
                jobs.append(Job(f"{dataset}_{mech}{p:g}", params))
        return jobs

    def data_files(self, config, job=None):
        sets = self.settings(config)["datasets"] if job is None else [job.params["spec"]]
        return ["oil/DataTrn.txt", "oil/DataTrnLbls.txt"] if any(s["source"] == "oil" for s in sets) else []

    def resources(self, config, job):
        return {"mem_mb": 2000, "runtime": 60}

    def run(self, job, settings, data_dir, *, progress=None, threads=1):
        P = job.params
        X = load_dataset(P["spec"], data_dir, settings["subsample_seed"])
        rows, arrays = run_cell(
            X,
            mechanism=P["mechanism"],
            p=P["p"],
            seed=P["seed"],
            n_masks=P["n_masks"],
            methods=settings["methods"],
            settings=settings,
            progress=progress,
        )
        cell = f"{P['dataset']} {P['mechanism']} p={P['p']:g}"
        rows.insert(0, "cell", cell)
        rows.insert(0, "p", P["p"])
        rows.insert(0, "mechanism", P["mechanism"])
        rows.insert(0, "dataset", P["dataset"])
        rows.insert(4, "n_rows", X.shape[0])
        rows.insert(5, "n_cols", X.shape[1])
        return JobOutput(rows=rows, arrays=arrays)

    def summarise(self, runs):
        return summarise(runs)

    def caption(self, config):
        s = self.settings(config)
        sets = ", ".join(
            f"{spec['name']} ({spec['source']}"
            + (f", {spec['n_rows']} rows" if spec.get("n_rows") else "")
            + (f", {spec['pool']} x {spec['pool']} pixel blocks" if spec.get("pool", 1) > 1 else "")
            + ")"
            for spec in s["datasets"]
        )
        return (
            f"Benchmark (not in the paper): RMSE of the hidden entries in units of each column's sd, mean ± "
            f"sd over {s['n_masks']} seeded masks per cell, and mean rank over the cells (1 = best). Data "
            f"sets: {sets}; sklearn rows drawn with seed {s['subsample_seed']}. Ours: "
            "KernelRegularizerImputer() with no arguments. Peers' knobs by "
            f"{s['n_folds']}-fold hold-out CV on the observed entries of each cell's first mask, reused on "
            "its other masks; missForest with 100 trees. Every method sees the columns standardised by "
            "their observed entries."
        )

    def draw(self, figure, runs, arrays, data_dir):
        if figure != "benchmark_ranks":
            return super().draw(figure, runs, arrays, data_dir)
        return benchmark_figure(ranks(runs), _order(runs["method"]))


def benchmark_figure(cells: pd.DataFrame, methods):
    """Two panels from :func:`ranks`' frame: the heat map of each method's mean RMSE over the best
    method's per cell (methods x cells, log colour scale), and each method's mean rank over the cells."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm
    from matplotlib.ticker import ScalarFormatter

    order = list(dict.fromkeys(cells["cell"]))
    ratio = cells.assign(ratio=cells["rmse"] / cells.groupby("cell")["rmse"].transform("min"))
    grid = ratio.pivot(index="method", columns="cell", values="ratio").reindex(index=methods, columns=order)
    mean_rank = cells.groupby("method")["rank"].mean().reindex(methods)
    fig, (ax, bx) = plt.subplots(
        1,
        2,
        figsize=(max(8.0, 0.32 * len(order) + 4.0), 0.45 * len(methods) + 3.4),
        gridspec_kw={"width_ratios": [max(3.0, 0.32 * len(order)), 1.6]},
    )
    top = max(float(np.nanmax(grid.to_numpy())), 1.01)
    image = ax.imshow(grid.to_numpy(), aspect="auto", cmap="viridis_r", norm=LogNorm(1.0, top))
    for (i, j), value in np.ndenumerate(grid.to_numpy()):
        if np.isfinite(value):
            ax.text(
                j, i, f"{value:.2f}", ha="center", va="center", fontsize=5, color="w" if value > 1.2 else "k"
            )
    ax.set_yticks(range(len(methods)), methods)
    ax.set_xticks(range(len(order)), order, rotation=75, ha="right", fontsize=7)
    ax.set_title("RMSE / best RMSE of the cell")
    bar = fig.colorbar(image, ax=ax, fraction=0.03, pad=0.01)
    bar.ax.yaxis.set_major_formatter(ScalarFormatter())
    bar.ax.yaxis.set_minor_formatter(ScalarFormatter())
    bx.barh(range(len(methods)), mean_rank.to_numpy(), color="0.45")
    bx.set_yticks(range(len(methods)), [])
    bx.invert_yaxis()
    bx.set_xlabel("mean rank (1 = best)")
    bx.set_title("over all cells")
    fig.tight_layout()
    return fig
