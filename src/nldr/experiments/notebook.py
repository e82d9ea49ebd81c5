"""What the notebooks in ``notebooks/`` share: the repository, the config as the pipeline reads it, and
a cache for what a notebook computes itself.

A notebook reads the pipeline's results (``snakemake <experiment>`` computes them); run by the pipeline
it is given this run's files as relative paths, run by hand it finds them from the config. Either way
it works from any working directory and its executed copy names no absolute path.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import pickle
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "repo_root",
    "load_config",
    "merge_config",
    "need",
    "cached",
    "locate",
    "Located",
    "timing_path",
]

_MARKERS = ("Snakefile", "config/config.yaml")


def _is_root(folder: Path) -> bool:
    return all((folder / marker).is_file() for marker in _MARKERS)


def repo_root(start: str | os.PathLike | None = None) -> Path:
    """The repository: the first folder holding ``Snakefile`` and ``config/config.yaml``, walking up
    from ``start`` (default: the working directory), else the checkout this package was imported from
    (an editable install or ``PYTHONPATH=src``).

    Raises
    ------
    FileNotFoundError
        Neither walk finds one (``nldr`` installed from a wheel and run outside a checkout); the
        message says to pass ``start``.
    """
    begin = Path(start if start is not None else Path.cwd()).resolve()
    for folder in (begin, *begin.parents):
        if _is_root(folder):
            return folder
    source = Path(__file__).resolve().parents[3]  # <checkout>/src/nldr/experiments/notebook.py
    if _is_root(source):
        return source
    raise FileNotFoundError(
        f"no folder holding {' and '.join(_MARKERS)} above {begin} or {source}: "
        "pass start= (the repository's folder) or run from inside a checkout"
    )


def merge_config(base: Mapping, overlay: Mapping) -> dict:
    """``overlay`` laid over ``base`` as Snakemake merges ``--configfile`` files: nested mappings merge
    key by key, any other value replaces."""
    out = copy.deepcopy(dict(base))
    for key, value in overlay.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = merge_config(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def load_config(root: str | os.PathLike, configfile: str | os.PathLike = "") -> dict:
    """``config/config.yaml`` of ``root`` with ``configfile`` (e.g. ``"config/quick.yaml"``, relative
    to ``root`` or absolute) laid over it, as ``snakemake --configfile <configfile>`` sees it."""
    import yaml

    root = Path(root)
    config = yaml.safe_load((root / "config" / "config.yaml").read_text())
    if configfile:
        path = Path(configfile) if Path(configfile).is_absolute() else root / configfile
        if not path.is_file():
            raise ValueError(f"configfile {str(configfile)!r} not found (relative paths are from {root})")
        config = merge_config(config, yaml.safe_load(path.read_text()) or {})
    return config


def need(path: str | os.PathLike, target: str) -> Path:
    """``path`` if it is a file; else FileNotFoundError saying which Snakemake target builds it."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(
            f"{path} not found: build it with `snakemake -c all {target}` (for the quick protocol's "
            f"results, `snakemake -c all {target} --configfile config/quick.yaml` and configfile = "
            '"config/quick.yaml" in the parameters cell)'
        )
    return path


def timing_path(run: str | os.PathLike) -> Path:
    """The timings file of a run file: ``<results>/runs/<experiment>/<job>.csv`` ->
    ``<results>/timings/<experiment>/<job>.csv`` (what the job measured: times; the pipeline keeps
    them apart so that run files repeat byte for byte)."""
    run = Path(run)
    return run.parents[2] / "timings" / run.parent.name / run.name


