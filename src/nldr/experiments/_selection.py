"""Selection (not in the paper): Table 2's completion protocol with every knob chosen by
hold-out cross-validation on the observed entries, beside the paper's values and an oracle.

One job = one missing probability p and one seeded mask (the same masks as Table 2: mask k at p uses
seed + k). Rows, per job:

- ``Ours (paper values)``: the regularizer at the paper's gamma and tau (Table 2's "Ours");
- ``Ours (CV)``: tau and gamma chosen by :class:`nldr.model_selection.HoldoutSearch` on the
  observed entries only (folds hiding the config's ``holdout`` share, its ``rule``; the tau path of
  each width solved from the smallest tau up, stopped once its error passes 1.5 times its best; the
  fold solves at looser tolerances), then refitted on all of them;
- ``Ours (oracle grid point)``: the grid point with the lowest error against the complete matrix.
  It sees ground truth, so it is a reference for how good the grid can be, never a result;
- ``<baseline> (CV)``: each baseline and peer with a knob, its knob chosen by the same search over
  :func:`nldr.impute._grids.baseline_grid` (IterativeImputer has no knob and is fitted once).

The error is Table 2's: the sum of squared errors over the whole n x d matrix.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
from sklearn.base import clone

from .. import paper as paper_numbers
from ..datasets import load_oil
from ..impute import KernelRegularizerImputer
from ..impute._grids import MISSFOREST_TREES, baseline_grid
from ..model_selection import HoldoutSearch, median_gamma
from ._table2 import PEER_ROWS, Table2, peer_label, random_mask
from .base import Job, JobOutput, summary_stats

__all__ = ["Selection", "SelectionFull", "METHODS", "exact_path", "regularizer_imputer", "fold_params"]

PAPER = "Ours (paper values)"
CV = "Ours (CV)"
ORACLE = "Ours (oracle grid point)"
#: Row order of the table.
METHODS = (PAPER, CV, ORACLE, "PPCA (CV)", "PKPCA (CV)", "RKPCA (CV)") + PEER_ROWS
#: Ours (CV): a tau path stops in a fold once a candidate's error passes this times the path's best.
STOP_FACTOR = 1.5
#: Ours (CV): the fold solves' tolerances (they only rank candidates; the refit uses the solver's).
FOLD_TOLERANCES = {"tol": 1e-7, "gtol": 1e-4}


def exact_path(settings, p: float) -> dict:
    """Keyword arguments of ``KernelRegularizerImputer`` for the exact solves at missing share p
    (config ``exact_path``): {} for the default path, else ``method="nystroem-warm"`` with its
    ``n_landmarks`` and ``options``: Nystroem stages then the exact solver's last ``exact_stages``
    (``low_p.exact_stages`` at p <= ``low_p.max_p``)."""
    path = dict(settings.get("exact_path") or {})
    low = path.pop("low_p", None)
    if path:
        path["options"] = dict(path["options"])
    if low is not None and p <= low["max_p"]:
        path["options"]["exact_stages"] = low["exact_stages"]
    return path


def regularizer_imputer(settings, p: float) -> KernelRegularizerImputer:
    """The regularizer of the exact solves, with the paper's settings written out: data in its units
    (``standardize=False``), the block's ``center`` and penalty ``schedule``, and the path to the exact
    answer of :func:`exact_path` at missing share p (landmarks drawn from seed 0). Along a tau path
    :class:`~nldr.model_selection.HoldoutSearch` sets its ``warm_start``: every candidate of a fold
    after the first starts from its neighbour's solution with the last penalty stage only."""
    path = exact_path(settings, p)
    options = dict(path.get("options") or {})
    if path:
        options.setdefault("landmark_seed", 0)
    return KernelRegularizerImputer(
        standardize=False,
        denoise=True,  # the solve's S on every entry, as Table 2 scores it
        center=bool(settings["center"]),
        method=path.get("method", "exact"),
        n_landmarks=path.get("n_landmarks"),
        options=options or None,
        **settings["schedule"],
    )


def fold_params(settings) -> dict:
    """Parameters of the CV's fold solves: :data:`FOLD_TOLERANCES`, the exact kernel (or the
    Nystroem kernel on ``fold_landmarks`` landmark rows), never the refit's path."""
    params = {"method": "exact", "n_landmarks": None, "options": None, **FOLD_TOLERANCES}
    if settings.get("fold_landmarks") is not None:
        params.update(method="nystroem", n_landmarks=settings["fold_landmarks"], options={"landmark_seed": 0})
    return params


def _total_sse(X, X_hat, hidden) -> float:
    """Table 2's error: the sum of squared errors over the whole matrix (the oracle's score)."""
    return float(np.sum((X_hat - X) ** 2))


