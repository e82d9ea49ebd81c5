"""CPU seconds of named pipeline jobs of a checkout, each run in this process as the pipeline runs it.

Compares the arithmetic of two commits job by job, without Snakemake's start-up and without the
contention of two jobs sharing the cores (which decides a full ``make reproduce``'s wall time on a
2-core machine). Run it once per checkout, with that checkout's environment, one BLAS thread::

    OPENBLAS_NUM_THREADS=1 <repo>/.venv/bin/python benchmarks/bench_jobs.py <repo> \
        table4:drink_full_seed2016 table3:drink_full_seed2016 table2:p0.5_seeds2036-2045

Each argument is ``<experiment>:<job id>`` (the job ids are the run files' names under
``results/runs/<experiment>/``); the job reads ``<repo>/config/config.yaml`` and ``<repo>/resources``
(fetched by an earlier pipeline run). Prints CPU seconds (``time.process_time``) and wall seconds
per job; nothing is written.
"""

from __future__ import annotations

import sys
from functools import partial
from pathlib import Path

import yaml
from _common import check_blas, cpu_and_wall, parser


def main():
    ap = parser(__doc__, options=False)
    ap.add_argument("repo", type=Path, help="a checkout with config/ and resources/")
    ap.add_argument("jobs", nargs="+", help="<experiment>:<job id>")
    args = ap.parse_args()
    check_blas()
    sys.path.insert(0, str(args.repo / "src"))
    from nldr.experiments import get

    config = yaml.safe_load((args.repo / "config" / "config.yaml").read_text())
    for spec in args.jobs:
        name, _, job_id = spec.partition(":")
        experiment = get(name)
        matches = [job for job in experiment.jobs(config) if job.id == job_id]
        if not matches:
            raise SystemExit(
                f"{name} has no job {job_id!r}; its jobs: {[j.id for j in experiment.jobs(config)]}"
            )
        settings, data_dir = experiment.settings(config), str(args.repo / "resources")
        cpu, wall, _ = cpu_and_wall(partial(experiment.run, matches[0], settings, data_dir, threads=1))
        print(f"{args.repo} {spec}: {cpu:.1f} CPU s, {wall:.1f} wall s", flush=True)


if __name__ == "__main__":
    main()
