"""Table 2: matrix completion on oil flow, the regularizer against five baselines (and, not in the
paper, against the imputers people use).

One run = one missing probability p and one seeded mask; every method is an imputer of
:mod:`nldr.impute` (the mean: scikit-learn's ``SimpleImputer``) with the paper's settings written out
in the config (:func:`paper_methods`), and completes the same masked matrix (NaN where missing),
starting (where it iterates) from mean imputation. The error is the sum of squared errors over the
whole n x d matrix (docs/REPRODUCTION.md#table-2-error explains why not the root mean square).

The peers follow the paper's rows: scikit-learn's KNNImputer and IterativeImputer,
missForest and SoftImpute, each with its knob chosen by :class:`~nldr.model_selection.HoldoutSearch`
on the observed entries of the same mask (:func:`run_peers`); the config can restrict a costly peer to
the first masks of each p.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping

import numpy as np
import pandas as pd
from sklearn.base import clone
from sklearn.impute import SimpleImputer

from .. import paper as paper_numbers
from .._validation import as_float_matrix
from ..datasets import load_oil, load_oil_rows
from ..impute._grids import MISSFOREST_TREES, baseline_grid
from ..model_selection import HoldoutSearch
from .base import Experiment, Job, JobOutput, summary_stats

__all__ = [
    "METHODS",
    "PEERS",
    "PEER_ROWS",
    "peer_label",
    "random_mask",
    "paper_methods",
    "run_mask",
    "run_peers",
    "summarise",
    "Table2",
    "Table2Full",
    "Table2All",
]

# Paper order; "Ours" is the regularizer of Algorithm 1 with the masked least-squares data term.
METHODS = ("mean", "1-NN", "PPCA", "PKPCA", "RKPCA", "Ours")
#: The peers (not in the paper), names of :func:`nldr.impute._grids.baseline_grid`.
PEERS = ("KNNImputer", "IterativeImputer", "SoftImpute", "missForest")
#: Their rows, in this order after the paper's: "(CV)" where a knob was chosen by CV (IterativeImputer
#: has none); missForest's label names its trees when they are not its recommended 100
#: (:func:`peer_label`; the paper-protocol tables run 10).
PEER_ROWS = (
    "KNNImputer (CV)",
    "IterativeImputer",
    "SoftImpute (CV)",
    "missForest (CV)",
    "missForest (10 trees, CV)",
)


def peer_label(method: str, tuned: bool, n_trees: int = MISSFOREST_TREES) -> str:
    """A peer's row label: ``"<method> (CV)"`` when a knob was chosen by CV, and for missForest with
    other than :data:`~nldr.impute._grids.MISSFOREST_TREES` trees, ``"missForest (<k> trees,
    CV)"``."""
    if method == "missForest" and n_trees != MISSFOREST_TREES:
        return f"missForest ({n_trees} trees, CV)"
    return f"{method} (CV)" if tuned else method


def random_mask(shape: tuple[int, int], p: float, seed: int) -> np.ndarray:
    """Observation mask (True = observed): each entry is removed independently with probability p.

    A column left with no observed entry cannot be imputed by any method; such draws are redrawn
    from the same generator (for 100 x 12 at p <= 0.5 this has probability below 1e-29).
    """
    if not 0.0 < p < 1.0:
        raise ValueError(f"p must lie in (0, 1); got {p}")
    rng = np.random.default_rng(seed)
    while True:
        mask = rng.random(shape) >= p
        if mask.any(axis=0).all():
            return mask


