"""The paper's method as a scikit-learn imputer: :class:`KernelRegularizerImputer`."""

from __future__ import annotations

from numbers import Integral, Real

import numpy as np
from sklearn.utils import check_random_state
from sklearn.utils._param_validation import Interval, StrOptions

from .._baselines._masked import mean_fill, neighbour_fill, observed_standardisation
from .._options import last_stage_only, solver_options
from .._preimage import Subspace, average_solutions, complete_from_starts, nearest_rows
from ..data_terms import MaskedHuber, MaskedLeastSquares
from ..regularizer import minimize_regularized
from ._base import MaskedImputerBase
from ._defaults import (
    AUTO_EXACT_MAX_ROWS,
    AUTO_KNN_MIN_ROWS,
    AUTO_LANDMARK_RULE,
    AUTO_LANDMARKS,
    AUTO_NYSTROEM_TOL,
    AUTO_STAGE_TOL,
    DEFAULT_LANDMARKS,
    DEFAULT_TOL,
    EXACT_OPTIONS,
    FLAT_OPTIONS,
    INIT_MAX_DONORS,
    INIT_NEIGHBOURS,
    INITS,
    LOSSES,
    MEDIAN_RULE_MULTIPLE,
    METHODS,
    NYSTROEM_OPTIONS,
    TUNE_GAMMA_MULTIPLES,
    TUNE_LANDMARKS,
    TUNE_MAX_ROWS,
    TUNE_MIN_ROWS,
    TUNE_TAUS,
    TUNE_TOLERANCES,
    UNTUNED_TAU,
    median_rule_gamma,
)
from ._new_rows import NoComponentsError, regularizer_subspace
from ._tuning import is_auto, report_holdout, transform_candidates, tune, tune_transform

__all__ = ["KernelRegularizerImputer"]


