"""The choice rules of :class:`~nldr.model_selection.HoldoutSearch`: which candidate its fold errors pick."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = ["RULES", "choose", "reference_index"]

#: Choice rules of :class:`~nldr.model_selection.HoldoutSearch`.
RULES = ("min", "one_se", "reference")


def choose(mean, std, n_folds, rule, prefer, candidates, eligible=None, reference=None, paired=None) -> int:
    """Index chosen by ``rule`` among the eligible candidates with a finite mean error.

    ``eligible`` (bool per candidate, default all) restricts every rule; if no candidate with a finite
    mean is eligible, all of those are. ``rule="reference"``: ``reference`` is the index of the
    default and ``paired`` the (mean, standard error) over folds of each candidate's error minus the
    reference's in the same fold; the reference is kept unless eligible candidates have
    ``mean + se < 0``, and then the one of those with the smallest mean error is chosen.
    """
    finite = np.isfinite(mean)
    allowed = finite if eligible is None else finite & np.asarray(eligible, dtype=bool)
    if not allowed.any():
        allowed = finite
    if rule == "reference":
        diff, se = paired
        better = allowed & np.isfinite(diff) & np.isfinite(se) & (diff + se < 0)
        if not better.any():
            return int(reference)
        return int(np.flatnonzero(better)[np.argmin(mean[better])])
    idx = np.flatnonzero(allowed)
    best = int(idx[np.argmin(mean[idx])])
    if rule == "min":
        return best
    close = idx[mean[idx] <= mean[best] + std[best] / np.sqrt(n_folds)]
    for name in prefer:
        key, sign = (name[1:], -1.0) if name.startswith("-") else (name, 1.0)
        values = np.array([sign * float(candidates[i][key]) for i in close])
        close = close[values == values.min()]
    return int(close[np.argmin(mean[close])])


def reference_index(candidates, rule, reference) -> int | None:
    """Index of the ``reference`` candidate among ``candidates`` (``rule="reference"``), None for the
    other rules; ValueError unless it is exactly one candidate."""
    if rule != "reference":
        if reference is not None:
            raise ValueError(f"reference is the default of rule='reference'; got rule={rule!r}")
        return None
    if not isinstance(reference, Mapping) or not reference:
        raise ValueError(f"rule='reference' needs reference, a dict of a candidate's parameters; got "
                         f"{reference!r}")

    def same(a, b):
        if isinstance(a, (int, float, np.number)) and isinstance(b, (int, float, np.number)):
            return bool(np.isclose(float(a), float(b)))
        return a == b

    ref = dict(reference)
    hits = [k for k, c in enumerate(candidates)
            if set(c) == set(ref) and all(same(c[n], ref[n]) for n in ref)]  # fmt: skip
    if len(hits) != 1:
        raise ValueError(f"reference {ref} must be one candidate of param_grid; it is {len(hits)}")
    return hits[0]
