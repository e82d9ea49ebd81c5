"""Out of sample (not in the paper): complete new oil-flow rows against a manifold learned once.

The paper computes pre-images only for the rows its manifold was learned from and leaves new samples as
future work (its Section 4.1). Here :class:`nldr.impute.RobustKernelPCAImputer` learns the manifold
on the 1000 rows of ``DataTrn.txt`` and completes the rows of ``DataTst.txt`` (never seen in the fit),
each with entries missing independently with probability p.

One job = one p and one seeded test mask. Methods, all fitted on the same training rows:

- ``complete``: RobustKernelPCAImputer fitted on the training rows, then the pre-image step per new row (hard
  limit: observed entries kept, missing ones minimise the feature distance to the learned subspace);
- ``KNNImputer`` and ``IterativeImputer`` (scikit-learn, ``fit`` on the training rows, ``transform`` on
  the masked test rows);
- ``Ours``: the transductive joint solve, the regularizer (:class:`nldr.impute.KernelRegularizerImputer`)
  on training rows and masked test rows together. It costs O(n^2) per evaluation in the joint rows, so it
  runs on the first ``ours.n_train`` training rows and first ``ours.n_test`` test rows, with the paper's
  Table 2 values of gamma and tau (not chosen by CV).

Knobs (complete: gamma, tau, the start's neighbours; KNNImputer: neighbours, weights) are chosen by
hold-out CV on the training rows only: ``cv.n_folds`` disjoint blocks of ``cv.holdout_rows`` training
rows are held out in turn, their entries hidden at the job's p (seeded), the method fitted on the other
training rows, and the SSE on the hidden entries scored. The test rows' ground truth is used only for the
reported errors.

Huber demonstration (``corrupt`` jobs): the test rows at p = ``corrupt.p`` with gross errors in a share of
their observed entries (as in the ``robust`` experiment: random sign times 3-6 column standard
deviations), and ``complete`` with finite rho, every entry free: ``complete (LS)`` with the squared loss,
``complete (Huber)`` with the Huber loss; their rho (and delta) by hold-out CV on training rows corrupted
the same way (:func:`select_denoising`); gamma, tau and the neighbours fixed in ``corrupt``. Against them
``complete`` (hard limit: observed entries, errors included, kept) and ``KNNImputer``; ``sse`` is
against the clean test rows over all entries.

Metrics: ``sse`` over all test entries (observed entries are returned as observed by every method),
``sse_subset`` on the rows ``Ours`` solves (for comparing with it), and ``ms_per_row``: CPU milliseconds
(``time.process_time``, the pipeline pins BLAS to one thread) per test row of the completion step, the
fit excluded (it is done once), except for ``Ours``, whose solve is the whole cost.
"""

from __future__ import annotations

import itertools
import time

import numpy as np
import pandas as pd
from sklearn.experimental import enable_iterative_imputer  # noqa: F401
from sklearn.impute import IterativeImputer, KNNImputer

from ..datasets import load_oil
from ..impute import KernelRegularizerImputer, RobustKernelPCAImputer
from ..model_selection import HoldoutSearch
from ._robust import gross_corruption
from ._table2 import random_mask
from .base import Experiment, Job, JobOutput, summary_stats

__all__ = [
    "OutOfSample",
    "METHODS",
    "cv_splits",
    "row_folds",
    "select_complete",
    "select_knn",
    "select_denoising",
]

METHODS = ("complete", "complete (LS)", "complete (Huber)", "KNNImputer", "IterativeImputer", "Ours")


def cv_splits(n: int, holdout_rows: int, n_folds: int, seed: int):
    """``n_folds`` disjoint blocks of ``holdout_rows`` rows of a seeded permutation of range(n):
    yields (fit_rows, held_rows) index arrays."""
    if n_folds * holdout_rows >= n:
        raise ValueError(f"cv: n_folds * holdout_rows must be below the {n} training rows")
    perm = np.random.default_rng(seed).permutation(n)
    for k in range(n_folds):
        held = perm[k * holdout_rows : (k + 1) * holdout_rows]
        yield np.setdiff1d(perm, held), held


