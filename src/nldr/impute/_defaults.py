"""The defaults of :class:`~nldr.impute.KernelRegularizerImputer`: its solver paths and the grids, folds
and tolerances of its ``"auto"`` tuning. Where a value was measured, its comment names the docs anchor."""

from __future__ import annotations

import dataclasses

import numpy as np

from .._options import ExactOptions, NystroemOptions, NystroemWarmOptions
from ..kernels import squared_distances

__all__ = [
    "median_rule_gamma",
    "LOSSES",
    "METHODS",
    "FLAT_OPTIONS",
    "AUTO_EXACT_MAX_ROWS",
    "AUTO_LANDMARKS",
    "AUTO_LANDMARK_RULE",
    "AUTO_STAGE_TOL",
    "DEFAULT_TOL",
    "AUTO_NYSTROEM_TOL",
    "DEFAULT_LANDMARKS",
    "INITS",
    "INIT_NEIGHBOURS",
    "INIT_MAX_DONORS",
    "AUTO_KNN_MIN_ROWS",
    "EXACT_OPTIONS",
    "MEDIAN_RULE_MULTIPLE",
    "TUNE_GAMMA_MULTIPLES",
    "TUNE_TAUS",
    "TUNE_FOLDS",
    "TUNE_HOLDOUT",
    "TUNE_MIN_ROWS",
    "TUNE_MAX_ROWS",
    "UNTUNED_TAU",
    "TUNE_TRANSFORM",
    "TUNE_ROW_SHARE",
    "TUNE_ROW_HIDDEN",
    "TUNE_TOLERANCES",
    "TUNE_LANDMARKS",
    "TUNE_STOP_FACTOR",
    "NYSTROEM_OPTIONS",
]