class KernelRegularizerImputer(MaskedImputerBase):
    """Matrix completion with the non-linear dimensionality regularizer (Garg, Eriksson, Reid 2016).

    ``fit_transform(X)`` completes X by solving the paper's joint problem over the completed matrix
    and a kernel factor; ``fit`` keeps the learnt manifold, and ``transform`` completes new rows
    against it. Both keep the observed entries and fill the missing ones (an imputer);
    ``denoise=True`` returns the solve's estimate of every entry instead (a denoiser). With no
    arguments this is the recommended configuration (tau and the width chosen by hold-out on the
    observed entries inside ``fit``); the paper's Table 2 is ``KernelRegularizerImputer(
    standardize=False, gamma=0.075, tau=0.1, method="exact", denoise=True)``. The user
    guide (docs/user_guide.md) explains the problem, the defaults and the options.

    Parameters
    ----------
    missing_values : np.nan or float, default np.nan
        The marker of a missing entry (NaN is always missing too).
    gamma : float > 0, None or "auto", default "auto"
        RBF inverse squared width, in 1 / (units of the solved matrix)^2: standardised units when
        ``standardize``, the data's units otherwise. None: the median rule on the
        mean-imputed (standardised) matrix: :data:`MEDIAN_RULE_MULTIPLE` / (median squared distance
        between its rows). "auto": the hold-out search's choice among :data:`TUNE_GAMMA_MULTIPLES`
        / (that median squared distance), searched as ``tau`` (the median rule where not).
    tau : float > 0 or "auto", default "auto"
        Weight of the trace norm of C (the feature-space data's nuclear norm), in the data term's
        units (squared units of the solved matrix). Larger tau: a lower-dimensional manifold.
        "auto": the hold-out search's choice among :data:`TUNE_TAUS` from :data:`TUNE_MIN_ROWS`
        rows up to :data:`TUNE_MAX_ROWS` (excluded), :data:`UNTUNED_TAU` and the median rule's width
        outside (at scale the search costs more than the solve and does not beat the rule:
        docs/PERFORMANCE.md#defaults-at-scale). The search's folds hide
        :data:`TUNE_HOLDOUT` of the observed entries each (drawn from seed 0, rows sorted by content),
        its fold solves stop at looser tolerances and use the Nystroem kernel (100 pivoted landmarks) above
        :data:`AUTO_EXACT_MAX_ROWS` rows; the smallest mean squared hold-out error wins, in standardised
        units when ``standardize`` (so that no column decides by its units). A choice whose hold-out
        error is no better than the observed column means' on the same folds is reported:
        ``result_.success`` False and a ConvergenceWarning.
    standardize : bool, default True
        Solve on columns centred and scaled by their observed entries' mean and standard deviation
        (a constant column is only centred), and return the estimate in the data's units. False
        solves on X as given, the paper's setting.
    center : bool, default False
        Double-centre the kernel (the paper's Table 2 does not).
    method : {"auto", "exact", "nystroem", "nystroem-warm"}, default "auto"
        :func:`~nldr.regularizer.minimize_regularized`'s solver path. "exact": every penalty stage
        with the exact kernel. "nystroem-warm": the stages before the last on a Nystroem kernel of
        ``n_landmarks`` landmark rows, then the last stage exactly from there (an exact stopping
        test, possibly another local minimum: docs/PERFORMANCE.md). "nystroem": every stage on the
        Nystroem kernel of ``n_landmarks`` rows (not the exact minimiser). "auto": "exact" up to
        :data:`AUTO_EXACT_MAX_ROWS` rows; above, "nystroem" on :data:`AUTO_LANDMARKS` landmarks
        chosen by pivoted Cholesky of the start's kernel (``landmark_rule="pivoted"``: a function of
        the data, not of ``random_state``), the stages before the last stopping at ``stage_tol``
        :data:`AUTO_STAGE_TOL`: an approximate minimiser whose cost grows linearly in the rows
        (docs/PERFORMANCE.md#auto-landmarks).
    n_landmarks : int >= 1 or None, default None
        Landmark rows of the Nystroem kernel (``options["landmarks"]`` of
        :func:`~nldr.regularizer.minimize_regularized`), for the Nystroem paths only. None:
        :data:`DEFAULT_LANDMARKS` (100) for "nystroem" and "nystroem-warm", :data:`AUTO_LANDMARKS`
        for "auto" above :data:`AUTO_EXACT_MAX_ROWS` rows; ``method="exact"`` refuses it. "auto"
        ignores it at or below :data:`AUTO_EXACT_MAX_ROWS` rows.
    rho0 : float > 0, default 1.0
        First penalty weight of the schedule (kernel units against the data term's units; the
        paper's 1).
    rho_growth : float > 1, default 10.0
        Factor between consecutive penalty weights (the paper's 10).
    rho_max : float > 0, default 1e4
        Last penalty weight (the paper's 1e4; at least ``rho0``).
    max_iter : int >= 1, default 3000
        L-BFGS iterations per penalty stage (``options["max_inner"]`` of
        :func:`~nldr.regularizer.minimize_regularized`).
    tol : float > 0 or "auto", default "auto"
        A stage stops when the energy's relative decrease per L-BFGS iteration is below tol
        (L-BFGS's ``ftol``; dimensionless). "auto": :data:`DEFAULT_TOL` (1e-10), and
        :data:`AUTO_NYSTROEM_TOL` (1e-9) on "auto"'s approximate path above :data:`AUTO_EXACT_MAX_ROWS` rows.
    gtol : float > 0, default 1e-6
        ... or when the largest gradient entry is below gtol (in the stopping units: the solved
        matrix's units over ``sqrt(rho0)`` unless ``options["scale"]`` sets them).
    options : dict or None, default None
        The solver path's rarely tuned options, as :func:`~nldr.regularizer.minimize_regularized`
        takes them: ``stage_tol``, ``isolation_guard``, ``scale``, ``eigensolver``,
        ``landmark_seed``, ``landmark_rule``, and the Nystroem warm start's ``exact_stages``,
        ``exact_tol``, ``last_landmarks``. They stay in a dict because they change how a path runs rather than
        what it minimises, and none is worth a grid. An option the path does not take is a
        ValueError naming the path (raised by every fit, before any solve); the knobs above are
        parameters, not options. "auto" takes the options of "nystroem-warm"; at or below
        :data:`AUTO_EXACT_MAX_ROWS` rows it uses those of "exact", above only those of "nystroem"
        (``landmark_rule``, ``landmark_seed`` and the stopping options). With
        ``landmark_rule="random"`` (the explicit Nystroem paths' default) ``landmark_seed`` defaults
        to a draw from ``random_state``.
    init : {"auto", "mean", "knn"}, default "auto"
        The solve's start at the missing entries: "mean", the observed column means (the paper's);
        "knn", the mean of the :data:`INIT_NEIGHBOURS` nearest rows observing the entry, among at most
        :data:`INIT_MAX_DONORS` rows (:func:`nldr._baselines._masked.neighbour_fill`). "auto": "knn"
        for ``method="auto"`` from :data:`AUTO_KNN_MIN_ROWS` rows, whose approximate minimiser depends
        on the start and reaches a lower energy from there, else "mean"
        (docs/PERFORMANCE.md#the-start). The tuning's folds take the same start; the median rule's
        width is set on the mean fill either way; a warm start starts from the previous solve.
    verbose : bool, default False
        Print one line per penalty stage.
    n_neighbors : int >= 1 or "auto", default "auto"
        ``transform``: the training rows nearest to a new row on its observed entries, which give
        its starts.
    starts : {"mean", "each", "auto"}, default "auto"
        ``transform``: one start at the neighbours' mean, or one per neighbour with the local minima
        averaged (:meth:`nldr.robust_kpca.RobustKernelPCA.complete`). "auto" (either knob): the
        first ``transform`` of a row not seen in ``fit`` chooses (n_neighbors, starts) among the
        pairs :data:`TUNE_TRANSFORM` that agree with the fixed knob, by :data:`TUNE_FOLDS` row
        folds: the manifold fitted (at the chosen tau and width) on the other rows completes
        :data:`TUNE_ROW_SHARE` of the rows with a share of their observed
        entries hidden (the training matrix's missing share, at least :data:`TUNE_ROW_HIDDEN`).
    weights : {"uniform", "distance"}, default "uniform"
        ``transform`` with ``starts="each"``: how the local minima are averaged.
    random_state : int, RandomState or None, default 0
        Seeds the landmark draw of the explicit Nystroem paths' solve ("exact" and "auto" draw
        nothing). The tuning's folds do not depend on it: they are drawn from seed 0 on the rows
        sorted by their content (their fold solves' landmarks are pivots), so the chosen width and
        tau depend on the data alone, not on the row order or a seed. With the explicit Nystroem
        paths the default 0 makes two fits of one matrix identical; None draws the landmarks afresh.
    warm_start : bool, default False
        A fit after a previous fit on a matrix of the same shape starts from the previous solve's S
        (``result_.x``) and solves the last penalty stage only (rho0 = rho_max), its stopping tests in
        the units of the full schedule (``options["scale"]`` = sqrt(``rho0``) unless ``options``
        sets it). This is how a path of taus or widths is solved cheaply, e.g. by
        :class:`nldr.model_selection.HoldoutSearch` with ``path="tau"``. The first fit, or one on
        another shape, solves the full schedule from the ``init`` start. A fit on the previous fit's
        matrix that changes only ``n_neighbors``, ``starts``, ``weights`` or ``verbose`` keeps the
        previous solve (the same problem; a path over ``transform``'s knobs shares one fit).
    loss : {"squared", "huber"}, default "squared"
        The data term on the observed entries: masked least squares
        (:class:`~nldr.data_terms.MaskedLeastSquares`), or the masked Huber loss
        (:class:`~nldr.data_terms.MaskedHuber`: squared within ``delta``, linear beyond), for data
        with gross errors among the observed entries (to correct them, pass ``denoise=True``).
        ``transform`` of new rows is the same for both unless ``denoise`` (then the loss weighs
        their observed entries too).
    delta : float > 0, default 1.0
        The Huber threshold, in the units of the solved matrix (standardised units when
        ``standardize``); used with ``loss="huber"`` only.
        :class:`nldr.model_selection.RobustScaleDelta` sets it from a least-squares fit's residuals.
    denoise : bool, default False
        What ``fit_transform`` and ``transform`` return for the observed entries. False (an
        imputer): the observed entries as given, the missing ones estimated. True (a denoiser):
        the estimate of every entry: for the training rows the solve's S (whose observed entries the
        data term only pulls towards X), for new rows the point nearest their observed entries
        under the data loss (``loss``, ``delta``) plus ``rho_max`` times the squared feature-space
        distance to the learnt subspace, the same balance of data against manifold as the last
        penalty stage (:func:`nldr._preimage.complete_rows` with ``rho=rho_max``). The solve is
        the same either way (a warm refit that changes only ``denoise`` keeps it).

    Attributes
    ----------
    gamma_, tau_ : float
        The width and weight used (standardised units when ``standardize``).
    cv_results_ : dict of arrays
        The tau and width search's record (:attr:`nldr.model_selection.HoldoutSearch.cv_results_`),
        when ``gamma`` or ``tau`` is "auto" and the rows are at least :data:`TUNE_MIN_ROWS`.
    n_neighbors_, starts_ : int, str
        ``transform``'s neighbours and starts (set by ``fit`` when fixed or not searched, by the
        first ``transform`` of a new row when searched).
    transform_results_ : dict
        (n_neighbors, starts) -> mean squared error of the row folds, when they were searched.
    method_ : str
        The solver path used: "exact", "nystroem-warm" or "nystroem".
    mean_, scale_ : arrays, shape (n_features,)
        The standardisation (zeros and ones when ``standardize`` is False).
    result_ : nldr.regularizer.RegularizerResult
        The solve (its ``x`` in standardised units when ``standardize``).
    completed_ : array, shape (n_samples, n_features)
        The estimate of the training matrix, in the data's units.
    manifold_rows_ : array, shape (n_samples, n_features)
        S, the rows of the learnt manifold (standardised units when ``standardize``).
    kernel_factor_ : array, shape (n_components_, n_samples)
        The non-zero rows of C (``diag(l) U^T``).
    n_components_ : int
        Rank of C: the dimension of the learnt manifold's principal subspace.
    n_features_in_ : int
    feature_names_in_ : array of str (when X has string column names)

    See Also
    --------
    nldr.regularizer.minimize_regularized : The solver underneath, for any data term.
    nldr.model_selection.HoldoutSearch : The hold-out search that chooses tau and the width.
    RobustKernelPCAImputer : New rows against a manifold learnt once from complete rows.

    Notes
    -----
    ``fit`` solves

        min ||mask o (X - S)||_F^2 + rho/2 ||K(S) - C^T C||_F^2 + tau ||C||_*

    over the completed matrix S and the kernel factor C, with the RBF kernel
    ``K_ij = exp(-gamma ||s_i - s_j||^2)``, by the penalty method on rho from the ``init`` start. The
    estimate of a training row's missing entries is the solve's S there (its observed entries move
    slightly too, the data term being a penalty: ``denoise=True`` returns them); ``transform`` keeps
    the observed entries of new rows and moves the missing ones to the pre-image nearest the learnt
    subspace (:mod:`nldr._preimage`). Identical training rows share one estimate (the mean of the
    solve's copies). Stability: the width and tau chosen by "auto" depend on the rows as a set; the
    solve itself depends on the row order and on rounding-level changes of X only within its
    stopping tolerances (docs/user_guide.md#stability).

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[1.0, 2.0, 3.0], [2.0, np.nan, 5.9], [3.0, 6.1, 9.0],
    ...               [4.0, 7.9, np.nan], [5.0, 9.9, 15.1], [6.0, 12.0, 18.0]])
    >>> from nldr.impute import KernelRegularizerImputer
    >>> X_hat = KernelRegularizerImputer().fit_transform(X)
    >>> X_hat.shape, bool(np.isnan(X_hat).any())
    ((6, 3), False)
    >>> np.round(X_hat[[1, 3], [1, 2]])  # the missing entries, near 4 and 12
    array([ 4., 12.])
    """

    def __init__(
        self,
        missing_values=np.nan,
        *,
        gamma="auto",
        tau="auto",
        standardize=True,
        center=False,
        method="auto",
        n_landmarks=None,
        rho0=1.0,
        rho_growth=10.0,
        rho_max=1e4,
        max_iter=3000,
        tol="auto",
        gtol=1e-6,
        options=None,
        init="auto",
        verbose=False,
        n_neighbors="auto",
        starts="auto",
        weights="uniform",
        random_state=0,
        warm_start=False,
        loss="squared",
        delta=1.0,
        denoise=False,
    ):
        self.missing_values = missing_values
        self.gamma = gamma
        self.tau = tau
        self.standardize = standardize
        self.center = center
        self.method = method
        self.n_landmarks = n_landmarks
        self.rho0 = rho0
        self.rho_growth = rho_growth
        self.rho_max = rho_max
        self.max_iter = max_iter
        self.tol = tol
        self.gtol = gtol
        self.options = options
        self.init = init
        self.verbose = verbose
        self.n_neighbors = n_neighbors
        self.starts = starts
        self.weights = weights
        self.random_state = random_state
        self.warm_start = warm_start
        self.loss = loss
        self.delta = delta
        self.denoise = denoise

    _min_samples = 2

    _parameter_constraints: dict = {
        **MaskedImputerBase._parameter_constraints,
        "gamma": [Interval(Real, 0, np.inf, closed="neither"), None, StrOptions({"auto"})],
        "tau": [Interval(Real, 0, np.inf, closed="neither"), StrOptions({"auto"})],
        "standardize": ["boolean"],
        "center": ["boolean"],
        "method": [StrOptions(set(METHODS))],
        "n_landmarks": [Interval(Integral, 1, None, closed="left"), None],
        "rho0": [Interval(Real, 0, np.inf, closed="neither")],
        "rho_growth": [Interval(Real, 1, np.inf, closed="neither")],
        "rho_max": [Interval(Real, 0, np.inf, closed="neither")],
        "max_iter": [Interval(Integral, 1, None, closed="left")],
        "tol": [Interval(Real, 0, np.inf, closed="neither"), StrOptions({"auto"})],
        "gtol": [Interval(Real, 0, np.inf, closed="neither")],
        "options": [dict, None],
        "init": [StrOptions(set(INITS))],
        "verbose": ["verbose"],
        "n_neighbors": [Interval(Integral, 1, None, closed="left"), StrOptions({"auto"})],
        "starts": [StrOptions({"mean", "each", "auto"})],
        "weights": [StrOptions({"uniform", "distance"})],
        "random_state": ["random_state"],
        "warm_start": ["boolean"],
        "loss": [StrOptions(set(LOSSES))],
        "delta": [Interval(Real, 0, np.inf, closed="neither")],
        "denoise": ["boolean"],
    }

    def _validate_params(self) -> None:
        """The constraints above, each parameter alone; then the rules that tie parameters together
        (run by ``fit`` before anything else, and by HoldoutSearch on every candidate before any fit)."""
        super()._validate_params()
        if self.rho_max < self.rho0:
            raise ValueError(f"rho_max ({self.rho_max!r}) must be at least rho0 ({self.rho0!r})")
        if self.method == "exact" and self.n_landmarks is not None:
            raise ValueError("n_landmarks applies to the Nystroem paths; with method='exact' set it to None")
        flat = sorted(set(self.options or {}) & {*FLAT_OPTIONS, *FLAT_OPTIONS.values()})
        if flat:
            names = {v: k for k, v in FLAT_OPTIONS.items()}
            hint = ", ".join(f"{names.get(k, k)}=" for k in flat)
            raise ValueError(f"options {flat} are parameters of {type(self).__name__}: pass {hint}")
        options = self._solver_options()
        if self.method != "exact":
            options.setdefault("landmark_seed", 0)  # drawn from random_state at fit
        solver_options("nystroem-warm" if self.method == "auto" else self.method, options)

    def _solver_options(self) -> dict:
        """minimize_regularized's options: ``options`` with the flat parameters written in."""
        options = dict(self.options or {})
        tol = DEFAULT_TOL if is_auto(self.tol) else self.tol
        options.update(max_inner=self.max_iter, tol=tol, gtol=self.gtol)
        if self.n_landmarks is not None:
            options["landmarks"] = self.n_landmarks
        elif self.method == "nystroem":  # "nystroem-warm" has the same default in its options record
            options["landmarks"] = DEFAULT_LANDMARKS
        return options

    def _standardisation(self, W, mask):
        if not self.standardize:
            return np.zeros(W.shape[1]), np.ones(W.shape[1])
        return observed_standardisation(W, mask)

    def _solver_arguments(self, n: int, warm: bool) -> tuple[str, dict]:
        """The solver path and minimize_regularized's keyword arguments (checked by
        _validate_params). ``warm``: the last penalty stage only, in the stopping units of the full
        schedule."""
        method = self.method
        if method == "auto":
            method = "exact" if n <= AUTO_EXACT_MAX_ROWS else "nystroem"
        schedule = {"rho0": self.rho0, "rho_growth": self.rho_growth, "rho_max": self.rho_max}
        options = self._solver_options()
        if method == "exact":
            options = {k: v for k, v in options.items() if k in EXACT_OPTIONS}
        elif self.method == "auto":
            kept = {k: v for k, v in options.items() if k in NYSTROEM_OPTIONS}
            auto = {"landmarks": AUTO_LANDMARKS, "landmark_rule": AUTO_LANDMARK_RULE}
            options = {**auto, "stage_tol": AUTO_STAGE_TOL, **kept}
            options["tol"] = AUTO_NYSTROEM_TOL if is_auto(self.tol) else options["tol"]
        drawn = method != "exact" and options.get("landmark_rule", "random") == "random"
        if drawn and "landmark_seed" not in options:
            options["landmark_seed"] = int(
                check_random_state(self.random_state).randint(np.iinfo(np.int32).max)
            )
        kwargs = {"method": method, "options": options, "verbose": bool(self.verbose), **schedule}
        return method, last_stage_only(kwargs) if warm else kwargs

    def _grid(self, gamma, tau, median_rule: float) -> dict:
        """The tuning's candidates: every "auto" knob over its grid, the others at their one value."""
        if is_auto(gamma):
            gammas = [float(m * median_rule / MEDIAN_RULE_MULTIPLE) for m in TUNE_GAMMA_MULTIPLES]
        else:
            gammas = [median_rule if gamma is None else float(gamma)]
        return {"gamma": gammas, "tau": [float(t) for t in TUNE_TAUS] if is_auto(tau) else [float(tau)]}

    def _tune_seed(self) -> int:
        """The seed of the tuning's folds (and of their landmarks if ``options`` asks for a random draw):
        fixed, so that the chosen knobs depend on the data (rows in canonical order) only."""
        return 0

    def _start(self, n: int) -> str:
        """What ``init`` resolves to on n rows ("auto": "knn" on method="auto" from AUTO_KNN_MIN_ROWS)."""
        if self.init != "auto":
            return self.init
        return "knn" if self.method == "auto" and n >= AUTO_KNN_MIN_ROWS else "mean"

    def _fold_solver(self, n: int) -> dict:
        """The tuning's fold solves: the exact kernel up to AUTO_EXACT_MAX_ROWS rows, the Nystroem kernel
        above, at looser tolerances (they only rank candidates), from the final solve's start."""
        common = {"init": self._start(n), **TUNE_TOLERANCES}
        if n <= AUTO_EXACT_MAX_ROWS:
            options = {k: v for k, v in (self.options or {}).items() if k in EXACT_OPTIONS}
            return {"method": "exact", "n_landmarks": None, "options": options or None, **common}
        options = {k: v for k, v in (self.options or {}).items() if k in NYSTROEM_OPTIONS}
        options = {"landmark_seed": self._tune_seed(), "landmark_rule": AUTO_LANDMARK_RULE, **options}
        landmarks = TUNE_LANDMARKS if self.n_landmarks is None else self.n_landmarks
        return {"method": "nystroem", "n_landmarks": landmarks, "options": options, **common}

    def _solve(self, W, mask):
        gamma = None if self.gamma is None else self.gamma if is_auto(self.gamma) else float(self.gamma)
        tau = "auto" if is_auto(self.tau) else float(self.tau)
        if self._keeps_solve(W, mask):  # a warm refit that changes only transform's knobs
            self._transform_knobs(W.shape[0])
            return self._estimate, self.result_
        self.__dict__.pop("_solved_key", None)
        self.mean_, self.scale_ = self._standardisation(W, mask)
        Z = W if not self.standardize else np.where(mask, (W - self.mean_) / self.scale_, 0.0)
        filled = S0 = mean_fill(Z, mask)
        previous = getattr(self, "_estimate", None) if self.warm_start else None
        warm = previous is not None and previous.shape == W.shape
        if warm:  # the previous estimate, in this fit's (standardised) units
            S0 = previous if not self.standardize else (previous - self.mean_) / self.scale_
        elif self._start(W.shape[0]) == "knn":
            S0 = neighbour_fill(Z, mask, INIT_NEIGHBOURS, INIT_MAX_DONORS)
        median_rule = median_rule_gamma(filled) if gamma is None or is_auto(gamma) else None
        grid = self._grid(gamma, tau, median_rule)
        tuned = (is_auto(gamma) or is_auto(tau)) and TUNE_MIN_ROWS <= W.shape[0] < TUNE_MAX_ROWS
        self.__dict__.pop("_holdout_against_means", None)
        if tuned:
            chosen = tune(self, Z, mask, grid)  # scored in the solved (standardised) units
        else:
            self.__dict__.pop("cv_results_", None)
            chosen = {
                "gamma": median_rule if is_auto(gamma) else grid["gamma"][0],
                "tau": UNTUNED_TAU if is_auto(tau) else grid["tau"][0],
            }
        self.gamma_, self.tau_ = float(chosen["gamma"]), float(chosen["tau"])
        self._transform_knobs(W.shape[0])
        self._training = (W, mask)
        self.method_, kwargs = self._solver_arguments(W.shape[0], warm)
        result = minimize_regularized(
            self._data_term(Z, mask), S0, gamma=self.gamma_, tau=self.tau_, center=bool(self.center), **kwargs
        )
        S = result.x
        self.manifold_rows_ = S
        keep = np.flatnonzero(np.any(result.C != 0.0, axis=1))
        self.kernel_factor_ = result.C[keep]
        self.n_components_ = int(keep.size)
        self._space = None  # built by the first transform of a new row
        self._solved_key = self._solve_key()
        X_hat = S if not self.standardize else S * self.scale_ + self.mean_
        self._estimate = X_hat  # the solve's S in the data's units (the next warm start's start)
        report_holdout(self, result)
        return X_hat, result

    def _mean_fill_cause(self) -> str:
        return (
            f"tau (= {self.tau_:g}) far too large, or the data's units with standardize=False (tau, rho0 "
            "and gtol are in the solved matrix's units: for data scaled by s, scale tau and rho0 by s^2 "
            "and gtol by s, or standardize)"
        )

    def _solve_key(self) -> tuple:
        """The parameters the solve depends on (all but transform's knobs and verbose), comparable."""
        params = self.get_params(deep=False)
        ignored = {"n_neighbors", "starts", "weights", "warm_start", "verbose", "denoise"}
        return tuple((name, repr(params[name])) for name in sorted(set(params) - ignored))

    def _keeps_solve(self, W, mask) -> bool:
        """A warm fit on the previous fit's matrix that changes only transform's knobs keeps its solve."""
        training = getattr(self, "_training", None)
        return bool(
            self.warm_start
            and training is not None
            and getattr(self, "_solved_key", None) == self._solve_key()
            and np.array_equal(training[0], W)
            and np.array_equal(training[1], mask)
        )

    def _transform_knobs(self, n: int) -> None:
        """Reset transform's knobs: set now when fixed (or below TUNE_MIN_ROWS rows), else by a new row."""
        for name in ("transform_results_", "n_neighbors_", "starts_"):
            self.__dict__.pop(name, None)
        pairs = transform_candidates(self)
        if len(pairs) == 1 or n < TUNE_MIN_ROWS:
            self.n_neighbors_, self.starts_ = int(pairs[0][0]), str(pairs[0][1])

    def _data_term(self, Z, mask):
        """The data term on the solved matrix Z: masked least squares, or Huber (delta in Z's units)."""
        return MaskedHuber(Z, mask, self.delta) if self.loss == "huber" else MaskedLeastSquares(Z, mask)

    def _subspace(self) -> Subspace:
        """C's rows' principal subspace, as :mod:`nldr._preimage` takes it (built once per solve)."""
        space = getattr(self, "_space", None)
        if space is None:
            space = self._space = regularizer_subspace(
                self.manifold_rows_, self.gamma_, self.kernel_factor_, bool(self.center)
            )
        return space

    def _complete(self, W, mask):
        if self.n_components_ == 0:
            raise NoComponentsError(
                f"the fitted manifold has no component (tau = {self.tau_:g} removed them all): "
                "transform cannot complete new rows; lower tau"
            )
        Z = np.where(mask, (W - self.mean_) / self.scale_, 0.0)
        S = self.manifold_rows_
        if not hasattr(self, "n_neighbors_"):  # "auto": chosen once, before the first new row
            W_fit, mask_fit = self._training
            Z_fit = np.where(mask_fit, (W_fit - self.mean_) / self.scale_, 0.0)  # scored in solved units
            k, starts = tune_transform(self, Z_fit, mask_fit, self.gamma_, self.tau_)
            self.n_neighbors_, self.starts_ = int(k), str(starts)
        n_neighbors, starts = self.n_neighbors_, self.starts_
        nearest, distance = nearest_rows(S, Z, mask, min(n_neighbors, S.shape[0]))
        rows = S[nearest]
        rows[~mask.any(axis=1)] = S.mean(axis=0)
        if starts == "mean":
            rows = rows.mean(axis=1, keepdims=True)
        X0 = np.where(mask[:, None, :], Z[:, None, :], rows)
        denoise = {}
        if self.denoise:  # the observed entries free too: the last stage's balance of data and manifold
            delta = float(self.delta) if self.loss == "huber" else None
            denoise = {"rho": float(self.rho_max), "loss": self.loss, "delta": delta}
        X_hat = complete_from_starts(self._subspace(), Z, mask, X0, **denoise)
        X_hat = X_hat[:, 0] if starts == "mean" else average_solutions(X_hat, distance, self.weights)
        X_hat = X_hat * self.scale_ + self.mean_
        return X_hat if self.denoise else np.where(mask, W, X_hat)