def paper_methods(settings: Mapping) -> dict:
    """Table 2's methods as estimators, with the paper's settings written out (config ``table2``).

    ``methods.<name>`` are the estimator's keyword arguments; the width ``gamma`` is the block's
    (PKPCA, RKPCA and Ours), and ``ours`` (e.g. a Nystroem kernel at scale) is laid over Ours's.
    """
    from ..impute import (
        KernelRegularizerImputer,
        NearestNeighbourImputer,
        PKPCAImputer,
        PPCAImputer,
        RKPCAImputer,
    )

    kwargs = {name: dict(values) for name, values in settings["methods"].items()}
    for name in ("PKPCA", "RKPCA", "Ours"):
        kwargs.setdefault(name, {}).setdefault("gamma", settings["gamma"])
    extra = dict(settings.get("ours", {}))  # e.g. table2_all's Nystroem kernel, laid over Ours's
    ours = {**kwargs["Ours"], **{k: v for k, v in extra.items() if k not in ("options", "schedule")}}
    ours.update(ours.pop("schedule", None) or {})  # the config's penalty schedule: rho0, rho_growth, rho_max
    options = {**(kwargs["Ours"].get("options") or {}), **(extra.get("options") or {})}  # merged key by key
    if ours.get("method", "auto") != "exact":
        options = {"landmark_seed": 0, **options}  # landmarks from a fixed seed
    ours["options"] = options or None
    return {
        "mean": SimpleImputer(strategy="mean"),
        "1-NN": NearestNeighbourImputer(**kwargs.get("1-NN", {})),
        "PPCA": PPCAImputer(**kwargs.get("PPCA", {})),
        "PKPCA": PKPCAImputer(**kwargs["PKPCA"]),
        "RKPCA": RKPCAImputer(**kwargs["RKPCA"]),
        "Ours": KernelRegularizerImputer(**ours),
    }


def _outcome(estimator) -> tuple[bool, int]:
    """(converged, iterations) of a fitted estimator's solve; (True, 0) for one without a solver."""
    result = getattr(estimator, "result_", None)
    return (True, 0) if result is None else (bool(result.success), int(result.nit))


def run_mask(
    X,
    *,
    p: float,
    seed: int,
    estimators: Mapping,
    progress: Callable[[str], None] | None = None,
) -> pd.DataFrame:
    """Complete one seeded mask of X with every estimator.

    Parameters
    ----------
    X : (n, d) the complete ground-truth matrix.
    p : missing probability per entry.
    seed : seed of the mask.
    estimators : method name -> unfitted imputer (NaN marks missing), e.g. :func:`paper_methods`.
    progress : optional callback receiving one line per finished method.

    Returns
    -------
    DataFrame with one row per method: ``p, seed, method, sse`` (NaN when the method is not
    available, as 1-NN without fully observed rows), ``available, converged, n_iter, seconds,
    n_missing``.
    """
    X = as_float_matrix(X, "X")
    mask = random_mask(X.shape, p, seed)
    W = np.where(mask, X, np.nan)
    rows = []
    for method, estimator in estimators.items():
        start = time.perf_counter()
        fitted = clone(estimator)
        # the paper's NA: 1-NN has no donor without a fully observed row (its estimator refuses)
        X_hat = fitted.fit_transform(W) if method != "1-NN" or mask.all(axis=1).any() else None
        seconds = time.perf_counter() - start
        available = X_hat is not None
        sse = float(np.sum((X_hat - X) ** 2)) if available else np.nan
        if available and not np.isfinite(sse):
            raise FloatingPointError(f"{method} returned non-finite values (p={p}, seed={seed})")
        converged, n_iter = _outcome(fitted) if available else (True, 0)
        rows.append(
            {
                "p": p,
                "seed": seed,
                "method": method,
                "sse": sse,
                "available": available,
                "converged": converged,
                "n_iter": n_iter,
                "seconds": seconds,
                "n_missing": int((~mask).sum()),
            }
        )
        if progress is not None:
            progress(f"p={p} seed={seed} {method:6s} sse={sse:9.3f} {seconds:6.2f}s converged={converged}")
    return pd.DataFrame(rows)