#: data losses of ``loss``
LOSSES = ("squared", "huber")
#: solver paths of ``method``: "auto" and minimize_regularized's methods
METHODS = ("auto", "exact", "nystroem", "nystroem-warm")
#: the constructor parameters that set minimize_regularized's options, and the option each sets
FLAT_OPTIONS = {"max_iter": "max_inner", "tol": "tol", "gtol": "gtol", "n_landmarks": "landmarks"}
#: ``method="auto"`` solves exactly up to this many rows (measured: docs/PERFORMANCE.md#solver-path) ...
AUTO_EXACT_MAX_ROWS = 150
#: ... and above, every stage on the Nystroem kernel of AUTO_LANDMARKS landmarks chosen by pivoted
#: Cholesky of the start's kernel (deterministic), the stages before the last stopping at the relative
#: decrease AUTO_STAGE_TOL (they only give the next stage its start; measured:
#: docs/PERFORMANCE.md#auto-landmarks)
AUTO_LANDMARKS, AUTO_LANDMARK_RULE, AUTO_STAGE_TOL = 150, "pivoted", 1e-5
#: ``tol="auto"``: every stage stops at the relative decrease DEFAULT_TOL, except the last stage of
#: "auto"'s approximate path above AUTO_EXACT_MAX_ROWS rows: AUTO_NYSTROEM_TOL (at 1000 oil rows, 30
#: masks: 0.91x the CPU, SSE within 0.2 %; on wine's 50 masks RMSE within 5e-4; measured:
#: docs/PERFORMANCE.md#the-last-stage)
DEFAULT_TOL, AUTO_NYSTROEM_TOL = 1e-10, 1e-9
#: the solve's starts of ``init``, the nearest rows whose mean starts a missing entry with "knn", and the
#: most donor rows they are drawn from (an even subsample beyond: the fill's cost linear in the rows)
INITS, INIT_NEIGHBOURS, INIT_MAX_DONORS = ("auto", "mean", "knn"), 10, 2000
#: ``init="auto"`` starts ``method="auto"`` from "knn" from this many rows, from the mean below: from 500
#: oil rows the nearest rows' fill reached a lower exact energy on every mask measured (45), at 200-300 rows
#: on 24 of 30, and on wine (178 rows) it raised the error (docs/PERFORMANCE.md#the-start)
AUTO_KNN_MIN_ROWS = 500
#: ``n_landmarks=None`` with ``method="nystroem"`` or ``"nystroem-warm"``: the warm start's default
#: landmark count, one default for both Nystroem paths
DEFAULT_LANDMARKS = NystroemWarmOptions.landmarks
#: options "exact" takes (method="auto" drops the others below AUTO_EXACT_MAX_ROWS rows)
EXACT_OPTIONS = frozenset(f.name for f in dataclasses.fields(ExactOptions))
#: the default width is this multiple of 1 / (median squared distance between rows), standardised units
#: (measured: docs/REPRODUCTION.md#imputer-defaults)
MEDIAN_RULE_MULTIPLE = 0.25
#: ``gamma="auto"``: the hold-out chooses among these multiples of 1 / (median squared row distance)
#: (measured: docs/REPRODUCTION.md#imputer-defaults, as are the TUNE_* below)
TUNE_GAMMA_MULTIPLES = (0.125, 0.25, 0.5, 1.0)
#: ``tau="auto"``: the hold-out chooses among these taus (standardised units when ``standardize``)
TUNE_TAUS = (0.1, 0.3)
#: the tuning's Monte-Carlo hold-out folds: how many, and the share of observed entries each hides
TUNE_FOLDS = 2
TUNE_HOLDOUT = 0.1
#: below TUNE_MIN_ROWS rows, and from TUNE_MAX_ROWS rows, "auto" is not searched: tau UNTUNED_TAU and
#: the median rule's width (too few rows to hold out; at TUNE_MAX_ROWS rows and more the search costs
#: more than the solve and does not beat the rule: docs/PERFORMANCE.md#defaults-at-scale)
TUNE_MIN_ROWS, TUNE_MAX_ROWS, UNTUNED_TAU = 20, 1000, 0.1
#: ``n_neighbors="auto"``, ``starts="auto"``: the row folds choose ``transform``'s (n_neighbors, starts)
#: among these (the second is the choice when the rows are too few to tune)
TUNE_TRANSFORM = ((1, "mean"), (5, "mean"), (10, "mean"), (5, "each"))
#: the row folds hold out this share of the training rows, and hide this least share of their entries
TUNE_ROW_SHARE = 0.2
TUNE_ROW_HIDDEN = 0.25
#: the tuning's fold solves stop at these looser tolerances (they only rank candidates)
TUNE_TOLERANCES = {"tol": 1e-7, "gtol": 1e-4}
#: the tuning's fold solves above AUTO_EXACT_MAX_ROWS rows: the Nystroem kernel of this many landmarks
#: (chosen by AUTO_LANDMARK_RULE)
TUNE_LANDMARKS = 100
#: a fold's tau path stops once its error exceeds this factor times the path's best so far
TUNE_STOP_FACTOR = 1.5
NYSTROEM_OPTIONS = frozenset(f.name for f in dataclasses.fields(NystroemOptions))
def median_rule_gamma(S: np.ndarray) -> float:
    """``MEDIAN_RULE_MULTIPLE / median ||s_i - s_j||^2`` over the pairs of rows of a complete S (units S^-2).

    The default width of :class:`~nldr.impute.KernelRegularizerImputer`: the median pair of rows gets
    kernel value exp(-1/4). Beyond 2000 rows an even subsample of 2000 sets the median.
    """
    n = S.shape[0]
    rows = S if n <= 2000 else S[np.linspace(0, n - 1, 2000).astype(int)]
    D = squared_distances(rows)
    med = float(np.median(D[np.triu_indices(rows.shape[0], 1)]))
    if not med > 0:
        raise ValueError(
            "the rows of X (after mean imputation) coincide: the median rule cannot set gamma; pass gamma"
        )
    return MEDIAN_RULE_MULTIPLE / med
