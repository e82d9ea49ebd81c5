"""Baselines the paper compares against: KPCA (Table 1) and imputation methods (Table 2)."""

from .kpca import kpca_spectrum, truncated_kernel

__all__ = ["kpca_spectrum", "truncated_kernel"]
