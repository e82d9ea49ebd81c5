"""Baselines the paper compares against: KPCA (Table 1) and imputation methods (Table 2); and the
imputers people already use (:mod:`.peers`: KNN, chained equations, missForest, SoftImpute; not in
the paper)."""

from .kpca import kpca_spectrum, project_points, spectral_kernel_errors, truncated_spectra
from .mean import mean_impute
from .nearest_neighbour import NearestNeighbourResult, nearest_neighbour_impute
from .peers import (
    SoftImputeResult,
    singular_value_threshold,
    soft_impute,
    soft_impute_objective,
)
from .pkpca import PKPCAResult, pkpca_impute
from .ppca import PPCAResult, ppca_impute
from .rkpca import RKPCAResult, rkpca_impute

__all__ = [
    "kpca_spectrum",
    "truncated_spectra",
    "spectral_kernel_errors",
    "project_points",
    "mean_impute",
    "NearestNeighbourResult",
    "nearest_neighbour_impute",
    "PPCAResult",
    "ppca_impute",
    "PKPCAResult",
    "pkpca_impute",
    "RKPCAResult",
    "rkpca_impute",
    "SoftImputeResult",
    "soft_impute",
    "singular_value_threshold",
    "soft_impute_objective",
]
