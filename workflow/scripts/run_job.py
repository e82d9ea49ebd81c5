"""Run one job of one experiment (nldr.experiments) and write its rows (CSV) and arrays (NPZ), and
apart from them what it measured of the machine (times; ``timings/``), so that the run files repeat
byte for byte between runs."""

from _pipeline import setup, write_csv, write_npz

from nldr.experiments import Job, get
from nldr.experiments.base import split_measured

sm = snakemake  # noqa: F821
log = setup(sm)
experiment = get(sm.wildcards.experiment)
job = Job(sm.wildcards.job, dict(sm.params.job))
log.info("%s job %s: %s", experiment.name, job.id, dict(job.params))
output = experiment.run(
    job, dict(sm.params.settings), sm.params.data_dir, progress=log.info, threads=int(sm.threads)
)
log.info("\n%s", output.rows.to_string())
results, timings = split_measured(output)
write_npz(sm.output.timing_arrays, **timings.arrays)
write_csv(sm.output.timings, timings.rows)
write_npz(sm.output.arrays, **results.arrays)
write_csv(sm.output.table, results.rows)
