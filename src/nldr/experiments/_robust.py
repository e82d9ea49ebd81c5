"""Robust (not in the paper): completion and denoising of oil flow with sparse gross errors.

The paper's closing remark, that its framework "could trivially incorporate robust functions like the L1
norm", built and measured. The first ``n_rows`` oil-flow training rows are the clean matrix X. One job
is one missing probability p (p = 0: nothing missing) and one seed: the seed's mask (Table 2's
:func:`~nldr.experiments._table2.random_mask`), then, for every corruption share c, that share of the
observed entries gets a gross error (:func:`gross_corruption`; the shares are nested, so the 5 %
outliers of a seed are among its 10 %). Each method sees only the corrupted observed entries; every
knob is chosen by hold-out CV on them, scored by the absolute error per hidden entry (the hidden
entries are corrupted too: a squared score would be ruled by the outliers among them, which nothing
can predict). Rows, per (c, job):

Every search is :class:`nldr.model_selection.HoldoutSearch`:

- ``Ours (LS)``: the regularizer with masked least squares (:class:`nldr.impute.KernelRegularizerImputer`
  in the data's units) over (tau, gamma), smallest mean error;
- ``Ours (Huber)``: the regularizer with :class:`nldr.data_terms.MaskedHuber`
  (``KernelRegularizerImputer(loss="huber")``) over (tau, gamma), its tau paths warm-started as least
  squares' (without the early stop), delta by the robust-scale rule
  (:class:`~nldr.model_selection.RobustScaleDelta`: 1.345 x the MAD scale of the least-squares
  residuals at the same tau and gamma, on each fit's own training entries);
- ``RPCA``: principal component pursuit (:class:`nldr.impute.RobustPCAImputer`), its weight lam as a
  multiple of Candes et al.'s;
- ``SoftImpute``: its low-rank fit Z + mu on every entry (the imputed matrix would return the outliers
  unchanged), its lam on the grid of :func:`~nldr.impute._grids.baseline_grid`;
- ``KNNImputer``: scikit-learn's, which fills missing entries and keeps the observed ones (with their
  outliers): what an imputer does with corrupted data.

The metric is the sum of squared errors against the clean X over all n x d entries.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from ..datasets import load_oil
from ..impute import KernelRegularizerImputer
from ..impute._grids import baseline_grid
from ..model_selection import HoldoutSearch, RobustScaleDelta, median_gamma
from ._table2 import random_mask
from .base import Experiment, Job, JobOutput, summary_stats

__all__ = ["Robust", "METHODS", "gross_corruption"]

#: Row order of the table.
METHODS = ("Ours (LS)", "Ours (Huber)", "RPCA", "SoftImpute", "KNNImputer")
#: The regularizer's fold solves: looser tolerances than the refit's (they only rank candidates).
FOLD_TOLERANCES = {"tol": 1e-7, "gtol": 1e-4}


def _words(params) -> str:
    """The regularizer's chosen parameters as the table's ``params`` column writes them."""
    return ", ".join(f"{key}={params[key]:.3g}" for key in ("tau", "gamma", "delta") if key in params)


def gross_corruption(X, mask, shares, seed: int, *, low: float = 3.0, high: float = 6.0) -> dict:
    """Corrupted copies of X: for each share c, that share of the observed entries get a gross error.

    The observed entries are shuffled once by ``seed``; share c corrupts the first round(c m) of them
    (nested sets). Entry (i, j) becomes ``X_ij + s a sd_j``, s a random sign, a uniform on [low, high],
    sd_j the standard deviation of column j of X (the same s and a for an entry at every share).

    Parameters
    ----------
    X : array, shape (n, d)
    mask : bool array, shape (n, d); True where observed (only those entries are corrupted).
    shares : sequence of float in [0, 1)
    seed : int
    low, high : float, 0 < low <= high
        Range of the error in column standard deviations.

    Returns
    -------
    dict share -> (W, outliers): W (n, d) the corrupted matrix, outliers (n, d) bool the corrupted entries.
    """
    X = np.asarray(X, dtype=np.float64)
    mask = np.asarray(mask, dtype=bool)
    if not 0 < low <= high:
        raise ValueError(f"low and high must satisfy 0 < low <= high; got {low}, {high}")
    rng = np.random.default_rng(seed)
    order = rng.permutation(np.flatnonzero(mask.ravel()))
    error = rng.choice([-1.0, 1.0], size=order.size) * rng.uniform(low, high, size=order.size)
    sd = X.std(axis=0)
    out = {}
    for share in shares:
        if not 0.0 <= share < 1.0:
            raise ValueError(f"shares must lie in [0, 1); got {share}")
        k = int(round(share * order.size))
        W = X.copy().ravel()
        W[order[:k]] += error[:k] * sd[order[:k] % X.shape[1]]
        outliers = np.zeros(X.size, dtype=bool)
        outliers[order[:k]] = True
        out[share] = (W.reshape(X.shape), outliers.reshape(X.shape))
    return out


class Robust(Experiment):
    """Completion with gross errors: the regularizer with least squares and with Huber against linear
    Robust PCA, SoftImpute and KNNImputer, every knob by hold-out CV (not in the paper)."""

    name = "robust"
    title = "Robust completion: Huber data term against least squares, Robust PCA and imputers"
    in_paper = False
    notebook = "robust"
    render = {"digits": 2, "metrics": ["sse"], "transpose": False}
    enumerates = ("p", "corrupt", "n_seeds", "seed")

    def jobs(self, config):
        s = self.settings(config)
        return [
            Job(
                f"p{p:g}_seed{s['seed'] + k}",
                {"p": float(p), "seed": s["seed"] + k, "corrupt": list(s["corrupt"])},
            )
            for p in s["p"]
            for k in range(s["n_seeds"])
        ]

    def check(self, config):
        s = self.settings(config)
        if s["outlier_sd"]["low"] > s["outlier_sd"]["high"]:
            raise ValueError(f"robust.outlier_sd: low must not exceed high; got {s['outlier_sd']}")
        grid = s["grid"]["log10_tau"]
        if grid["min"] > grid["max"]:
            raise ValueError(f"robust.grid.log10_tau: min must not exceed max; got {grid}")
        return super().check(config)

    def data_files(self, config, job=None):
        return ["oil/DataTrn.txt", "oil/DataTrnLbls.txt"]

    def resources(self, config, job):
        return {"mem_mb": 1000, "runtime": 20}

    def run(self, job, settings, data_dir, *, progress=None, threads=1):
        say = progress or (lambda line: None)
        X, _ = load_oil("train", data_dir)
        X = X[: settings["n_rows"]]
        p, seed = float(job.params["p"]), int(job.params["seed"])
        mask = random_mask(X.shape, p, seed) if p > 0 else np.ones(X.shape, dtype=bool)
        shares = [float(c) for c in job.params["corrupt"]]
        sd = settings["outlier_sd"]
        corrupted = gross_corruption(X, mask, shares, seed, low=sd["low"], high=sd["high"])
        grid = settings["grid"]
        taus = np.logspace(grid["log10_tau"]["min"], grid["log10_tau"]["max"], grid["log10_tau"]["num"])
        cv = {"n_folds": settings["n_folds"], "random_state": seed}  # the imputers' folds: partitions
        schedule = dict(settings["schedule"])
        rows, arrays = [], {"mask": mask}
        for c in shares:
            W, outliers = corrupted[c]
            W = np.where(mask, W, np.nan)
            gammas = np.asarray(grid["gamma_multiples"], dtype=float) * median_gamma(W, mask)

            def record(method, X_hat, seconds, params, c=c, outliers=outliers):
                sse = float(np.sum((X_hat - X) ** 2))
                rows.append(
                    {
                        "p": p,
                        "corrupt": c,
                        "seed": seed,
                        "method": method,
                        "sse": sse,
                        "seconds": seconds,
                        "n_outliers": int(outliers.sum()),
                        "params": params,
                    }
                )
                arrays[f"{method}_corrupt{c:g}"] = X_hat
                say(f"p={p:g} c={c:g} seed={seed} {method:13s} sse={sse:9.3f} {seconds:6.2f}s {params}")

            candidates = {"gamma": [float(g) for g in gammas], "tau": [float(t) for t in taus]}
            # the regularizer in the data's units with the block's schedule; the fold solves stop
            # earlier (they only rank), each tau path from the smallest tau up
            # denoise: the estimate of every entry (the outliers among the observed ones corrected)
            ours = KernelRegularizerImputer(standardize=False, method="exact", **schedule, denoise=True)
            search = {
                "n_folds": settings["n_folds"],
                "random_state": seed,
                "holdout": settings["holdout"],
                "scoring": "absolute",
            }
            start = time.perf_counter()
            folds = dict(FOLD_TOLERANCES)
            ls = HoldoutSearch(ours, candidates, path="tau", stop_factor=1.5, fold_params=folds, **search)
            X_hat = ls.fit_transform(W)
            record("Ours (LS)", X_hat, time.perf_counter() - start, _words(ls.best_params_))
            start = time.perf_counter()
            # the same estimator with the Huber loss, each fold's tau path warm-started the same way;
            # delta per fit from the least-squares fit's residuals at the same tau and gamma
            delta = RobustScaleDelta(settings["delta_factor"])
            huber = KernelRegularizerImputer(
                standardize=False, method="exact", **schedule, loss="huber", denoise=True
            )
            huber = HoldoutSearch(huber, candidates, path="tau", derive=delta, fold_params=folds, **search)
            X_hat = huber.fit_transform(W)
            chosen = {**huber.best_params_, "delta": huber.best_estimator_.delta}
            record("Ours (Huber)", X_hat, time.perf_counter() - start, _words(chosen))
            start = time.perf_counter()
            rpca, _ = baseline_grid("RPCA", W, standardize=False)  # the data's units, as Ours here
            rpca.set_params(denoise=True)  # its low-rank L on every entry, as the regularizer's S
            grid = {"lam_factor": list(settings["rpca_lam_factors"])}
            rpca = HoldoutSearch(rpca, grid, scoring="absolute", **cv)
            record("RPCA", rpca.fit_transform(W), time.perf_counter() - start, repr(rpca.best_params_))
            start = time.perf_counter()
            soft, grid = baseline_grid("SoftImpute", W, standardize=False)  # result_ in the data's units
            # its low-rank fit Z + mu on every entry: the imputed matrix would keep the outliers
            soft = HoldoutSearch(soft, grid, scoring="absolute", **cv).fit(W)
            fit = soft.best_estimator_.result_  # the hidden entries were scored on the same Z + mu
            seconds = time.perf_counter() - start
            record("SoftImpute", fit.Z + fit.column_means, seconds, repr(soft.best_params_))
            start = time.perf_counter()
            if p > 0:
                knn, grid = baseline_grid("KNNImputer", W)
                knn = HoldoutSearch(knn, grid, scoring="absolute", **cv)
                X_knn, params = knn.fit_transform(W), repr(knn.best_params_)
            else:  # nothing is missing: an imputer returns the data, outliers and all
                X_knn, params = W, "nothing to impute"
            record("KNNImputer", np.asarray(X_knn, dtype=float), time.perf_counter() - start, params)
        return JobOutput(rows=pd.DataFrame(rows), arrays=arrays)

    def summarise(self, runs):
        rows = []
        for p in sorted(runs["p"].unique()):
            for c in sorted(runs["corrupt"].unique()):
                for method in [m for m in METHODS if m in set(runs["method"])]:
                    group = runs[(runs["p"] == p) & (runs["corrupt"] == c) & (runs["method"] == method)]
                    if group.empty:
                        continue
                    stats = {**summary_stats(group["sse"], "sse"), "n_seeds": float(len(group))}
                    for metric, value in stats.items():
                        rows.append((f"corrupt={c:g},p={p:g}", method, metric, float(value)))
        return pd.DataFrame(rows, columns=["setting", "method", "metric", "value"])

    def caption(self, config):
        s = self.settings(config)
        shares = ", ".join(f"{c:.0%}" for c in s["corrupt"])
        return (
            f"Robust completion (not in the paper): the first {s['n_rows']} oil-flow training rows with "
            f"{shares} of the observed entries replaced by gross errors (± {s['outlier_sd']['low']:g}–"
            f"{s['outlier_sd']['high']:g} column standard deviations), missing probability "
            f"{', '.join(f'{p:g}' for p in s['p'])}; sum of squared errors against the clean matrix over "
            f"all entries, mean ± sd over {s['n_seeds']} seeds. Every knob by {s['n_folds']}-fold hold-out "
            "CV on the corrupted observed entries, scored by absolute error; the Huber threshold by the "
            "robust-scale rule (1.345 × MAD scale of the least-squares residuals). SoftImpute: its "
            "low-rank fit on every entry; KNNImputer keeps the observed entries (outliers included)."
        )
