"""What every experiment is: the unit that the pipeline, the notebooks and the report are generic over.

An :class:`Experiment` owns everything about one table (a paper table, or one of ours beyond the
paper): the jobs its config block declares, how one job runs (arrays in, a tidy frame and named
arrays out), how the jobs' rows are summarised into the table, the paper's numbers, the caption, the
render options, its figures and each job's threads and resources. The Snakemake rules in
``workflow/rules/experiments.smk`` know nothing about any particular table: they ask the registry
(:mod:`nldr.experiments`) for an experiment by name and call these methods. Adding an experiment
means a module here, its config and schema block, and its notebook (docs/ARCHITECTURE.md).

No file I/O happens here apart from loading the raw data through :mod:`nldr.datasets`.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import pandas as pd

from ..paper import paper_frame
from ..tables import attach_paper

__all__ = [
    "Job",
    "JobOutput",
    "Experiment",
    "summary_stats",
    "SD_DDOF",
    "float_counts",
    "is_measured",
    "split_measured",
    "join_measured",
    "split_measured_table",
]

#: Standard deviations over replicates (noise draws, masks, seeds) in every table are sample
#: standard deviations (``ddof=1``); with one replicate the spread is NaN, shown as no "± sd".
SD_DDOF = 1
#: what a job id may contain (it names files, and the workflow's wildcard accepts exactly this)
_JOB_ID = re.compile(r"[A-Za-z0-9_.+-]+")
#: Names that measure the machine, not the method (times, and ratios of times): a run column, an
#: array or a table metric (without its ``_sd``/``_min``/``_max`` suffix) so named, or ending in one of
#: :data:`MEASURED_SUFFIXES`, is measured. The pipeline keeps measured values apart from the results
#: (``results/timings/``), so that results/tables, runs and figures repeat byte for byte.
MEASURED_NAMES = frozenset({"solves", "ms_per_row"})
MEASURED_SUFFIXES = ("seconds", "_time")
#: Columns that identify a run row; the timings file repeats those a job's rows have.
RUN_KEYS = ("protocol", "sequence", "dataset", "p", "corrupt", "noise_std", "displaced",
            "missing_fraction", "n_rows", "seed", "method")  # fmt: skip


def _types(schema: Mapping) -> set:
    kind = schema.get("type", ())
    return {kind} if isinstance(kind, str) else set(kind)


def _count_only(schema: Mapping, value: float) -> bool:
    """Whether ``schema`` admits the float ``value`` only as an integer (JSON Schema's 2.0 == 2)."""
    if "oneOf" in schema or "anyOf" in schema:
        from jsonschema.validators import validator_for

        branches = schema.get("oneOf", schema.get("anyOf"))
        valid = [b for b in branches if validator_for(b)(b).is_valid(value)]
        return bool(valid) and all(_count_only(b, value) for b in valid)
    kinds = _types(schema)
    return "integer" in kinds and "number" not in kinds


def float_counts(config, schema: Mapping, path: str = "") -> list[str]:
    """Config keys the schema types as integers whose value is a float, e.g. ``n_masks: 2.0``.

    JSON Schema counts 2.0 as an integer, so validation passes them; a count, seed or step then fails
    far from the config (``range(2.0)``, a job id ``seed0.0``). Returns each such key as a dotted path
    (list items as ``[i]``) with its value; the pipeline refuses them before any job.
    """
    found = []
    if isinstance(config, Mapping):
        properties = schema.get("properties", {})
        extra = schema.get("additionalProperties")
        for key, value in config.items():
            sub = properties.get(key, extra if isinstance(extra, Mapping) else None)
            if sub is not None:
                found += float_counts(value, sub, f"{path}.{key}" if path else str(key))
    elif isinstance(config, list) and isinstance(schema.get("items"), Mapping):
        for i, value in enumerate(config):
            found += float_counts(value, schema["items"], f"{path}[{i}]")
    elif isinstance(config, float) and _count_only(schema, config):
        found.append(f"{path}: {config!r}")
    return found


def is_measured(name: str) -> bool:
    """Whether a run column, array or table metric called ``name`` is a measurement of the machine
    (a time or a ratio of times, :data:`MEASURED_NAMES`, :data:`MEASURED_SUFFIXES`)."""
    base = re.sub(r"_(sd|min|max)$", "", str(name))
    return base in MEASURED_NAMES or base.endswith(MEASURED_SUFFIXES)


def split_measured(output: JobOutput) -> tuple[JobOutput, JobOutput]:
    """A job's output -> (results, timings).

    ``results`` is ``output`` without its measured columns and arrays (:func:`is_measured`); it
    repeats bit for bit between runs. ``timings`` holds the same rows in the same order, with the
    row's position (``row``), its identifying columns (:data:`RUN_KEYS`) and its measured columns,
    and the measured arrays.
    :func:`join_measured` puts the two back together.
    """
    rows = output.rows
    measured = [c for c in rows.columns if is_measured(c)]
    keys = [c for c in RUN_KEYS if c in rows.columns]
    results = JobOutput(
        rows.drop(columns=measured), {k: v for k, v in output.arrays.items() if not is_measured(k)}
    )
    table = rows[keys + measured].reset_index(drop=True)
    table.insert(0, "row", range(len(rows)))
    timings = JobOutput(table, {k: v for k, v in output.arrays.items() if is_measured(k)})
    return results, timings


def join_measured(rows: pd.DataFrame, timings: pd.DataFrame) -> pd.DataFrame:
    """One job's result rows with its timing rows (:func:`split_measured`) beside them.

    Raises
    ------
    ValueError
        If the two do not describe the same rows (row count or identifying columns differ): the
        timings file is not this run file's.
    """
    keys = [c for c in timings.columns if not is_measured(c) and c != "row"]
    same = len(rows) == len(timings) and all(k in rows for k in keys)
    if same and keys:
        same = rows[keys].reset_index(drop=True).equals(timings[keys].reset_index(drop=True))
    if not same:
        raise ValueError(
            f"timings: rows do not match the run file's ({len(timings)} against {len(rows)} rows, keys "
            f"{keys}); rebuild both with the run_job rule"
        )
    measured = timings[[c for c in timings.columns if is_measured(c)]].reset_index(drop=True)
    return pd.concat([rows.reset_index(drop=True), measured], axis=1)


def split_measured_table(table: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A tidy table -> (rows whose metric is a result, rows whose metric is measured)."""
    measured = table["metric"].map(is_measured).astype(bool)
    return table[~measured].reset_index(drop=True), table[measured].reset_index(drop=True)


def summary_stats(values, prefix: str, *, extremes: bool = False) -> dict[str, float]:
    """Mean and sample sd (:data:`SD_DDOF`) of replicate values, as table metrics; with
    ``extremes`` also their min and max.

    Parameters
    ----------
    values : 1-d array-like of float
        One value per replicate (NaN entries are dropped, as unavailable runs).
    prefix : str
        Metric name; the keys are ``prefix``, ``prefix_sd`` (and ``prefix_min``, ``prefix_max``).
    extremes : bool, default False
        Also report the smallest and largest replicate.

    Returns
    -------
    dict
        NaN where undefined (no replicate; sd with a single replicate).
    """
    v = pd.Series(values, dtype=float).dropna()
    n = len(v)
    stats = {
        prefix: float(v.mean()) if n else np.nan,
        f"{prefix}_sd": float(v.std(ddof=SD_DDOF)) if n > SD_DDOF else np.nan,
    }
    if extremes:
        stats[f"{prefix}_min"] = float(v.min()) if n else np.nan
        stats[f"{prefix}_max"] = float(v.max()) if n else np.nan
    return stats


@dataclass(frozen=True)
class Job:
    """One unit of work: ``id`` names its files (``runs/<experiment>/<id>.csv``), ``params`` are the
    values that differ between the experiment's jobs (seed, noise level, sequence, ...)."""

    id: str
    params: Mapping = field(default_factory=dict)


@dataclass
class JobOutput:
    """What one job produces: tidy ``rows`` (one per method, or per evaluated model) and named
    ``arrays`` (reconstructions, masks, ...; may be empty). The pipeline writes both, atomically."""

    rows: pd.DataFrame
    arrays: dict[str, np.ndarray] = field(default_factory=dict)


class Experiment:
    """Base class; subclasses set the class attributes and implement :meth:`jobs`, :meth:`run` and
    :meth:`summarise`.

    Class attributes
    ----------------
    name : str
        Config key, target name and folder name under ``results/``.
    title : str
        One line, for listings.
    in_paper : bool
        True for the paper's tables (their numbers enter the scorecard).
    paper : list of (setting, method, metric, value) or None
        The published numbers (:mod:`nldr.paper`), shown beside ours.
    notebook : str or None
        Stem of the notebook in ``notebooks/`` that explains the table; the pipeline executes it as
        the last step of the target. None: the target is the table alone.
    figures : tuple of str
        Figures drawn from this experiment's runs (:meth:`draw`), ``results/figures/<name>.png``.
    inherits : str or None
        Config block whose keys fill the keys this experiment's block does not set.
    gathers_with : tuple of str
        Other experiments whose runs :meth:`table` needs beside this one's.
    render : dict
        Keyword arguments of :func:`nldr.tables.to_markdown` / ``to_latex`` (digits, metrics, transpose).
    enumerates : tuple of str
        Config keys that only say which jobs exist (seeds, counts, lists of settings); the others are
        the settings every job runs with (:meth:`job_settings`), so changing a count or adding a seed
        reruns no existing job.
    figure_captions : dict
        Figure name -> caption (Markdown).
    """

    name: ClassVar[str]
    title: ClassVar[str]
    in_paper: ClassVar[bool] = False
    paper: ClassVar[list | None] = None
    notebook: ClassVar[str | None] = None
    figures: ClassVar[tuple[str, ...]] = ()
    inherits: ClassVar[str | None] = None
    gathers_with: ClassVar[tuple[str, ...]] = ()
    render: ClassVar[dict] = {}
    enumerates: ClassVar[tuple[str, ...]] = ()
    figure_captions: ClassVar[dict[str, str]] = {}

    # -- configuration -------------------------------------------------------------------------
    def settings(self, config: Mapping) -> dict:
        """This experiment's config block, completed from the block it inherits from."""
        own = dict(config[self.name])
        if self.inherits is None:
            return own
        return {**dict(config[self.inherits]), **own}

    def job_settings(self, config: Mapping) -> dict:
        """:meth:`settings` without the keys in :attr:`enumerates`: what every job runs with."""
        return {k: v for k, v in self.settings(config).items() if k not in self.enumerates}

    def jobs(self, config: Mapping) -> list[Job]:
        """Every job the config declares, in a stable order."""
        raise NotImplementedError

    def check(self, config: Mapping) -> list[Job]:
        """Cross-field checks the schema cannot express; returns :meth:`jobs` when they pass.

        Every job id must be a distinct file name of letters, digits and ``_.+-``, and every float
        parameter must survive its ``:g`` formatting (ids and table settings print values that way):
        0.2000001 would print as 0.2 and two values that print alike would share one file. Subclasses
        add their own checks and call this one.

        Raises
        ------
        ValueError
            Naming the config key (``experiment.key``) and the offending value.
        """
        jobs = self.jobs(config)
        for job in jobs:
            for key, value in job.params.items():
                if isinstance(value, float) and float(f"{value:g}") != value:
                    raise ValueError(
                        f"{self.name}.{key}: {value!r} prints as {value:g} in file names and tables; "
                        "use at most 6 significant digits"
                    )
            if not _JOB_ID.fullmatch(job.id):
                raise ValueError(
                    f"{self.name}: job id {job.id!r} is not a plain file name (letters, digits, _.+-)"
                )
        seen = set()
        for job in jobs:
            if job.id in seen:
                raise ValueError(f"{self.name}: two jobs share the id {job.id!r}; a value is listed twice")
            seen.add(job.id)
        return jobs

    def job(self, config: Mapping, job_id: str) -> Job:
        """The job named ``job_id``; ValueError naming the known ids otherwise."""
        for job in self.jobs(config):
            if job.id == job_id:
                return job
        raise ValueError(f"experiment {self.name!r} has no job {job_id!r} under this config")

    def data_files(self, config: Mapping, job: Job | None = None) -> list[str]:
        """Raw data files (paths relative to the data folder) that ``job`` reads (every job: None)."""
        return []

    def threads(self, config: Mapping, job: Job) -> int:
        """BLAS threads (and worker processes) the job may use; the pipeline pins BLAS to it."""
        return 1

    def resources(self, config: Mapping, job: Job) -> dict:
        """Scheduler resources of one job (``mem_mb``, ``runtime`` in minutes)."""
        return {"mem_mb": 1000, "runtime": 20}

    # -- computation ---------------------------------------------------------------------------
    def run(
        self,
        job: Job,
        settings: Mapping,
        data_dir,
        *,
        progress: Callable[[str], None] | None = None,
        threads: int = 1,
    ) -> JobOutput:
        """Run one job on the data in ``data_dir``; ``settings`` is :meth:`job_settings` of the config."""
        raise NotImplementedError

    def summarise(self, runs: pd.DataFrame) -> pd.DataFrame:
        """The jobs' rows (concatenated) -> tidy ``setting, method, metric, value`` rows."""
        raise NotImplementedError

    def table(self, runs: pd.DataFrame, config: Mapping, others: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
        """The canonical table: :meth:`summarise` with the paper's numbers attached (column ``paper``).

        ``others`` maps each name of :attr:`gathers_with` to that experiment's concatenated runs.
        """
        return attach_paper(self.summarise(runs), paper_frame(self.published(config)))

    def published(self, config: Mapping) -> list:
        """The paper's numbers that apply under ``config`` (default: :attr:`paper`, or none)."""
        return self.paper or []

    # -- presentation --------------------------------------------------------------------------
    def caption(self, config: Mapping) -> str:
        """The table's caption (Markdown, LaTeX and the HTML report), from the config's values."""
        raise NotImplementedError

    def draw(self, figure: str, runs: pd.DataFrame, arrays: Mapping[str, Mapping], data_dir):
        """Draw ``figure`` (one of :attr:`figures`) from the runs and ``arrays`` (job id -> that job's
        saved arrays); returns a matplotlib Figure."""
        raise ValueError(f"experiment {self.name!r} draws no figure {figure!r}")

    @property
    def label(self) -> str:
        """LaTeX label of the table."""
        return "tab:" + self.name.replace("_", "-")