def _clock() -> tuple[float, float]:
    """(wall, CPU) now: a row's ``seconds`` and ``cpu_seconds`` are measured from it."""
    return time.perf_counter(), time.process_time()


class Selection(Table2):
    """Completion with parameters chosen from the data alone (hold-out CV), against the paper's values.

    Its jobs and data are Table 2's (one per p and mask, the same masks); everything else is its own.
    """

    name = "selection"
    title = "Parameters from the data: hold-out CV against the paper's values and an oracle"
    in_paper = False
    notebook = "selection"
    inherits = None
    #: the paper's Table 2 "Ours" beside our run at the paper's values
    paper = [(s, PAPER, m, v) for s, method, m, v in paper_numbers.TABLE2 if method == "Ours"]

    def check(self, config):
        grid = self.settings(config)["grid"]["log10_tau"]
        if grid["min"] > grid["max"]:
            raise ValueError(
                f"selection.grid.log10_tau: min must not exceed max; got {grid['min']} > {grid['max']}"
            )
        return super().check(config)

    def jobs(self, config):
        """One job per p and mask, mask k at p drawn from seed + k (Table 2's masks). Its own, not
        Table 2's, so that a regrouping of Table 2's jobs leaves these ids and runs alone."""
        s = self.settings(config)
        return [
            Job(f"p{p:g}_seed{s['seed'] + k}", {"p": p, "seed": s["seed"] + k, "mask": k})
            for p in s["p"]
            for k in range(s["n_masks"])
        ]

    def resources(self, config, job):
        return {"mem_mb": 1000, "runtime": 30}

    def run(self, job, settings, data_dir, *, progress=None, threads=1):
        say = progress or (lambda line: None)
        X = load_oil("train", data_dir)[0][: settings["n_rows"]]
        p, seed = job.params["p"], job.params["seed"]
        mask = random_mask(X.shape, p, seed)
        W = np.where(mask, X, np.nan)
        grid = settings["grid"]
        taus = np.logspace(grid["log10_tau"]["min"], grid["log10_tau"]["max"], grid["log10_tau"]["num"])
        gammas = np.asarray(grid["gamma_multiples"], dtype=float) * median_gamma(W, mask)
        candidates = {"gamma": [float(g) for g in gammas], "tau": [float(t) for t in taus]}
        rows = []

        def record(method, X_hat, clock, **extra):
            sse = float(np.sum((X_hat - X) ** 2))
            wall, cpu = time.perf_counter() - clock[0], time.process_time() - clock[1]
            rows.append(
                {
                    "p": p,
                    "seed": seed,
                    "method": method,
                    "sse": sse,
                    "seconds": wall,
                    "cpu_seconds": cpu,
                    **extra,
                }
            )
            say(f"p={p:g} seed={seed} {method:26s} sse={sse:9.3f} cpu {cpu:.2f}s {extra}")

        # the exact solves (paper values, the CV's refit, the oracle): the paper's schedule, the
        # uncentred kernel, the path to the exact answer the config gives at this p
        ours = regularizer_imputer(settings, p)
        paper = settings["paper"]
        clock = _clock()
        X_hat = clone(ours).set_params(gamma=paper["gamma"], tau=paper["tau"]).fit_transform(W)
        record(PAPER, X_hat, clock, tau=paper["tau"], gamma=paper["gamma"])
        one_solve = rows[-1]["cpu_seconds"]

        clock = _clock()
        search = HoldoutSearch(
            ours,
            candidates,
            n_folds=settings["n_folds"],
            holdout=settings["holdout"],
            random_state=seed,
            rule=settings["rule"],
            prefer=("tau", "gamma"),  # the smallest tau, then the widest kernel
            path="tau",
            stop_factor=STOP_FACTOR,
            fold_params=fold_params(settings),
        )
        X_hat = search.fit_transform(W)
        best = search.best_params_
        record(CV, X_hat, clock, tau=best["tau"], gamma=best["gamma"])
        rows[-1]["solves"] = rows[-1]["cpu_seconds"] / one_solve

        # the oracle: every grid point fitted on all observed entries and scored against the complete
        # matrix (the search with ground truth as its one fold, hiding exactly the missing entries)
        clock = _clock()
        oracle = HoldoutSearch(ours, candidates, folds=[~mask], scoring=_total_sse, refit=False).fit(X)
        k = oracle.best_index_
        best = oracle.cv_results_["params"][k]
        X_hat = clone(ours).set_params(**best).fit_transform(W)
        record(ORACLE, X_hat, clock, tau=best["tau"], gamma=best["gamma"])

        for method in settings["baselines"]:
            clock = _clock()
            trees = settings.get("missforest_trees", MISSFOREST_TREES)
            estimator, param_grid = baseline_grid(method, W, n_trees=trees)
            label = peer_label(method, bool(param_grid), trees)
            if param_grid:
                peer = HoldoutSearch(estimator, param_grid, n_folds=settings["n_folds"], random_state=seed)
                X_hat, params = peer.fit_transform(W), repr(peer.best_params_)
            else:
                X_hat, params = clone(estimator).fit_transform(W), "{}"
            record(label, X_hat, clock, params=params)

        cv, truth = search.cv_results_, oracle.cv_results_
        arrays = {
            "cv_tau": cv["param_tau"].astype(float),
            "cv_gamma": cv["param_gamma"].astype(float),
            "cv_error": cv["mean_test_error"],
            "cv_error_sd": cv["std_test_error"],
            "oracle_sse": truth["mean_test_error"],
            "oracle_tau": truth["param_tau"].astype(float),
            "oracle_gamma": truth["param_gamma"].astype(float),
        }
        return JobOutput(rows=pd.DataFrame(rows), arrays=arrays)

    def published(self, config):
        """The paper's Table 2 "Ours" beside the paper-values row, where the protocol is the paper's
        (its first 100 rows)."""
        return self.paper if self.settings(config)["n_rows"] == 100 else []

    def summarise(self, runs):
        rows = []
        for p in sorted(runs["p"].unique()):
            for method in [m for m in METHODS if m in set(runs["method"])]:
                group = runs[(runs["p"] == p) & (runs["method"] == method)]
                stats = {**summary_stats(group["sse"], "sse"), "n_masks": float(len(group))}
                for metric, value in stats.items():
                    rows.append((f"p={p:g}", method, metric, float(value)))
        return pd.DataFrame(rows, columns=["setting", "method", "metric", "value"])

    def caption(self, config):
        s = self.settings(config)
        folds = (
            f"{s['n_folds']} folds partitioning them"
            if s["holdout"] is None
            else f"{s['n_folds']} folds each hiding {s['holdout']:.0%} of them"
        )
        rule = (
            "the best"
            if s["rule"] == "min"
            else "the smallest tau, then the widest kernel, within one standard error of the best"
        )
        return (
            f"Selection (not in the paper): oil-flow completion (first {s['n_rows']} training rows, Table "
            f"2's masks), sum of squared errors, mean ± sd over {s['n_masks']} masks per p. Ours with the "
            f"paper's gamma and tau; with tau and gamma chosen by hold-out CV on the observed entries "
            f"({folds}, {rule}); and the best grid point on ground truth (an oracle, a reference only). "
            f"Baselines and peers (KNNImputer, IterativeImputer, SoftImpute, missForest with "
            f"{s.get('missforest_trees', MISSFOREST_TREES)} trees; not in the paper) "
            f"with their knob chosen by {s['n_folds']}-fold CV (a partition of the observed entries; "
            "IterativeImputer has none)."
        )


