# Paths of every experiment's files, derived from the config and the registry nldr.experiments.
from snakemake.exceptions import WorkflowError

from nldr.datasets import DataError, verify_present
from nldr.experiments import EXPERIMENTS, figure_owner

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


def run_files(experiment, ext="csv"):
    e = EXPERIMENTS[experiment] if isinstance(experiment, str) else experiment
    return [f"{RESULTS}/runs/{e.name}/{job_id}.{ext}" for job_id in JOBS[e.name]]


def table_files(experiment):
    """CSV (canonical), Markdown (in the HTML report), LaTeX."""
    name = experiment if isinstance(experiment, str) else experiment.name
    return [f"{RESULTS}/tables/{name}.{ext}" for ext in ("csv", "md", "tex")]


def figure_path(figure):
    return f"{RESULTS}/figures/{figure}.png"


def notebook_path(experiment):
    return f"{RESULTS}/notebooks/{experiment.notebook}.ipynb"


def target_of(experiment):
    """What `snakemake <name>` builds: the executed notebook if the experiment has one (which needs
    the table and figures), else the table and figures."""
    if experiment.notebook:
        return notebook_path(experiment)
    return table_files(experiment) + [figure_path(f) for f in experiment.figures]
