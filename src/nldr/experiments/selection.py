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
from .base import Job, JobOutput, summary_stats
from .table2 import PEER_ROWS, Table2, fit_peer, random_mask

__all__ = ["Selection", "SelectionFull", "METHODS", "exact_path"]

PAPER = "Ours (paper values)"
CV = "Ours (CV)"
ORACLE = "Ours (oracle grid point)"
#: Row order of the table.
METHODS = (PAPER, CV, ORACLE, "PPCA (CV)", "PKPCA (CV)", "RKPCA (CV)") + PEER_ROWS


def exact_path(settings, p: float) -> dict:
    """Keyword arguments of ``minimize_regularized`` for the exact solves at missing share p (config
    ``exact_path``): {} for the default path, else ``method="nystroem-warm"`` with its options: Nystroem
    stages then the exact solver's last ``exact_stages`` (``low_p.exact_stages`` at p <= ``low_p.max_p``)."""
    path = dict(settings.get("exact_path") or {})
    low = path.pop("low_p", None)
    if path:
        path["options"] = dict(path["options"])
    if low is not None and p <= low["max_p"]:
        path["options"]["exact_stages"] = low["exact_stages"]
    return path


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
        term, S0 = MaskedLeastSquares(W, mask), mean_impute(W, mask)
        schedule = dict(settings["schedule"])  # rho0, rho_growth, rho_max
        center = bool(settings["center"])
        grid = settings["grid"]
        taus = np.logspace(grid["log10_tau"]["min"], grid["log10_tau"]["max"], grid["log10_tau"]["num"])
        gammas = np.asarray(grid["gamma_multiples"], dtype=float) * median_gamma(W, mask)
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
            say(f"p={p:g} seed={seed} {method:26s} sse={sse:9.3f} {cpu:7.2f} CPU s {extra}")

        path = exact_path(settings, p)  # how the exact solves reach their answer

        def solve(gamma, tau):
            # the refit of select_regularizer makes this same call (exact kernel, isolation guard on)
            return minimize_regularized(term, S0, gamma=gamma, tau=tau, center=center, **schedule, **path)

        paper = settings["paper"]
        clock = _clock()
        res = solve(paper["gamma"], paper["tau"])
        record(PAPER, res.x, clock, tau=paper["tau"], gamma=paper["gamma"])
        one_solve = rows[-1]["cpu_seconds"]

        clock = _clock()
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
            fold_landmarks=settings.get("fold_landmarks"),
            refit_options=path,
            **schedule,
        )
        record(CV, sel.result_.x, clock, tau=sel.tau_, gamma=sel.gamma_)
        rows[-1]["solves"] = rows[-1]["cpu_seconds"] / one_solve

        # the oracle: every grid point on all observed entries, scored against the complete matrix; the
        # CV's refit is the same call at its grid point, so that solve is taken from it, not repeated
        clock = _clock()
        oracle = []
        for gamma in gammas:
            for tau in taus:
                chosen = float(gamma) == sel.gamma_ and float(tau) == sel.tau_
                x = sel.result_.x if chosen else solve(float(gamma), float(tau)).x
                oracle.append((float(np.sum((x - X) ** 2)), float(tau), float(gamma), x))
        best = min(oracle, key=lambda item: item[0])
        record(ORACLE, best[3], clock, tau=best[1], gamma=best[2])

        for method in settings["baselines"]:
            clock = _clock()
            fit = fit_peer(method, W, mask, n_folds=settings["n_folds"], seed=seed)
            record(fit["method"], fit["x"], clock, params=fit["params"])

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
            f"Baselines and peers (KNNImputer, IterativeImputer, SoftImpute, missForest; not in the paper) "
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
            m = path["options"]["landmarks"]
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
