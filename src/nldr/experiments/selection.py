"""Selection (not in the paper; issue 15): Table 2's completion protocol with every knob chosen by
hold-out cross-validation on the observed entries, beside the paper's values and an oracle.

One job = one missing probability p and one seeded mask (the same masks as Table 2: mask k at p uses
seed + k). Rows, per job:

- ``Ours (paper values)``: the regularizer at the paper's gamma and tau (Table 2's "Ours");
- ``Ours (CV)``: tau and gamma chosen by :func:`nldr.model_selection.select_regularizer` on the
  observed entries only (folds hiding the config's ``holdout`` share, its ``rule``), then refitted on
  all of them;
- ``Ours (oracle grid point)``: the grid point with the lowest error against the complete matrix.
  It sees ground truth, so it is a reference for how good the grid can be, never a result;
- ``<baseline> (CV)``: each baseline with a knob, its knob chosen on the same folds
  (:func:`nldr.model_selection.select_imputer`), and the peers of issue 16 the same way
  (:func:`nldr.experiments.table2.fit_peer`; IterativeImputer has no knob and is fitted once).

The error is Table 2's: the sum of squared errors over the whole n x d matrix.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from .. import paper as paper_numbers
from ..baselines import mean_impute
from ..data_terms import MaskedLeastSquares
from ..datasets import load_oil
from ..model_selection import median_gamma, select_regularizer
from ..regularizer import minimize_regularized
from .base import JobOutput, summary_stats
from .table2 import PEER_ROWS, Table2, fit_peer, random_mask

__all__ = ["Selection", "METHODS"]

PAPER = "Ours (paper values)"
CV = "Ours (CV)"
ORACLE = "Ours (oracle grid point)"
#: Row order of the table.
METHODS = (PAPER, CV, ORACLE, "PPCA (CV)", "PKPCA (CV)", "RKPCA (CV)") + PEER_ROWS


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

    def resources(self, config, job):
        return {"mem_mb": 1000, "runtime": 30}

    def run(self, job, settings, data_dir, *, progress=None, threads=1):
        say = progress or (lambda line: None)
        X, _ = load_oil("train", data_dir)
        X = X[: settings["n_rows"]]
        p, seed = job.params["p"], job.params["seed"]
        mask = random_mask(X.shape, p, seed)
        W = np.where(mask, X, np.nan)
        term, S0 = MaskedLeastSquares(W, mask), mean_impute(W, mask)
        schedule = dict(settings["schedule"])  # rho0, rho_growth, rho_max
        center = bool(settings["center"])
        grid = settings["grid"]
        taus = np.logspace(grid["log10_tau"]["min"], grid["log10_tau"]["max"], grid["log10_tau"]["num"])
        gammas = np.asarray(grid["gamma_multiples"], dtype=float) * median_gamma(W, mask)
        rows = []

        def record(method, X_hat, seconds, **extra):
            sse = float(np.sum((X_hat - X) ** 2))
            rows.append({"p": p, "seed": seed, "method": method, "sse": sse, "seconds": seconds, **extra})
            say(f"p={p:g} seed={seed} {method:26s} sse={sse:9.3f} {seconds:6.2f}s {extra}")

        paper = settings["paper"]
        start = time.perf_counter()
        res = minimize_regularized(
            term, S0, gamma=paper["gamma"], tau=paper["tau"], center=center, **schedule
        )
        record(PAPER, res.x, time.perf_counter() - start, tau=paper["tau"], gamma=paper["gamma"])
        one_solve = rows[-1]["seconds"]

        start = time.perf_counter()
        sel = select_regularizer(
            W,
            mask,
            taus=taus,
            gammas=gammas,
            center=center,
            n_folds=settings["n_folds"],
            holdout=settings["holdout"],
            rule=settings["rule"],
            random_state=seed,
            **schedule,
        )
        seconds = time.perf_counter() - start
        record(CV, sel.result_.x, seconds, tau=sel.tau_, gamma=sel.gamma_, solves=seconds / one_solve)

        # the oracle: every grid point on all observed entries, scored against the complete matrix
        start = time.perf_counter()
        oracle = []
        for gamma in gammas:
            for tau in taus:
                fit = minimize_regularized(
                    term, S0, gamma=float(gamma), tau=float(tau), center=center, **schedule
                )
                oracle.append((float(np.sum((fit.x - X) ** 2)), float(tau), float(gamma), fit.x))
        best = min(oracle, key=lambda item: item[0])
        record(ORACLE, best[3], time.perf_counter() - start, tau=best[1], gamma=best[2])

        for method in settings["baselines"]:
            start = time.perf_counter()
            fit = fit_peer(method, W, mask, n_folds=settings["n_folds"], seed=seed)
            record(fit["method"], fit["x"], time.perf_counter() - start, params=fit["params"])

        cv = sel.cv_results_
        arrays = {
            "cv_tau": cv["tau"].to_numpy(),
            "cv_gamma": cv["gamma"].to_numpy(),
            "cv_error": cv["mean_test_error"].to_numpy(),
            "cv_error_sd": cv["std_test_error"].to_numpy(),
            "oracle_sse": np.array([o[0] for o in oracle]),
            "oracle_tau": np.array([o[1] for o in oracle]),
            "oracle_gamma": np.array([o[2] for o in oracle]),
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
        rule = "the best" if s["rule"] == "min" else "the smallest tau within one standard error of the best"
        return (
            f"Selection (not in the paper): oil-flow completion (first {s['n_rows']} training rows, Table "
            f"2's masks), sum of squared errors, mean ± sd over {s['n_masks']} masks per p. Ours with the "
            f"paper's gamma and tau; with tau and gamma chosen by hold-out CV on the observed entries "
            f"({folds}, {rule}); and the best grid point on ground truth (an oracle, a reference only). "
            f"Baselines and peers (KNNImputer, IterativeImputer, SoftImpute, missForest; not in the paper) "
            f"with their knob chosen by {s['n_folds']}-fold CV (a partition of the observed entries; "
            "IterativeImputer has none)."
        )
