"""Run one job of one experiment (nldr.experiments) and write its rows (CSV) and arrays (NPZ)."""

from _pipeline import setup, write_csv, write_npz

from nldr.experiments import Job, get

sm = snakemake  # noqa: F821
log = setup(sm)
experiment = get(sm.wildcards.experiment)
job = Job(sm.wildcards.job, dict(sm.params.job))
log.info("%s job %s: %s", experiment.name, job.id, dict(job.params))
output = experiment.run(
    job, dict(sm.params.settings), sm.params.data_dir, progress=log.info, threads=int(sm.threads)
)
log.info("\n%s", output.rows.to_string())
write_npz(sm.output.arrays, **output.arrays)
write_csv(sm.output.table, output.rows)