def select_complete(X, p, seed, cv) -> tuple[dict, pd.DataFrame]:
    """``complete``'s gamma, tau, neighbours, starts and weights by the hold-out SSE on training rows
    (:func:`row_folds`; :class:`~nldr.impute.RobustKernelPCAImputer` in a
    :class:`~nldr.model_selection.HoldoutSearch`).

    Per (gamma, tau) the candidates share one manifold per fold, and the ``starts="each"`` ones one
    set of solves: the search runs the neighbour counts as a warm path from the largest down, each
    averaging the largest count's first local minima (the imputer's ``warm_start``). Returns the
    parameters with the lowest mean hidden-entry SSE over the folds (as a dict of ``gamma, tau,
    n_neighbors, starts, weights``) and the search's ``cv_results_`` as a frame.
    """
    ks = sorted(cv["n_neighbors"], reverse=True)
    grid = []
    for gamma, log10_tau in itertools.product(cv["gammas"], cv["log10_tau"]):
        point = {"gamma": [gamma], "tau": [10.0**log10_tau], "n_neighbors": ks}
        if "mean" in cv["starts"]:
            grid.append({**point, "starts": ["mean"]})
        if "each" in cv["starts"]:
            grid.append({**point, "starts": ["each"], "weights": list(cv["weights"])})
    folds = row_folds(X, p, seed, cv["holdout_rows"], cv["n_folds"])
    imputer = RobustKernelPCAImputer(standardize=False, warm_start=True)
    search = HoldoutSearch(imputer, grid, folds=folds, scoring=_sse, path="n_neighbors", refit=False).fit(X)
    best = {"weights": "uniform", **search.best_params_}
    chosen = {key: best[key] for key in ("gamma", "tau", "n_neighbors", "starts", "weights")}
    return chosen, pd.DataFrame(search.cv_results_)


def _corrupt_manifold(c) -> dict:
    """The fixed knobs of ``complete`` in the ``corrupt`` jobs (config block ``corrupt``)."""
    tau = 10.0 ** c["log10_tau"]
    fixed = {"gamma": c["gamma"], "tau": tau, "n_neighbors": c["n_neighbors"], "starts": "each"}
    return {"standardize": False, **fixed}  # gamma in the data's units, as Table 2


def select_denoising(X, p, share, seed, cv, c) -> tuple[dict, dict]:
    """Loss, rho and delta of ``complete`` with finite rho for rows with gross errors, by hold-out CV on
    training rows: each held-out block gets the job's missing entries (probability p) and gross errors
    in ``share`` of its observed entries (:func:`nldr.experiments._robust.gross_corruption`, seeded), and
    the SSE against the clean held-out rows over all entries is scored (training rows are clean, so the
    corruption is simulated there; the test rows' truth is never used). Returns the best squared-loss
    and the best Huber candidate, each a dict of ``complete`` keyword arguments (sorted by name).

    Each search's folds are ``(fit_rows, hidden, inputs)``: the inputs are the corrupted blocks, the
    score is against X (clean); the candidates of a fold share one manifold (a warm path in rho)."""
    n, d = X.shape
    sd = c["outlier_sd"]
    folds = []
    for k, (fit, held) in enumerate(cv_splits(n, cv["holdout_rows"], c["n_folds"], seed)):
        mask = random_mask((held.size, d), p, seed + 1000 + k)
        corrupted = gross_corruption(X[held], mask, [share], seed + 2000 + k, low=sd["low"], high=sd["high"])
        W = corrupted[share][0]
        fit_rows = np.zeros(n, dtype=bool)
        fit_rows[fit] = True
        hidden = np.zeros((n, d), dtype=bool)
        hidden[held] = True  # scored on every entry of the block
        order = np.argsort(held)  # the block's rows in X's order, as the search scores them
        folds.append((fit_rows, hidden, np.where(mask, W, np.nan)[order]))
    imputer = RobustKernelPCAImputer(**_corrupt_manifold(c), warm_start=True)
    grids = {
        "squared": {"loss": ["squared"], "rho": list(c["rho"])},
        "huber": {"loss": ["huber"], "rho": list(c["rho"]), "delta": list(c["delta"])},
    }
    search = {"folds": folds, "scoring": _sse, "path": "rho", "refit": False}
    best = {loss: HoldoutSearch(imputer, grid, **search).fit(X).best_params_ for loss, grid in grids.items()}
    return best["squared"], best["huber"]


