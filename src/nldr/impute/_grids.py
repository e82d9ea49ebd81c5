"""Default hold-out grids of the baselines and peers, as ``(estimator, param_grid)`` for
:class:`~nldr.model_selection.HoldoutSearch` (:func:`baseline_grid`)."""

from __future__ import annotations

import numpy as np
from sklearn.ensemble import ExtraTreesRegressor

# IterativeImputer is still "experimental" in scikit-learn (1.6-1.9): it is importable only after this
# import, which registers it in sklearn.impute. The import has that side effect only.
from sklearn.experimental import enable_iterative_imputer  # noqa: F401
from sklearn.impute import IterativeImputer, KNNImputer
from sklearn.linear_model import BayesianRidge

from .._baselines._masked import mean_fill, observed_standardisation
from .._validation import as_float_matrix
from ..model_selection._folds import GAMMA_MULTIPLES, median_gamma
from ._kernel_pca import PKPCAImputer, RKPCAImputer
from ._linear import PPCAImputer, RobustPCAImputer, SoftImputer

__all__ = [
    "BASELINES",
    "SOFT_IMPUTE_FRACTIONS",
    "MISSFOREST_TREES",
    "GPLVM_LATENT",
    "GPLVM_INDUCING",
    "baseline_grid",
    "iterative_imputer",
    "missforest_imputer",
]

#: The names :func:`baseline_grid` knows: the paper's baselines with a knob, then the peers.
BASELINES = (
    "PPCA",
    "PKPCA",
    "RKPCA",
    "KNNImputer",
    "IterativeImputer",
    "missForest",
    "SoftImpute",
    "RPCA",
    "GP-LVM",
)
#: missForest's trees per column and sweep: its authors' recommendation and ExtraTreesRegressor's default
MISSFOREST_TREES = 100
#: GP-LVM's grid: latent dimensions and inducing points (each capped below the matrix's columns / rows)
GPLVM_LATENT = (2, 5)
GPLVM_INDUCING = (15, 30)
#: SoftImpute's lam grid, as fractions of the largest singular value of the centred mean-filled matrix
#: (the lam at which Z = 0): two and a half decades below it.
SOFT_IMPUTE_FRACTIONS = (0.003, 0.01, 0.03, 0.1, 0.3)


def iterative_imputer(*, max_iter: int = 10, tol: float = 1e-3, random_state: int = 0) -> IterativeImputer:
    """scikit-learn's ``IterativeImputer`` with ``BayesianRidge`` from the column means, every column in
    ascending order of missing entries (its defaults, written out): chained-equation imputation."""
    return IterativeImputer(
        estimator=BayesianRidge(),
        initial_strategy="mean",
        imputation_order="ascending",
        max_iter=max_iter,
        tol=tol,
        random_state=random_state,
        keep_empty_features=False,
    )


def missforest_imputer(
    *,
    max_features: float = 1.0,
    n_estimators: int = MISSFOREST_TREES,
    max_iter: int = 5,
    random_state: int = 0,
) -> IterativeImputer:
    """missForest (Stekhoven & Buehlmann 2012) in scikit-learn's form: ``IterativeImputer`` with an
    ``ExtraTreesRegressor`` per column, from the column means (as scikit-learn's own example).

    ``max_features``: share of the predictor columns drawn at each split (1.0: all; missForest's sqrt
    rule is about 0.3 at d = 12), the knob of :func:`baseline_grid` (``estimator__max_features``).
    ``n_estimators``: trees per column and sweep (:data:`MISSFOREST_TREES`, missForest's and
    scikit-learn's default). ``max_iter``: sweeps (random
    trees never meet scikit-learn's ``tol``, so all run; on oil flow 5 are as good as 10).
    ``random_state`` seeds the trees.
    """
    forest = ExtraTreesRegressor(
        n_estimators=n_estimators,
        max_features=max_features,
        min_samples_leaf=1,
        random_state=random_state,
        n_jobs=1,
    )
    return IterativeImputer(
        estimator=forest,
        initial_strategy="mean",
        imputation_order="ascending",
        max_iter=max_iter,
        tol=1e-3,
        random_state=random_state,
        keep_empty_features=False,
    )