class SelectionFull(Selection):
    """:class:`Selection` on all 1000 oil-flow training rows (``table2_full``'s masks; not in the paper).

    Affordable at that size: a smaller grid, fewer folds and masks (config ``selection_full``), and the
    fold solves of the CV on the Nystroem kernel (``fold_landmarks``). The paper-values row, the CV's
    refit and every oracle grid point are exact solves.
    """

    name = "selection_full"
    title = "Parameters from the data on all 1000 oil-flow training rows (not in the paper)"
    notebook = None
    inherits = "selection"

    def resources(self, config, job):
        return {"mem_mb": 2000, "runtime": 120}

    def caption(self, config):
        s = self.settings(config)
        m = s.get("fold_landmarks")
        folds = (
            f" The CV's fold solves use the Nystroem kernel on {m} landmark rows (approximate; they only "
            "rank the candidates); the paper-values row, the CV's refit and every oracle grid point are "
            "exact solves."
            if m
            else ""
        )
        path = s.get("exact_path")
        if path:
            m = path["n_landmarks"]
            folds += (
                f" The exact solves start on a {m}-landmark Nystroem kernel and end with the "
                "exact solver's last penalty stage(s) (same stopping test; docs/PERFORMANCE.md#scale)."
            )
        skipped = [b for b in ("PPCA", "PKPCA", "RKPCA") if b not in s["baselines"]]
        skip = (
            f" Not run at this size (CPU cost of their CV, docs/PERFORMANCE.md): {', '.join(skipped)}."
            if skipped
            else ""
        )
        return super().caption(config) + folds + skip