def row_folds(X, p: float, seed: int, holdout_rows: int, n_folds: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The training rows' hold-out folds as :class:`~nldr.model_selection.HoldoutSearch` takes them:
    per block of :func:`cv_splits`, ``(fit_rows, hidden)``, the other rows to fit on (bool (n,)) and
    the block's entries hidden at missing probability p (seed ``seed + 1000 + k``, bool (n, d))."""
    n, d = X.shape
    folds = []
    for k, (fit, held) in enumerate(cv_splits(n, holdout_rows, n_folds, seed)):
        fit_rows = np.zeros(n, dtype=bool)
        fit_rows[fit] = True
        hidden = np.zeros((n, d), dtype=bool)
        hidden[held] = ~random_mask((held.size, d), p, seed + 1000 + k)
        folds.append((fit_rows, hidden))
    return folds


def _sse(X, X_hat, hidden) -> float:
    """Sum of squared errors on the hidden entries (the fold score of these searches)."""
    return float(np.sum((X_hat - X)[hidden] ** 2))


def select_knn(X, p, seed, cv) -> dict:
    """KNNImputer's neighbours and weights by the hold-out SSE on training rows (:func:`row_folds`)."""
    grid = {"n_neighbors": list(cv["knn_neighbors"]), "weights": ["uniform", "distance"]}
    folds = row_folds(X, p, seed, cv["holdout_rows"], cv["n_folds"])
    return HoldoutSearch(KNNImputer(), grid, folds=folds, scoring=_sse, refit=False).fit(X).best_params_


def _timed(fn):
    start = time.process_time()
    out = fn()
    return out, time.process_time() - start


class OutOfSample(Experiment):
    """New oil-flow rows completed against a manifold learned on the training rows."""

    name = "out_of_sample"
    title = (
        "New samples on a learned manifold: oil-flow test rows completed after fitting on the training rows"
    )
    in_paper = False
    notebook = "out_of_sample"
    render = {"digits": 3, "metrics": ["sse", "sse_subset", "ms_per_row"], "transpose": True}
    enumerates = ("p", "n_masks", "seed")

    def jobs(self, config):
        s = self.settings(config)
        c = s["corrupt"]
        clean = [
            Job(f"p{p:g}_seed{s['seed'] + k}", {"p": p, "seed": s["seed"] + k})
            for p in s["p"]
            for k in range(s["n_masks"])
        ]
        return clean + [
            Job(
                f"p{c['p']:g}_corrupt{share:g}_seed{s['seed'] + k}",
                {"p": c["p"], "corrupt": share, "seed": s["seed"] + k},
            )
            for share in c["shares"]
            for k in range(c["n_masks"])
        ]

    def data_files(self, config, job=None):
        return ["oil/DataTrn.txt", "oil/DataTrnLbls.txt", "oil/DataTst.txt", "oil/DataTstLbls.txt"]

    def resources(self, config, job):
        return {"mem_mb": 1000, "runtime": 10}

    def run(self, job, settings, data_dir, *, progress=None, threads=1):
        say = progress or (lambda line: None)
        X_train, _ = load_oil("train", data_dir)
        X_test, _ = load_oil("test", data_dir)
        p, seed = job.params["p"], job.params["seed"]
        mask = random_mask(X_test.shape, p, seed)
        W = np.where(mask, X_test, np.nan)
        share = float(job.params.get("corrupt", 0.0))
        cv = settings["cv"]
        n_sub = settings["ours"]["n_test"]
        rows = []

        def record(method, X_hat, seconds, n_rows, params):
            err = (X_hat - X_test[: X_hat.shape[0]]) ** 2
            full = X_hat.shape[0] == X_test.shape[0]
            rows.append(
                {
                    "p": p,
                    "corrupt": share,
                    "seed": seed,
                    "method": method,
                    "sse": float(err.sum()) if full else np.nan,
                    "sse_subset": float(err[:n_sub].sum()),
                    "ms_per_row": 1000.0 * seconds / n_rows,
                    "params": repr(params),
                }
            )
            say(
                f"p={p} seed={seed} {method:16s} sse={rows[-1]['sse']:9.3f} "
                f"{rows[-1]['ms_per_row']:.2f} ms/row {params}"
            )

        if share > 0:
            c = settings["corrupt"]
            sd = c["outlier_sd"]
            W, _ = gross_corruption(X_test, mask, [share], seed, low=sd["low"], high=sd["high"])[share]
            W_missing = np.where(mask, W, np.nan)
            fixed = {"gamma": c["gamma"], "log10_tau": c["log10_tau"], "n_neighbors": c["n_neighbors"]}
            runs = [("complete", {})]
            runs += zip(
                ("complete (LS)", "complete (Huber)"),
                select_denoising(X_train, p, share, seed, cv, c),
                strict=True,
            )
            for method, kw in runs:
                imputer = RobustKernelPCAImputer(**_corrupt_manifold(c), **kw).fit(X_train)
                X_hat, seconds = _timed(lambda imputer=imputer: imputer.transform(W_missing))
                record(method, X_hat, seconds, X_test.shape[0], {**fixed, **kw})
            knn = select_knn(X_train, p, seed, cv)
            imputer = KNNImputer(**knn).fit(X_train)
            X_hat, seconds = _timed(lambda: imputer.transform(W_missing))
            record("KNNImputer", X_hat, seconds, X_test.shape[0], knn)
            return JobOutput(rows=pd.DataFrame(rows))

        chosen, _ = select_complete(X_train, p, seed, cv)
        model = RobustKernelPCAImputer(standardize=False, **chosen).fit(X_train)
        X_hat, seconds = _timed(lambda: model.transform(W))
        record("complete", X_hat, seconds, X_test.shape[0], {**chosen, "rank": model.n_components_})

        knn = select_knn(X_train, p, seed, cv)
        imputer = KNNImputer(**knn).fit(X_train)
        X_hat, seconds = _timed(lambda: imputer.transform(W))
        record("KNNImputer", X_hat, seconds, X_test.shape[0], knn)

        iterative = IterativeImputer(random_state=seed, max_iter=settings["iterative_max_iter"]).fit(X_train)
        X_hat, seconds = _timed(lambda: iterative.transform(W))
        record("IterativeImputer", X_hat, seconds, X_test.shape[0], {})

        ours = settings["ours"]
        if ours["n_test"] > 0:
            joint = np.vstack([X_train[: ours["n_train"]], W[:n_sub]])
            joint_mask = np.vstack([np.ones((ours["n_train"], X_test.shape[1]), bool), mask[:n_sub]])
            paper = {"gamma": ours["gamma"], "tau": ours["tau"]}
            solver = {"method": "exact", **ours["schedule"]}
            model = KernelRegularizerImputer(standardize=False, **solver, **paper)
            X_joint, seconds = _timed(lambda: model.fit_transform(np.where(joint_mask, joint, np.nan)))
            record("Ours", X_joint[ours["n_train"] :], seconds, n_sub, paper)
        return JobOutput(rows=pd.DataFrame(rows))

    def summarise(self, runs):
        out = []
        runs = runs.assign(corrupt=runs["corrupt"] if "corrupt" in runs else 0.0)
        for (c, p), setting in runs.groupby(["corrupt", "p"], sort=True):
            name = f"p={p:g}" if c == 0 else f"corrupt={c:g},p={p:g}"
            for method in [m for m in METHODS if m in set(setting["method"])]:
                group = setting[setting["method"] == method]
                stats = {"n_masks": float(len(group))}
                for metric in ("sse", "sse_subset", "ms_per_row"):
                    stats.update(summary_stats(group[metric], metric))
                for metric, value in stats.items():
                    out.append((name, method, metric, float(value)))
        return pd.DataFrame(out, columns=["setting", "method", "metric", "value"])

    def caption(self, config):
        s = self.settings(config)
        o, cv = s["ours"], s["cv"]
        return (
            "Out of sample (not in the paper): oil-flow test rows (DataTst, 1000 x 12) with entries missing "
            "at probability p, completed by methods fitted on the 1000 training rows; sum of squared errors "
            f"over all test entries, mean ± sd over {s['n_masks']} seeded masks per p; ms_per_row: CPU ms "
            "per test row of the completion step (fit excluded; one BLAS thread). Knobs of complete and "
            f"KNNImputer by {cv['n_folds']}-fold hold-out CV on {cv['holdout_rows']} training rows per fold "
            f"(entries hidden at the same p). Ours: the regularizer solved jointly on the first "
            f"{o['n_train']} training and first {o['n_test']} test rows (paper's gamma = {o['gamma']:g}, "
            f"tau = {o['tau']:g}; not CV), compared on sse_subset, the SSE over those test rows. "
            f"corrupt=c: a share c of the observed test entries (p = {s['corrupt']['p']:g}) given gross "
            f"errors; complete (LS) / (Huber): finite rho (and delta) by CV on training rows corrupted "
            f"the same way, {s['corrupt']['n_masks']} masks; SSE against the clean rows."
        )
