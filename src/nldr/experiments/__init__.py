"""The experiments: one :class:`~nldr.experiments.base.Experiment` per table, in a registry.

The pipeline, the notebooks and the report are generic over this registry. To add an experiment,
write its module (a subclass of :class:`~nldr.experiments.base.Experiment`), register it in
``_REGISTRY`` below, and add its config and schema block and its notebook (docs/ARCHITECTURE.md).

An experiment's module is imported when it is first asked for (:func:`get`), so a pipeline job
loads only its own experiment's code; ``EXPERIMENTS`` imports them all.
"""

from __future__ import annotations

from importlib import import_module

from .base import Experiment, Job, JobOutput, summary_stats

__all__ = ["Experiment", "Job", "JobOutput", "summary_stats", "EXPERIMENTS", "get", "figure_owner"]

#: name -> (module in this package, class); the paper's tables first, in the paper's order.
_REGISTRY = {
    "table1": ("_table1", "Table1"),
    "table2": ("_table2", "Table2"),
    "table3": ("_table3", "Table3"),
    "table4": ("_table4", "Table4"),
    "table2_full": ("_table2", "Table2Full"),
    "table2_all": ("_table2", "Table2All"),
    "table3_full": ("_table3", "Table3Full"),
    "selection": ("_selection", "Selection"),
    "selection_full": ("_selection", "SelectionFull"),
    "selection_nrsfm": ("_selection_nrsfm", "SelectionNRSfM"),
    "robust": ("_robust", "Robust"),
    "robust_nrsfm": ("_robust_nrsfm", "RobustNRSfM"),
    "out_of_sample": ("_out_of_sample", "OutOfSample"),
    "denoising": ("_denoising", "Denoising"),
    "benchmark": ("_benchmark", "Benchmark"),
}
_INSTANCES: dict[str, Experiment] = {}


def get(name: str) -> Experiment:
    """The experiment called ``name``; ValueError naming the known ones otherwise."""
    if name not in _REGISTRY:
        raise ValueError(f"unknown experiment {name!r}; known: {', '.join(_REGISTRY)}")
    if name not in _INSTANCES:
        module, cls = _REGISTRY[name]
        _INSTANCES[name] = getattr(import_module(f".{module}", __name__), cls)()
    return _INSTANCES[name]


def figure_owner(figure: str) -> Experiment:
    """The experiment that draws ``figure``."""
    for name in _REGISTRY:
        if figure in get(name).figures:
            return get(name)
    raise ValueError(f"no experiment draws figure {figure!r}")


def __getattr__(attr: str):
    # EXPERIMENTS (every experiment by name) is built on first use: importing it loads every module.
    if attr == "EXPERIMENTS":
        return {name: get(name) for name in _REGISTRY}
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")