def run_peers(
    X,
    *,
    p: float,
    seed: int,
    methods=PEERS,
    n_folds: int = 5,
    n_trees: int = MISSFOREST_TREES,
    progress: Callable[[str], None] | None = None,
) -> pd.DataFrame:
    """Complete the mask of :func:`run_mask` (same p and seed) with each peer, its knob chosen by
    :class:`~nldr.model_selection.HoldoutSearch` over :func:`~nldr.impute._grids.baseline_grid` on
    the observed entries (folds seeded by the mask's seed; a peer without a knob is fitted once).

    Parameters
    ----------
    X : (n, d) the complete ground-truth matrix.
    p, seed : the mask's missing probability and seed (also the seed of the CV folds).
    methods : which of :data:`PEERS`.
    n_folds : hold-out folds of the observed entries.
    n_trees : missForest's trees per column (its label names them when not 100, :func:`peer_label`).
    progress : optional callback receiving one line per finished method.

    Returns
    -------
    DataFrame with :func:`run_mask`'s columns (``seconds``: CV and refit) and ``params``, the chosen knob.
    """
    X = as_float_matrix(X, "X")
    unknown = set(methods) - set(PEERS)
    if unknown:
        raise ValueError(f"unknown peers {sorted(unknown)}; choose from {PEERS}")
    mask = random_mask(X.shape, p, seed)
    W = np.where(mask, X, np.nan)
    rows = []
    for method in methods:
        start = time.perf_counter()
        # the data's units, as the paper's rows (oil flow's columns share one unit)
        estimator, grid = baseline_grid(method, W, n_trees=n_trees, standardize=False)
        label = peer_label(method, bool(grid), n_trees)
        if grid:
            search = HoldoutSearch(estimator, grid, n_folds=n_folds, random_state=seed)
            X_hat, fitted = search.fit_transform(W), search.best_estimator_
            params = repr(search.best_params_)
        else:
            fitted = clone(estimator)
            X_hat, params = fitted.fit_transform(W), "{}"
        seconds = time.perf_counter() - start
        sse = float(np.sum((X_hat - X) ** 2))
        if not np.isfinite(sse):
            raise FloatingPointError(f"{method} returned non-finite values (p={p}, seed={seed})")
        converged, n_iter = _outcome(fitted)
        rows.append(
            {
                "p": p,
                "seed": seed,
                "method": label,
                "sse": sse,
                "available": True,
                "converged": converged,
                "n_iter": n_iter,
                "seconds": seconds,
                "n_missing": int((~mask).sum()),
                "params": params,
            }
        )
        if progress is not None:
            progress(f"p={p} seed={seed} {label:16s} sse={sse:9.3f} {seconds:6.2f}s {params}")
    return pd.DataFrame(rows)


def summarise(runs: pd.DataFrame) -> pd.DataFrame:
    """Aggregate :func:`run_mask` frames into Table 2's tidy rows (setting, method, metric, value).

    Per p and method: mean and sample standard deviation of the SSE over the masks where the method was
    available (NaN, the paper's NA, when it never was), the number of such masks and the fraction of
    runs that converged. Timings stay in the run frames: a table must not change between reruns.
    """
    rows = []
    for p in sorted(runs["p"].unique()):
        known = list(METHODS + PEER_ROWS)
        present = list(dict.fromkeys(runs["method"]))  # e.g. "Ours (Nystroem 300)" after Ours's place
        order = [m for m in known if m in present] + [m for m in present if m not in known]
        order.sort(key=lambda m: known.index(m) if m in known else known.index("Ours") + 0.5)
        for method in order:
            group = runs[(runs["p"] == p) & (runs["method"] == method)]
            ok = group[group["available"]]
            stats = {
                **summary_stats(ok["sse"], "sse"),
                "n_masks": float(len(ok)),
                "converged_frac": float(group["converged"].mean()),
            }
            for metric, value in stats.items():
                rows.append((f"p={p:g}", method, metric, float(value)))
    return pd.DataFrame(rows, columns=["setting", "method", "metric", "value"])