@dataclass
class Located:
    """Where a notebook's inputs are (see :func:`locate`); every path absolute."""

    root: Path  # the repository (the folder holding the Snakefile)
    config: dict  # config.yaml with the notebook's configfile laid over it
    results: Path  # the results folder of that config
    settings: dict  # the experiment's config block (as the pipeline ran it, when given)
    table: Path  # the experiment's tidy CSV (checked to exist)
    runs: list  # the per-job CSVs
    arrays: list  # the per-job .npz files (those beside the CSVs unless given)
    data_dir: Path  # the folder holding oil/ and nrsfm/
    timings: list  # the per-job timings CSVs (times), one per run file, same order
    timing_table: Path  # the table's measured rows (times): <results>/timings/<experiment>.csv

    def read_runs(self):
        """Every run file's rows, concatenated, with its timings beside them (columns such as
        ``seconds``, ``cpu_seconds``; :func:`nldr.experiments.base.join_measured`)."""
        import pandas as pd

        from .base import join_measured

        return pd.concat(
            [
                join_measured(pd.read_csv(r), pd.read_csv(t))
                for r, t in zip(self.runs, self.timings, strict=True)
            ],
            ignore_index=True,
        )

    def read_table(self):
        """The table's rows with its measured rows (times) after them, when it has a timings table."""
        import pandas as pd

        table = pd.read_csv(self.table)
        if self.timing_table.is_file():
            table = pd.concat([table, pd.read_csv(self.timing_table)], ignore_index=True)
        return table


def locate(
    experiment: str,
    configfile: str = "",
    workdir: str = "",
    results: str = "",
    table: str = "",
    runs: Sequence[str] = (),
    arrays: Sequence[str] = (),
    settings: Mapping | None = None,
    data_dir: str = "",
) -> Located:
    """The inputs of ``experiment``'s notebook from its parameters cell (the arguments in the order of
    the cell: ``locate(name, configfile, workdir, results, table, runs, arrays, settings, data_dir)``).

    Run by the pipeline, the parameters name this run's files relative to ``workdir``; run by hand they
    are empty and everything follows from the config: ``<results>/tables/<experiment>.csv``, every CSV
    in ``<results>/runs/<experiment>/`` and the ``.npz`` beside each; the timings are found beside the
    runs (:func:`timing_path`). The repository is found by walking
    up to its ``Snakefile`` (:func:`repo_root`), so the notebook runs from any working directory.
    A missing table raises FileNotFoundError naming the target that builds it (:func:`need`).
    """
    from . import get

    root = repo_root()
    config = load_config(root, configfile)
    base = Path(workdir) if workdir else root
    folder = base / (results or config["results"])
    run_paths = [base / r for r in runs] or sorted((folder / "runs" / experiment).glob("*.csv"))
    table_path = need(base / (table or folder / "tables" / f"{experiment}.csv"), experiment)
    return Located(
        root=root,
        config=config,
        results=folder,
        settings=dict(settings) if settings else get(experiment).settings(config),
        table=table_path,
        runs=run_paths,
        arrays=[base / a for a in arrays] or [p.with_suffix(".npz") for p in run_paths],
        data_dir=base / (data_dir or config["data"]["dir"]),
        timings=[timing_path(p) for p in run_paths],
        timing_table=table_path.parents[1] / "timings" / f"{experiment}.csv",
    )


def cached(
    folder: str | os.PathLike,
    name: str,
    key: Mapping,
    compute: Callable[[], object],
    *,
    recompute: bool = False,
):
    """``compute()``'s value, kept in ``folder/<name>-<hash of key>.pkl``.

    The file is read when it exists and ``recompute`` is false; otherwise ``compute()`` runs and its
    value is written (atomically: complete or absent). ``key`` holds everything the value depends on
    (JSON-serialisable settings), so changing a setting computes afresh instead of reading a stale
    value. Read only caches you wrote: unpickling runs code.
    """
    digest = hashlib.sha256(json.dumps(key, sort_keys=True, default=str).encode()).hexdigest()[:12]
    path = Path(folder) / f"{name}-{digest}.pkl"
    if path.is_file() and not recompute:
        with open(path, "rb") as fh:
            return pickle.load(fh)
    value = compute()
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            pickle.dump(value, fh)
        os.replace(tmp, path)
    finally:
        Path(tmp).unlink(missing_ok=True)
    return value
