"""The options of :func:`nldr.regularizer.minimize_regularized`, one frozen record per ``method``.

``minimize_regularized(..., method=..., options={...})`` checks the mapping against the method's own
record here: an unknown key is a ValueError naming the method and listing its options, and every value
is validated once, so the solver's inner functions read a record that cannot change under them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ._spectral import check_eigensolver
from ._validation import check_count, check_flag, check_positive

__all__ = [
    "ExactOptions",
    "NystroemOptions",
    "NystroemWarmOptions",
    "METHODS",
    "solver_options",
    "merge_solver_kwargs",
    "last_stage_only",
    "DEFAULT_RHO0",
    "DEFAULT_RHO_MAX",
]

#: :func:`nldr.regularizer.minimize_regularized`'s default first and last penalty weights
DEFAULT_RHO0 = 1.0
DEFAULT_RHO_MAX = 1e4


#: ``options["landmark_rule"]`` of the Nystroem paths
LANDMARK_RULES = ("random", "pivoted")


def _check_rule(value, name: str) -> str:
    if not isinstance(value, str) or value not in LANDMARK_RULES:
        raise ValueError(f"{name} must be one of {list(LANDMARK_RULES)}; got {value!r}")
    return value


def _check_seed(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 0:
        raise ValueError(f"{name} must be an integer >= 0 (a seed of numpy's default_rng); got {value!r}")
    return int(value)


@dataclass(frozen=True, kw_only=True)
class _StoppingOptions:
    """Options every method takes: the stages' iteration limit and stopping tests, the isolation guard.

    Attributes
    ----------
    max_inner : int >= 1, default 3000
        Per-stage limit of L-BFGS iterations.
    tol : float > 0, default 1e-10
        Stage convergence (the L-BFGS ``ftol``): relative energy decrease per iteration.
    gtol : float > 0, default 1e-6
        L-BFGS also stops when the largest gradient entry is below gtol.
    stage_tol : float > 0 or None, default None
        ``tol`` of every stage but the last; None means ``tol``.
    isolation_guard : bool, default True
        Start the schedule at ``max(rho0, isolation_safe_rho0(tau))`` (module :mod:`nldr._schedule`).
    scale : float > 0 or None, default None
        The length unit of the stopping tests, in the units of S (energies in ``scale**2``); None
        means ``sqrt(rho0)`` (see :func:`nldr.regularizer.minimize_regularized`).
    """

    max_inner: int = 3000
    tol: float = 1e-10
    gtol: float = 1e-6
    stage_tol: float | None = None
    isolation_guard: bool = True
    scale: float | None = None

    def __post_init__(self):
        self._set("max_inner", check_count(self.max_inner, "options['max_inner']"))
        self._set("tol", check_positive(self.tol, "options['tol']"))
        self._set("gtol", check_positive(self.gtol, "options['gtol']"))
        if self.stage_tol is not None:
            self._set("stage_tol", check_positive(self.stage_tol, "options['stage_tol']"))
        self._set("isolation_guard", check_flag(self.isolation_guard, "options['isolation_guard']"))
        if self.scale is not None:
            self._set("scale", check_positive(self.scale, "options['scale']"))

    def _set(self, name, value):
        object.__setattr__(self, name, value)

    @property
    def tols(self) -> tuple[float, float]:
        """``(tol of every stage but the last, tol of the last)``."""
        return (self.tol if self.stage_tol is None else self.stage_tol), self.tol


@dataclass(frozen=True, kw_only=True)
class ExactOptions(_StoppingOptions):
    """Options of ``method="exact"``: the stopping options and the C-step's eigensolver.

    Attributes
    ----------
    eigensolver : {"auto", "partial", "krylov", "full"}, default "auto"
        The C-step's decomposition (see :func:`nldr.regularizer.minimize_regularized`).
    """

    eigensolver: str = "auto"

    def __post_init__(self):
        super().__post_init__()
        self._set("eigensolver", check_eigensolver(self.eigensolver))


@dataclass(frozen=True, kw_only=True)
class NystroemOptions(_StoppingOptions):
    """Options of ``method="nystroem"``: the stopping options and the landmarks.

    Attributes
    ----------
    landmarks : int >= 1 (required)
        Number of landmark samples; ``landmarks >= n_samples`` runs the exact kernel.
    landmark_seed : int >= 0, default 0
        Seed of the landmark draw (``landmark_rule="random"``).
    landmark_rule : {"random", "pivoted"}, default "random"
        How the landmarks are chosen: a uniform draw without replacement from ``landmark_seed``, or
        the pivots of a greedy pivoted Cholesky factorisation of the start's kernel
        (:func:`nldr._nystroem.pivoted_landmarks`: deterministic, isolated samples included).
    """

    landmarks: int
    landmark_seed: int = 0
    landmark_rule: str = "random"

    def __post_init__(self):
        super().__post_init__()
        self._set("landmarks", check_count(self.landmarks, "options['landmarks']"))
        self._set("landmark_seed", _check_seed(self.landmark_seed, "options['landmark_seed']"))
        self._set("landmark_rule", _check_rule(self.landmark_rule, "options['landmark_rule']"))


@dataclass(frozen=True, kw_only=True)
class NystroemWarmOptions(_StoppingOptions):
    """Options of ``method="nystroem-warm"``: Nystroem stages, then the last ``exact_stages`` exact.

    Attributes
    ----------
    landmarks : int >= 1, default 100
    landmark_seed : int >= 0, default 0
    landmark_rule : {"random", "pivoted"}, default "random"
        As :class:`NystroemOptions`.
    exact_stages : int >= 1, default 1
        Number of final stages solved with the exact kernel.
    exact_tol : float > 0 or None, default None
        Plateau test of the exact stages (see :func:`nldr.regularizer.minimize_regularized`).
    last_landmarks : int >= 1 or None, default None
        Landmarks of the last Nystroem stage; None means ``landmarks``.
    eigensolver : {"auto", "partial", "krylov", "full"}, default "auto"
        The exact stages' decomposition.
    """

    landmarks: int = 100
    landmark_seed: int = 0
    landmark_rule: str = "random"
    exact_stages: int = 1
    exact_tol: float | None = None
    last_landmarks: int | None = None
    eigensolver: str = "auto"

    def __post_init__(self):
        super().__post_init__()
        self._set("landmarks", check_count(self.landmarks, "options['landmarks']"))
        self._set("landmark_seed", _check_seed(self.landmark_seed, "options['landmark_seed']"))
        self._set("landmark_rule", _check_rule(self.landmark_rule, "options['landmark_rule']"))
        self._set("exact_stages", check_count(self.exact_stages, "options['exact_stages']"))
        if self.exact_tol is not None:
            self._set("exact_tol", check_positive(self.exact_tol, "options['exact_tol']"))
        if self.last_landmarks is not None:
            self._set("last_landmarks", check_count(self.last_landmarks, "options['last_landmarks']"))
        self._set("eigensolver", check_eigensolver(self.eigensolver))


#: ``method`` -> its options record.
METHODS = {"exact": ExactOptions, "nystroem": NystroemOptions, "nystroem-warm": NystroemWarmOptions}


def solver_options(method, options: Mapping | None):
    """The options record of ``method`` built from the mapping ``options`` (None: the defaults).

    Raises a ValueError for an unknown method, an option the method does not take (naming the method
    and listing its options), a missing required option, or a value out of range.
    """
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"method must be one of {sorted(METHODS)}; got {method!r}")
    if options is None:
        options = {}
    if not isinstance(options, Mapping):
        raise ValueError(f"options must be a mapping (dict) or None; got {type(options).__name__}")
    record = METHODS[method]
    fields = [f.name for f in dataclasses.fields(record)]
    unknown = sorted(set(options) - set(fields))
    if unknown:
        names = ", ".join(map(repr, unknown))
        raise ValueError(f"method {method!r} takes no option {names}; its options are {', '.join(fields)}")
    required = [
        f.name
        for f in dataclasses.fields(record)
        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    ]
    missing = [name for name in required if name not in options]
    if missing:
        raise ValueError(f"method {method!r} needs the option(s) {', '.join(map(repr, missing))}")
    return record(**options)


def merge_solver_kwargs(*kwargs: Mapping | None) -> dict:
    """Merge mappings of :func:`nldr.regularizer.minimize_regularized` keyword arguments, later ones
    winning; their ``options`` mappings are merged key by key rather than replaced. No validation."""
    merged: dict = {}
    for kw in kwargs:
        kw = dict(kw or {})
        options = {**(merged.get("options") or {}), **(kw.pop("options", None) or {})}
        merged.update(kw)
        if options:
            merged["options"] = options
    return merged


def last_stage_only(
    kwargs: Mapping, *, rho0: float = DEFAULT_RHO0, rho_max: float = DEFAULT_RHO_MAX
) -> dict:
    """:func:`nldr.regularizer.minimize_regularized`'s keyword arguments for the last penalty stage
    alone, with the stopping tests in the units of the full schedule.

    A warm start (a path of taus or widths, each solve starting from its neighbour's answer) skips
    the early stages, whose only purpose is to reach the neighbourhood of a minimiser from a poor
    start. Solving ``rho0 = rho_max`` alone would also move the stopping tests' length unit, which
    defaults to ``sqrt(rho0)``; so the unit is pinned to the full schedule's, ``options["scale"] =
    sqrt(rho0)``, unless ``options`` already sets it.

    Parameters
    ----------
    kwargs : mapping
        The full schedule's keyword arguments (``rho0``, ``rho_max``, ``options``, and any others,
        passed through).
    rho0, rho_max : float
        The values of ``rho0`` and ``rho_max`` when ``kwargs`` does not set them (the caller's
        defaults; :func:`~nldr.regularizer.minimize_regularized`'s are 1 and 1e4).

    Returns
    -------
    dict
        A copy of ``kwargs`` with ``rho0 = rho_max = rho_max`` and ``options["scale"]`` set; the
        ``options`` mapping is copied, never changed in place.
    """
    out = dict(kwargs)
    first = float(out.get("rho0", rho0))
    last = float(out.get("rho_max", rho_max))
    options = dict(out.get("options") or {})
    options.setdefault("scale", float(np.sqrt(first)))
    out.update(rho0=last, rho_max=last, options=options)
    return out