_PEER_WORDS = {
    "KNNImputer": "scikit-learn's KNNImputer (neighbours, weights)",
    "IterativeImputer": "IterativeImputer with BayesianRidge (no knob, fitted once)",
    "SoftImpute": "SoftImpute, nuclear-norm completion (lambda)",
    "missForest": "missForest, IterativeImputer with extra trees (max_features)",
}


def _peer_words(method: str, peers: Mapping) -> str:
    words = _PEER_WORDS[method]
    trees = peers.get("missforest_trees", MISSFOREST_TREES)
    if method == "missForest" and trees != MISSFOREST_TREES:
        words += f", {trees} trees per column (its authors recommend {MISSFOREST_TREES})"
    return words


def peers_caption(settings: Mapping) -> str:
    """The caption's sentence on the peers' rows (empty without peers)."""
    peers = settings["peers"]
    if not peers["methods"]:
        return ""
    names = "; ".join(_peer_words(m, peers) for m in peers["methods"])
    limits = [
        f"{m} on the first {k} masks per p only (its CV is the costly part)"
        for m, k in peers.get("masks", {}).items()
        if m in peers["methods"] and k < settings["n_masks"]
    ]
    return (
        f" Rows after Ours are not in the paper: {names}; each knob chosen by {peers['n_folds']}-fold "
        "hold-out CV on the observed entries of the same mask"
        + (f"; {'; '.join(limits)}" if limits else "")
        + "."
    )


class Table2(Experiment):
    """Table 2: completion of the first oil-flow training rows, the regularizer against five baselines
    (and the peers, not in the paper)."""

    name = "table2"
    title = "Matrix completion on oil flow: the regularizer against five baselines"
    in_paper = True
    paper = paper_numbers.TABLE2
    notebook = "table2_completion"
    render = {"digits": 3, "metrics": ["sse"], "transpose": True}
    enumerates = ("p", "n_masks", "seed", "masks_per_job")

    def jobs(self, config):
        """One job per p and run of ``masks_per_job`` consecutive masks (default 1): at 100 rows a mask
        costs less arithmetic than a job's Python start-up (measured: docs/PERFORMANCE.md#pipeline), so
        the paper's protocol groups its 50 masks per p into a few jobs. A single-mask job is named
        ``p0.05_seed2016``, a group ``p0.05_seeds2016-2025``; the masks and their seeds are the same
        however they are grouped, so the table does not depend on the grouping."""
        s = self.settings(config)
        per = s.get("masks_per_job", 1)
        jobs = []
        for p in s["p"]:
            for first in range(0, s["n_masks"], per):
                count = min(per, s["n_masks"] - first)
                seed = s["seed"] + first
                name = f"p{p:g}_seed{seed}" if count == 1 else f"p{p:g}_seeds{seed}-{seed + count - 1}"
                jobs.append(Job(name, {"p": p, "seed": seed, "mask": first, "count": count}))
        return jobs

    def data_files(self, config, job=None):
        return ["oil/DataTrn.txt", "oil/DataTrnLbls.txt"]

    def resources(self, config, job):
        return {"mem_mb": 1000, "runtime": 20 * job.params.get("count", 1)}

    def load(self, settings, data_dir) -> np.ndarray:
        """The complete matrix (n_rows, 12): the first ``n_rows`` oil-flow training rows."""
        return load_oil("train", data_dir)[0][: settings["n_rows"]]

    def run(self, job, settings, data_dir, *, progress=None, threads=1):
        X = self.load(settings, data_dir)
        count = job.params.get("count", 1)
        frames = []
        for k in range(count):  # the job's masks, each exactly as a single-mask job would run it
            p, seed, mask = job.params["p"], job.params["seed"] + k, job.params["mask"] + k
            frames.append(self._run_mask(X, p, seed, mask, settings, progress))
            if progress is not None and count > 1:
                progress(f"p={p} mask {k + 1} of {count} done")
        return JobOutput(rows=pd.concat(frames, ignore_index=True))

    def _run_mask(self, X, p, seed, mask, settings, progress):
        """Every method (and every peer this mask runs) on mask number ``mask`` (seed ``seed``)."""
        skip = set(settings.get("skip", []))
        estimators = {m: e for m, e in paper_methods(settings).items() if m not in skip}
        rows = run_mask(X, p=p, seed=seed, estimators=estimators, progress=progress)
        landmarks = settings.get("ours", {}).get("n_landmarks")
        if landmarks is not None:  # not the exact solve: the label says so wherever the row appears
            rows["method"] = rows["method"].replace("Ours", f"Ours (Nystroem {landmarks})")
        peers = settings["peers"]
        limits = peers.get("masks", {})
        chosen = [m for m in peers["methods"] if mask < limits.get(m, mask + 1)]
        if chosen:
            more = run_peers(
                X,
                p=p,
                seed=seed,
                methods=chosen,
                n_folds=peers["n_folds"],
                n_trees=peers.get("missforest_trees", MISSFOREST_TREES),
                progress=progress,
            )
            rows = pd.concat([rows, more], ignore_index=True)
        return rows

    def summarise(self, runs):
        return summarise(runs)

    def caption(self, config):
        s = self.settings(config)
        return (
            f"Table 2: oil-flow completion (first {s['n_rows']} training rows), sum of squared errors over "
            f"the whole matrix, mean ± sd over {s['n_masks']} seeded masks per p; paper in parentheses, "
            "– where not available." + peers_caption(s)
        )


