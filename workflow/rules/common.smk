# Paths of every experiment's files, derived from the config and the registry nldr.experiments.
import yaml
from snakemake.exceptions import WorkflowError

from nldr.datasets import DataError, verify_present
from nldr.experiments import EXPERIMENTS, figure_owner
from nldr.experiments.base import float_counts

REPO = Path(workflow.basedir)
DATA_DIR = config["data"]["dir"]
RESULTS = config["results"]  # config.yaml: results; quick.yaml: results/quick (never the same files)
PAPER = [e for e in EXPERIMENTS.values() if e.in_paper]
NOTEBOOKS = {e.notebook: e for e in EXPERIMENTS.values() if e.notebook}


def _checked_jobs(experiment):
    """The experiment's jobs after its cross-field checks (Experiment.check): a bad value stops the
    run here, before any job, naming its config key."""
    try:
        return {job.id: job for job in experiment.check(config)}
    except ValueError as exc:
        raise WorkflowError(f"invalid config: {exc}") from None


def _integers_are_integers():
    """Integer keys written as floats (n_masks: 2.0) pass the schema (JSON Schema counts 2.0 as an
    integer) and would fail inside every job, naming no key: refused here, before any job."""
    schema = yaml.safe_load((REPO / "workflow/schemas/config.schema.yaml").read_text())
    bad = float_counts(config, schema)
    if bad:
        raise WorkflowError(
            "invalid config: these keys take an integer (a count, seed or step) and were given a "
            "float; write them without a decimal point: " + "; ".join(bad)
        )


_integers_are_integers()
JOBS = {name: _checked_jobs(e) for name, e in EXPERIMENTS.items()}  # built once


def experiment_of(wildcards):
    return EXPERIMENTS[wildcards.experiment]


def job_of(wildcards):
    jobs = JOBS[wildcards.experiment]
    if wildcards.job in jobs:
        return jobs[wildcards.job]
    return experiment_of(wildcards).job(config, wildcards.job)  # raises, naming the experiment


def data_paths(relpaths):
    return [f"{DATA_DIR}/{rel}" for rel in relpaths]


def run_files(experiment, ext="csv", folder="runs"):
    """Each job's file under ``runs/`` (results) or ``timings/`` (what the job measured: times)."""
    e = EXPERIMENTS[experiment] if isinstance(experiment, str) else experiment
    return [f"{RESULTS}/{folder}/{e.name}/{job_id}.{ext}" for job_id in JOBS[e.name]]


def timing_files(experiment):
    """The jobs' timings (CSV) of an experiment, in the order of :func:`run_files`."""
    return run_files(experiment, "csv", "timings")


def timing_table(experiment):
    """The table's measured rows (times), apart from results/tables so that those repeat bit for bit."""
    name = experiment if isinstance(experiment, str) else experiment.name
    return f"{RESULTS}/timings/{name}.csv"


TABLE_FORMATS = ("csv", "md", "html", "tex")  # CSV is canonical; HTML is what the HTML report shows
FIGURE_FORMATS = ("png", "pdf", "svg")  # PNG for the report and notebooks, PDF and SVG for papers


def table_files(experiment):
    """CSV (canonical), Markdown, HTML (in the HTML report), LaTeX."""
    name = experiment if isinstance(experiment, str) else experiment.name
    return [f"{RESULTS}/tables/{name}.{ext}" for ext in TABLE_FORMATS]


def figure_path(figure, ext="png"):
    return f"{RESULTS}/figures/{figure}.{ext}"


def figure_files(figure):
    return [figure_path(figure, ext) for ext in FIGURE_FORMATS]


def notebook_path(experiment, ext="ipynb"):
    """The executed notebook (``ipynb``) or its HTML page (``html``) of an experiment or a notebook name."""
    name = experiment if isinstance(experiment, str) else experiment.notebook
    return f"{RESULTS}/notebooks/{name}.{ext}"


def target_of(experiment):
    """What `snakemake <name>` builds: the table in every format with its timings, the figures in every
    format, and the executed notebook with its HTML page if the experiment has one."""
    files = table_files(experiment) + [f for fig in experiment.figures for f in figure_files(fig)]
    files.append(timing_table(experiment))
    if experiment.notebook:
        files += [notebook_path(experiment), notebook_path(experiment, "html")]
    return files
