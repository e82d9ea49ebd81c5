"""Table 2: matrix completion on oil flow, the regularizer against five baselines (and, not in the
paper, against the imputers people use).

One run = one missing probability p and one seeded mask; every method completes the same masked
matrix, starting (where it iterates) from mean imputation. The error is the sum of squared errors
over the whole n x d matrix (docs/REPRODUCTION.md#table-2-error explains why not the root mean square).

The peers (issue 16; :mod:`nldr.baselines.peers`) follow the paper's rows: scikit-learn's KNNImputer
and IterativeImputer, missForest and SoftImpute, each with its knob chosen by hold-out CV on the
observed entries of the same mask (:func:`fit_peer`); the config can restrict a costly peer to the
first masks of each p.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping

import numpy as np
import pandas as pd

from .. import paper as paper_numbers
from .._validation import as_float_matrix
from ..baselines import mean_impute, nearest_neighbour_impute, pkpca_impute, ppca_impute, rkpca_impute
from ..data_terms import MaskedLeastSquares
from ..datasets import load_oil, load_oil_rows
from ..model_selection import baseline_grid, select_imputer
from ..regularizer import minimize_regularized
from .base import Experiment, Job, JobOutput, summary_stats

__all__ = [
    "METHODS",
    "PEERS",
    "PEER_ROWS",
    "random_mask",
    "run_mask",
    "fit_peer",
    "run_peers",
    "summarise",
    "Table2",
    "Table2Full",
    "Table2All",
]

# Paper order; "Ours" is the regularizer of Algorithm 1 with the masked least-squares data term.
METHODS = ("mean", "1-NN", "PPCA", "PKPCA", "RKPCA", "Ours")
#: The peers (not in the paper), names of :func:`nldr.model_selection.baseline_grid`.
PEERS = ("KNNImputer", "IterativeImputer", "SoftImpute", "missForest")
#: Their rows, in this order after the paper's: "(CV)" where a knob was chosen by CV (IterativeImputer
#: has none).
PEER_ROWS = ("KNNImputer (CV)", "IterativeImputer", "SoftImpute (CV)", "missForest (CV)")


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


def _ours(W, mask, params):
    S0 = mean_impute(W, mask)
    res = minimize_regularized(MaskedLeastSquares(W, mask), S0, **params)
    return res.x, res.success, res.nit


def _mean(W, mask, params):
    return mean_impute(W, mask), True, 0


def _nn(W, mask, params):
    res = nearest_neighbour_impute(W, mask)
    return res.x, True, 0


def _ppca(W, mask, params):
    res = ppca_impute(W, mask, **params)
    return res.x, res.success, res.nit


def _pkpca(W, mask, params):
    res = pkpca_impute(W, mask, **params)
    return res.x, res.success, res.nit


def _rkpca(W, mask, params):
    res = rkpca_impute(W, mask, **params)
    return res.x, res.success, res.nit


_RUNNERS: dict[str, Callable] = {
    "mean": _mean,
    "1-NN": _nn,
    "PPCA": _ppca,
    "PKPCA": _pkpca,
    "RKPCA": _rkpca,
    "Ours": _ours,
}


def run_mask(
    X,
    *,
    p: float,
    seed: int,
    params: Mapping[str, Mapping] | None = None,
    methods=METHODS,
    progress: Callable[[str], None] | None = None,
) -> pd.DataFrame:
    """Complete one seeded mask of X with every method.

    Parameters
    ----------
    X : (n, d) the complete ground-truth matrix.
    p : missing probability per entry.
    seed : seed of the mask.
    params : per-method keyword arguments, e.g. ``{"Ours": {"gamma": 0.075, "tau": 0.1}}``.
    methods : which of :data:`METHODS` to run.
    progress : optional callback receiving one line per finished method.

    Returns
    -------
    DataFrame with one row per method: ``p, seed, method, sse`` (NaN when the method is not
    available, as 1-NN without fully observed rows), ``available, converged, n_iter, seconds,
    n_missing``.
    """
    X = as_float_matrix(X, "X")
    unknown = set(methods) - set(_RUNNERS)
    if unknown:
        raise ValueError(f"unknown methods {sorted(unknown)}; choose from {METHODS}")
    params = dict(params or {})
    mask = random_mask(X.shape, p, seed)
    W = np.where(mask, X, np.nan)
    rows = []
    for method in methods:
        start = time.perf_counter()
        X_hat, converged, n_iter = _RUNNERS[method](W, mask, dict(params.get(method, {})))
        seconds = time.perf_counter() - start
        available = X_hat is not None
        sse = float(np.sum((X_hat - X) ** 2)) if available else np.nan
        if available and not np.isfinite(sse):
            raise FloatingPointError(f"{method} returned non-finite values (p={p}, seed={seed})")
        rows.append(
            {
                "p": p,
                "seed": seed,
                "method": method,
                "sse": sse,
                "available": available,
                "converged": bool(converged),
                "n_iter": int(n_iter),
                "seconds": seconds,
                "n_missing": int((~mask).sum()),
            }
        )
        if progress is not None:
            progress(f"p={p} seed={seed} {method:6s} sse={sse:9.3f} {seconds:6.2f}s converged={converged}")
    return pd.DataFrame(rows)


def fit_peer(method: str, W, mask, *, n_folds: int, seed: int) -> dict:
    """Complete W with a method of :func:`nldr.model_selection.baseline_grid`, its knob by hold-out CV.

    Parameters
    ----------
    method : a name :func:`~nldr.model_selection.baseline_grid` knows (a peer or a baseline with a knob).
    W : array, shape (n, d), NaN (or anything) where ``mask`` is False.
    mask : bool array, shape (n, d), True where observed.
    n_folds : folds of :func:`~nldr.model_selection.select_imputer`.
    seed : seed of the folds (the mask's seed, so every method of a job sees the same folds).

    Returns
    -------
    dict with ``method`` (``"<method> (CV)"``, or the bare name when the grid has no knob: then the
    method is fitted once, without CV), ``x`` (the completed (n, d) matrix), ``converged``, ``n_iter``
    (the refit's, where the method reports them, else True and 0) and ``params`` (the chosen knob, repr).
    """
    impute, grid = baseline_grid(method, W, mask)
    if grid:
        chosen = select_imputer(impute, W, mask, grid, n_folds=n_folds, random_state=seed)
        output, label, params = chosen.result_, f"{method} (CV)", repr(chosen.best_params_)
    else:
        output, label, params = impute(np.where(mask, W, np.nan), mask), method, "{}"
    return {
        "method": label,
        "x": np.asarray(getattr(output, "x", output), dtype=np.float64),
        "converged": bool(getattr(output, "success", True)),
        "n_iter": int(getattr(output, "nit", 0)),
        "params": params,
    }


def run_peers(
    X,
    *,
    p: float,
    seed: int,
    methods=PEERS,
    n_folds: int = 5,
    progress: Callable[[str], None] | None = None,
) -> pd.DataFrame:
    """Complete the mask of :func:`run_mask` (same p and seed) with each peer, knobs by CV.

    Parameters
    ----------
    X : (n, d) the complete ground-truth matrix.
    p, seed : the mask's missing probability and seed (also the seed of the CV folds).
    methods : which of :data:`PEERS`.
    n_folds : hold-out folds of the observed entries.
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
        fit = fit_peer(method, W, mask, n_folds=n_folds, seed=seed)
        seconds = time.perf_counter() - start
        sse = float(np.sum((fit["x"] - X) ** 2))
        if not np.isfinite(sse):
            raise FloatingPointError(f"{method} returned non-finite values (p={p}, seed={seed})")
        rows.append(
            {
                "p": p,
                "seed": seed,
                "method": fit["method"],
                "sse": sse,
                "available": True,
                "converged": fit["converged"],
                "n_iter": fit["n_iter"],
                "seconds": seconds,
                "n_missing": int((~mask).sum()),
                "params": fit["params"],
            }
        )
        if progress is not None:
            progress(f"p={p} seed={seed} {fit['method']:16s} sse={sse:9.3f} {seconds:6.2f}s {fit['params']}")
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


def peers_caption(settings: Mapping) -> str:
    """The caption's sentence on the peers' rows (empty without peers)."""
    peers = settings["peers"]
    if not peers["methods"]:
        return ""
    names = "; ".join(_PEER_WORDS[m] for m in peers["methods"])
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
        costs about 1.5 CPU s of arithmetic against about 3.6 s of Python start-up per job, so the
        paper's protocol groups its 50 masks per p into a few jobs. A single-mask job is named
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
        params = {name: dict(kwargs) for name, kwargs in settings["methods"].items()}
        params.setdefault("Ours", {}).update(gamma=settings["gamma"], **settings.get("ours", {}))
        for name in ("PKPCA", "RKPCA"):
            params.setdefault(name, {}).setdefault("gamma", settings["gamma"])
        skip = set(settings.get("skip", []))
        methods = [m for m in METHODS if m not in skip]
        rows = run_mask(X, p=p, seed=seed, params=params, methods=methods, progress=progress)
        landmarks = settings.get("ours", {}).get("options", {}).get("landmarks")
        if landmarks is not None:  # not the exact solve: the label says so wherever the row appears
            rows["method"] = rows["method"].replace("Ours", f"Ours (Nystroem {landmarks})")
        peers = settings["peers"]
        limits = peers.get("masks", {})
        chosen = [m for m in peers["methods"] if mask < limits.get(m, mask + 1)]
        if chosen:
            more = run_peers(X, p=p, seed=seed, methods=chosen, n_folds=peers["n_folds"], progress=progress)
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
        ours = s.get("ours", {}).get("options", {})
        how = (
            f" Ours (Nystroem {ours['landmarks']}) is the regularizer on the Nystroem approximation of the "
            f"kernel ({ours['landmarks']} landmark samples, "
            "minimize_regularized(method='nystroem'), opt-in; not the exact solve, see docs/PERFORMANCE.md)."
            if "landmarks" in ours
            else ""
        )
        if s.get("skip"):
            how += f" Not run at this size (CPU cost): {', '.join(s['skip'])}."
        return (
            f"Table 2 on {s['n_rows']} oil-flow rows, the training, validation and test files together "
            f"(not in the paper): sum of squared errors over the whole matrix, mean ± sd over {s['n_masks']} "
            "seeded masks per p." + how + peers_caption(s)
        )