class Table2Full(Table2):
    """Table 2's protocol on more oil-flow rows (not in the paper; speed and scale)."""

    name = "table2_full"
    title = "Table 2 on more oil-flow rows (not in the paper)"
    in_paper = False
    paper = None
    notebook = None
    inherits = "table2"

    def resources(self, config, job):
        return {"mem_mb": 2000, "runtime": 60 * job.params.get("count", 1)}

    def caption(self, config):
        s = self.settings(config)
        return (
            f"Table 2 on {s['n_rows']} oil-flow training rows (not in the paper, which uses the first "
            f"{config['table2']['n_rows']}): sum of squared errors over the whole matrix, mean ± sd over "
            f"{s['n_masks']} seeded masks per p." + peers_caption(s)
        )


class Table2All(Table2Full):
    """Table 2's protocol on all 3000 oil-flow rows, training, validation and test (not in the paper)."""

    name = "table2_all"
    title = "Table 2 on all 3000 oil-flow rows (not in the paper)"

    def data_files(self, config, job=None):
        return [f"oil/Data{s}{kind}.txt" for s in ("Trn", "Vdn", "Tst") for kind in ("", "Lbls")]

    def load(self, settings, data_dir) -> np.ndarray:
        """The first ``n_rows`` of the training, then validation, then test rows (3000 x 12 in all)."""
        return load_oil_rows(settings["n_rows"], data_dir)

    def resources(self, config, job):
        return {"mem_mb": 4000, "runtime": 120 * job.params.get("count", 1)}

    def caption(self, config):
        s = self.settings(config)
        landmarks = s.get("ours", {}).get("n_landmarks")
        how = (
            f" Ours (Nystroem {landmarks}) is the regularizer on the Nystroem approximation of the "
            f"kernel ({landmarks} landmark samples, "
            "minimize_regularized(method='nystroem'), opt-in; not the exact solve, see docs/PERFORMANCE.md)."
            if landmarks is not None
            else ""
        )
        if s.get("skip"):
            how += f" Not run at this size (CPU cost): {', '.join(s['skip'])}."
        return (
            f"Table 2 on {s['n_rows']} oil-flow rows, the training, validation and test files together "
            f"(not in the paper): sum of squared errors over the whole matrix, mean ± sd over {s['n_masks']} "
            "seeded masks per p." + how + peers_caption(s)
        )
