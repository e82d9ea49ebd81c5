"""scikit-learn imputers: NaN marks a missing entry. The paper's method and every baseline.

Each estimator has ``fit``, ``transform`` and ``fit_transform``, works in a ``Pipeline``, with
``clone`` and ``GridSearchCV``, and passes scikit-learn's ``check_estimator``. ``fit_transform(X)``
is the method's (transductive) answer on X; ``transform`` completes rows never seen against the
model learnt in ``fit`` (rows seen in ``fit`` get their fitted estimate; identical rows share one).
Every estimator keeps the observed entries, as scikit-learn's imputers do; the two that also estimate
them (:class:`RobustPCAImputer`, :class:`KernelRegularizerImputer`) return that estimate of every
entry, from ``fit_transform`` and ``transform`` alike, with ``denoise=True``. The solvers stay functions
underneath (:mod:`nldr.regularizer`, :mod:`nldr._baselines`); each estimator keeps its solver's
result object as ``result_`` where there is one.

- :class:`KernelRegularizerImputer`: the paper's method, the non-linear dimensionality regularizer.
- :class:`RobustKernelPCAImputer`: new rows completed (or denoised) against the closed-form robust
  kernel PCA of complete training rows; :class:`DecompositionDenoiser`: a decomposition (PCA, KernelPCA)
  as a denoiser.
- The paper's baselines (Table 2): :class:`PPCAImputer`, :class:`PKPCAImputer`,
  :class:`RKPCAImputer`, :class:`NearestNeighbourImputer` (1-NN).
- Peers not in the paper: :class:`SoftImputer` (nuclear-norm completion) and
  :class:`RobustPCAImputer` (linear Robust PCA, for gross errors).

Every estimator converts X to float64 and returns float64 arrays, a float32 X included: the solvers
run in float64 (docs/user_guide.md).

The mean baseline is scikit-learn's ``SimpleImputer``; ``KNNImputer`` and ``IterativeImputer`` are
scikit-learn's, used as they are.
"""

from ._kernel_pca import PKPCAImputer, RKPCAImputer
from ._linear import PPCAImputer, RobustPCAImputer, SoftImputer
from ._manifold import DecompositionDenoiser, RobustKernelPCAImputer
from ._neighbours import NearestNeighbourImputer
from ._regularizer import KernelRegularizerImputer

__all__ = [
    "KernelRegularizerImputer",
    "RobustKernelPCAImputer",
    "PPCAImputer",
    "PKPCAImputer",
    "RKPCAImputer",
    "NearestNeighbourImputer",
    "SoftImputer",
    "RobustPCAImputer",
    "DecompositionDenoiser",
]