def baseline_grid(
    method: str, X, *, n_trees: int = MISSFOREST_TREES, standardize: bool = True
) -> tuple[object, dict]:
    """Default ``(estimator, param_grid)`` of a baseline or a peer, for
    :class:`~nldr.model_selection.HoldoutSearch`.

    The paper's baselines with a knob (Table 2):

    - ``"PPCA"``: latent dimension 1 .. d-1.
    - ``"PKPCA"``: width (multiples :data:`GAMMA_MULTIPLES` of :func:`median_gamma`) and components
      (the variance rule, or 2, 4, 8).
    - ``"RKPCA"``: width as PKPCA, components 2, 4, 7, 10 (below n).

    The peers (not in the paper):

    - ``"KNNImputer"``: scikit-learn's, ``n_neighbors`` 1, 2, 3, 5, 10, 20, 50 (below n) x ``weights``
      uniform, distance.
    - ``"IterativeImputer"``: :func:`iterative_imputer`; no knob (BayesianRidge learns its own
      penalty): the grid is the one fixed setting, ``{}``.
    - ``"missForest"``: :func:`missforest_imputer`, ``max_features`` 1/3 and 1; ``n_trees`` trees
      (default :data:`MISSFOREST_TREES`), 5 sweeps.
    - ``"SoftImpute"``: ``lam`` = :data:`SOFT_IMPUTE_FRACTIONS` times the largest singular value of the
      centred mean-filled matrix (at that value and above, Z = 0).
    - ``"RPCA"``: principal component pursuit, ``lam_factor`` 0.5, 1, 2 (times Candes et al.'s weight).
    - ``"GP-LVM"``: :class:`nldr.impute._gplvm.GPLVMImputer` (needs GPy), ``n_latent``
      :data:`GPLVM_LATENT` (below d) x ``n_inducing`` :data:`GPLVM_INDUCING` (at most n).

    Parameters
    ----------
    method : one of :data:`BASELINES`
    X : array, shape (n, d), NaN where missing (the grid's widths and sizes depend on it).
    n_trees : int, default :data:`MISSFOREST_TREES`
        missForest's trees per column (the other methods ignore it).
    standardize : bool, default True
        The ``standardize`` of the library's imputers (PPCA, PKPCA, RKPCA, SoftImpute, RPCA; the
        others ignore it); the grids' widths and ``lam`` are in the units those imputers solve in
        (X's columns standardised by their observed entries, or X's own units when False).

    Returns
    -------
    estimator : an unfitted imputer
    param_grid : dict of parameter name -> list of candidate values (every combination is a candidate)
    """
    if method not in BASELINES:
        raise ValueError(f"method must be one of {', '.join(map(repr, BASELINES))}; got {method!r}")
    X = as_float_matrix(X, "X", allow_nan=True)
    mask = ~np.isnan(X)
    n, d = X.shape
    if not isinstance(standardize, bool | np.bool_):
        raise ValueError(f"standardize must be a bool; got {standardize!r}")
    ours = {"standardize": bool(standardize)}
    if standardize and mask.any(axis=0).all():  # the grids in the units the imputers solve in
        shift, scale = observed_standardisation(np.where(mask, X, 0.0), mask)
        X = np.where(mask, (X - shift) / scale, np.nan)
    if method == "KNNImputer":
        neighbours = [k for k in (1, 2, 3, 5, 10, 20, 50) if k < n]
        return KNNImputer(), {"n_neighbors": neighbours, "weights": ["uniform", "distance"]}
    if method == "IterativeImputer":
        return iterative_imputer(), {}
    if method == "missForest":
        if isinstance(n_trees, bool) or not isinstance(n_trees, int | np.integer) or n_trees < 1:
            raise ValueError(f"n_trees must be a positive integer; got {n_trees!r}")
        return missforest_imputer(n_estimators=int(n_trees)), {"estimator__max_features": [1 / 3, 1.0]}
    if method == "GP-LVM":
        from ._gplvm import GPLVMImputer  # GPy is optional: imported only when asked for

        latent = sorted({min(q, d - 1) for q in GPLVM_LATENT if d > 1})
        inducing = sorted({min(m, n) for m in GPLVM_INDUCING})
        return GPLVMImputer(), {"n_latent": latent, "n_inducing": inducing}
    if method == "PPCA":
        return PPCAImputer(**ours), {"n_components": list(range(1, d))}
    if method == "SoftImpute":
        filled = mean_fill(np.where(mask, X, 0.0), mask)
        top = float(np.linalg.svd(filled - filled.mean(axis=0), compute_uv=False)[0])
        return SoftImputer(**ours), {"lam": [float(f * top) for f in SOFT_IMPUTE_FRACTIONS]}
    if method == "RPCA":
        return RobustPCAImputer(**ours), {"lam_factor": [0.5, 1.0, 2.0]}
    gammas = [float(g) for g in np.asarray(GAMMA_MULTIPLES) * median_gamma(np.where(mask, X, 0.0), mask)]
    if method == "PKPCA":
        components = [None] + [q for q in (2, 4, 8) if q < n]
        return PKPCAImputer(**ours), {"gamma": gammas, "n_components": components}
    return RKPCAImputer(**ours), {"gamma": gammas, "n_components": [q for q in (2, 4, 7, 10) if q < n]}
