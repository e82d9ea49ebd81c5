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

Folds. With ``holdout=0.1`` (the regularizer's searches) each of the ``n_folds`` folds hides a fresh
random tenth of the observed entries (Monte-Carlo folds): the fold problems are nearly as dense as the
refit's, which 5-fold partitions (a fifth hidden) are not. ``holdout=None`` (the default) deals the
shuffled observed entries into ``n_folds`` disjoint groups instead. Either way a column whose observed
entries would all be hidden keeps one of them for training (it is then never scored in that fold), because
a method starting from column means needs one. Same seed, same folds, same answer.

Rule. ``rule="one_se"`` with ``prefer=("tau", "gamma")`` takes, among the candidates whose mean hold-out
error is within one standard error of the smallest, the one with the smallest tau, then the widest kernel
(smallest gamma), then the smallest error. Widest: the one-SE rule's usual direction, the smoothest of the
tied models. Where the widths tie, the hold-out cannot tell them apart, and a narrow kernel's advantage is
the fragile one (see "Limit" below); on 40 masks at 100 rows and 12 at 1000 rows (Table 2's protocol) this
tie-break changed 7 choices, 6 to a lower SSE; on 30 fresh masks at 100 rows, 2 (one lower, one higher)
(docs/REPRODUCTION.md#selection). On Table 2's protocol the hold-out error is flat in tau from 0.01 to
about 1 within that error, so ``"min"`` picks among ties by noise; and a fold solve at a larger tau is
warm-started from its smaller-tau neighbour and stays near it, while the refit starts cold and can land
elsewhere (with 5-fold partitions, ``"min"`` chose tau = 3.16 on 2 of 10 masks at p = 0.5: refit SSE 73
and 100, against 54 and 82 at tau = 0.01). The least regularised of the tied candidates is the one whose
fold solves are cold, like the refit. ``rule="min"`` (the default) takes the smallest mean error.

Cost. For the regularizer (``path="tau"``), the candidates of one fold form paths in tau, solved from the
smallest tau up: the first from mean imputation with the full penalty schedule, every later one
warm-started from its neighbour's solution with the last stage only (rho = rho_max). The neighbour is
already close to a minimiser of the limit problem, so the early stages, whose only purpose is to reach
that region from a poor start, are not needed again. The path goes up, not down, because a large tau can
collapse the samples onto one point (K ~ 1 1^T), a local minimum the last stage at a smaller tau does not
leave, so a downward path would score moderate taus at their over-smoothed neighbour's error. The first
solve of each gamma is warm-started the same way from the previous (smaller) gamma's, so a fold has one
cold solve (both when the estimator offers ``warm_start``). A path stops once a candidate's hold-out error
exceeds ``stop_factor`` (1.5 in the experiments) times the path's best so far: past that the samples are
collapsing and the solves are the slowest of the path. The fold solves can stop at looser tolerances than
the refit (``fold_params``): they only rank candidates. The folds are independent and run in parallel with
``n_jobs``. Every solve uses the isolation guard (:func:`nldr.regularizer.isolation_safe_rho0`), so large
tau cannot push hidden entries away. At large n, ``fold_params`` can put the fold solves on the Nystroem
kernel of m landmark rows (one evaluation O(n m^2) instead of O(n^2 r)); the fold scores are then those of
the approximate solve, and the refit stays exact (experiment ``selection_full``: 1000 rows, m = 200).

Limit (Table 2 at p <= 0.1; docs/REPRODUCTION.md, selection). There the ground-truth-best grid point
is usually a narrower kernel (0.5 times the median rule, tau = 0.01) whose advantage is fragile: hiding
a further 3 % of the observed entries raises its error on the truly missing entries by 38 % (p = 0.05)
and 106 % (p = 0.1) on average, against 1 % and 32 % for the widest kernel, so the hold-out folds,
which must hide entries, see the two about equal and every rule picks the wide one. More folds (20),
``rule="min"``, no warm starts across gamma, and folds hiding only 1.25 % (p = 0.05) or 2.8 %
(p = 0.1) of the observed entries did not bring the choice closer to that grid point.
"""

from ._folds import DEFAULT_TAUS, GAMMA_MULTIPLES, holdout_folds, median_gamma
from ._robust import HUBER_EFFICIENCY, RobustScaleDelta, robust_scale
from ._search import EntryFolds, HoldoutSearch

__all__ = [
    "HoldoutSearch",
    "EntryFolds",
    "DEFAULT_TAUS",
    "GAMMA_MULTIPLES",
    "median_gamma",
    "holdout_folds",
    "HUBER_EFFICIENCY",
    "RobustScaleDelta",
    "robust_scale",
]
