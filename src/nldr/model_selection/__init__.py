"""Choosing parameters from the data alone: hold-out cross-validation on the observed entries.

The paper sets tau and the kernel width by hand. With no ground truth, the only honest score of a
setting is how well it predicts entries it did not see: each fold hides a random share of the
*observed* entries, the method completes the matrix from the rest, and the fold's score is the mean
squared error on the hidden entries. The setting with the smallest mean score over the folds wins and is
refitted on every observed entry. A value chosen against ground truth is an oracle and must be labelled
as one; nothing here ever sees ground truth.

- :class:`HoldoutSearch` chooses any imputer's parameters this way (the regularizer's tau and width,
  :class:`nldr.impute.KernelRegularizerImputer`; every baseline's and peer's knob, with the default
  grids of :func:`baseline_grid`; scikit-learn's imputers as they are). Its ``folds`` can hide any
  set of entries, such as NRSfM's 2D points (both image coordinates of a point in a frame).
- :func:`holdout_folds` (:class:`EntryFolds`) deals the folds; :func:`median_gamma` and
  :data:`GAMMA_MULTIPLES`, :data:`DEFAULT_TAUS` give the regularizer's default grid.

Folds. ``holdout=0.1`` hides a fresh random tenth of the observed entries in each of the ``n_folds``
folds (Monte-Carlo folds: the fold problems are nearly as dense as the refit's); ``holdout=None`` (the
default) deals the shuffled observed entries into ``n_folds`` disjoint groups. A column whose observed
entries would all be hidden keeps one of them for training (never scored in that fold), because a
method starting from column means needs one. Same seed, same folds, same answer.

Rule. ``rule="min"`` (the default) takes the smallest mean error. ``rule="one_se"`` with
``prefer=("tau", "gamma")`` takes, among the candidates within one standard error of the smallest, the
one with the smallest tau, then the widest kernel (smallest gamma), then the smallest error: the
smoothest of the tied models, and the least regularised one, whose fold solves start cold like the
refit.

Cost. For the regularizer (``path="tau"``) the candidates of one fold form paths in tau, solved upwards
from the smallest: the first from the estimator's own start with the full penalty schedule, each later one
warm-started from its neighbour's solution with the last stage only. Upwards, because a large tau can
collapse the samples onto one point (K ~ 1 1^T), a local minimum a smaller tau's last stage does not
leave. The first solve of each gamma starts from the previous gamma's the same way, so a fold has one
cold solve (both when the estimator offers ``warm_start``). A path stops once a candidate's hold-out
error exceeds ``stop_factor`` times the path's best so far (the collapsing solves are the slowest).
``fold_params`` can give the fold solves looser tolerances or the Nystroem kernel (they only rank
candidates; the refit stays exact); the folds run in parallel with ``n_jobs``; every solve uses the
isolation guard (:func:`nldr._schedule.isolation_safe_rho0`), so a large tau cannot push hidden
entries away.

What the search chooses on the paper's data, and where it cannot find the ground-truth-best width:
docs/REPRODUCTION.md#selection.
"""

from ._folds import EntryFolds, holdout_folds, median_gamma
from ._robust import RobustScaleDelta, robust_scale
from ._search import HoldoutSearch

__all__ = [
    "HoldoutSearch",
    "EntryFolds",
    "median_gamma",
    "holdout_folds",
    "RobustScaleDelta",
    "robust_scale",
]
