"""The experiments: one :class:`~nldr.experiments.base.Experiment` per table, in a registry.

The pipeline, the notebooks and the report are generic over this registry. To add an experiment,
write its module (a subclass of :class:`~nldr.experiments.base.Experiment`), register an instance
below, and add its config and schema block and its notebook (docs/ARCHITECTURE.md).
"""

from __future__ import annotations

from .base import Experiment, Job, JobOutput, summary_stats
from .table1 import Table1
from .table2 import Table2, Table2Full
from .table3 import Table3, Table3Full
from .table4 import Table4

__all__ = ["Experiment", "Job", "JobOutput", "summary_stats", "EXPERIMENTS", "get", "figure_owner"]

#: Every experiment by name, the paper's tables first in the paper's order.
EXPERIMENTS: dict[str, Experiment] = {
    e.name: e for e in (Table1(), Table2(), Table3(), Table4(), Table2Full(), Table3Full())
}


def get(name: str) -> Experiment:
    """The experiment called ``name``; ValueError naming the known ones otherwise."""
    try:
        return EXPERIMENTS[name]
    except KeyError:
        raise ValueError(f"unknown experiment {name!r}; known: {', '.join(EXPERIMENTS)}") from None


def figure_owner(figure: str) -> Experiment:
    """The experiment that draws ``figure``."""
    for experiment in EXPERIMENTS.values():
        if figure in experiment.figures:
            return experiment
    raise ValueError(f"no experiment draws figure {figure!r}")
