"""Table 2: matrix completion on oil flow, the regularizer against five baselines.

One run = one missing probability p and one seeded mask; every method completes the same masked
matrix, starting (where it iterates) from mean imputation. The error is the sum of squared errors
over the whole n x d matrix (docs/REPRODUCTION.md#table-2-error explains why not the root mean square).
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
from ..datasets import load_oil
from ..regularizer import minimize_regularized
from .base import Experiment, Job, JobOutput, summary_stats

__all__ = ["METHODS", "random_mask", "run_mask", "summarise", "Table2", "Table2Full"]

# Paper order; "Ours" is the regularizer of Algorithm 1 with the masked least-squares data term.
METHODS = ("mean", "1-NN", "PPCA", "PKPCA", "RKPCA", "Ours")


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


def summarise(runs: pd.DataFrame) -> pd.DataFrame:
    """Aggregate :func:`run_mask` frames into Table 2's tidy rows (setting, method, metric, value).

    Per p and method: mean and sample standard deviation of the SSE over the masks where the method was
    available (NaN, the paper's NA, when it never was), the number of such masks and the fraction of
    runs that converged. Timings stay in the run frames: a table must not change between reruns.
    """
    rows = []
    for p in sorted(runs["p"].unique()):
        for method in [m for m in METHODS if m in set(runs["method"])]:
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


class Table2(Experiment):
    """Table 2: completion of the first oil-flow training rows, the regularizer against five baselines."""

    name = "table2"
    title = "Matrix completion on oil flow: the regularizer against five baselines"
    in_paper = True
    paper = paper_numbers.TABLE2
    notebook = "table2_completion"
    render = {"digits": 3, "metrics": ["sse"], "transpose": True}
    enumerates = ("p", "n_masks", "seed")

    def jobs(self, config):
        s = self.settings(config)
        return [
            Job(f"p{p:g}_seed{s['seed'] + k}", {"p": p, "seed": s["seed"] + k})
            for p in s["p"]
            for k in range(s["n_masks"])
        ]

    def data_files(self, config, job=None):
        return ["oil/DataTrn.txt", "oil/DataTrnLbls.txt"]

    def resources(self, config, job):
        return {"mem_mb": 1000, "runtime": 20}

    def run(self, job, settings, data_dir, *, progress=None, threads=1):
        X, _ = load_oil("train", data_dir)
        X = X[: settings["n_rows"]]
        params = {name: dict(kwargs) for name, kwargs in settings["methods"].items()}
        params.setdefault("Ours", {})["gamma"] = settings["gamma"]
        for name in ("PKPCA", "RKPCA"):
            params.setdefault(name, {}).setdefault("gamma", settings["gamma"])
        rows = run_mask(X, p=job.params["p"], seed=job.params["seed"], params=params, progress=progress)
        return JobOutput(rows=rows)

    def summarise(self, runs):
        return summarise(runs)

    def caption(self, config):
        s = self.settings(config)
        return (
            f"Table 2: oil-flow completion (first {s['n_rows']} training rows), sum of squared errors over "
            f"the whole matrix, mean ± sd over {s['n_masks']} seeded masks per p; paper in parentheses, "
            "– where not available."
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
        return {"mem_mb": 2000, "runtime": 60}

    def caption(self, config):
        s = self.settings(config)
        return (
            f"Table 2 on {s['n_rows']} oil-flow training rows (not in the paper, which uses the first "
            f"{config['table2']['n_rows']}): sum of squared errors over the whole matrix, mean ± sd over "
            f"{s['n_masks']} seeded masks per p."
        )
