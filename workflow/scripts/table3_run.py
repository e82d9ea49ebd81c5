"""One (sequence, setting, seed) of Table 3: TNH, then the kernel regularizer per width criterion."""

import numpy as np
from _pipeline import setup, write_csv, write_npz

from nldr.datasets import load_mocap
from nldr.experiments.table3 import run_sequence

sm = snakemake  # noqa: F821
log = setup(sm)
seq = load_mocap(sm.wildcards.seq, sm.params.data_dir).subsample(sm.params.step)
log.info("%s: %d frames, %d points, setting %s", seq.name, seq.n_frames, seq.n_points, sm.wildcards.setting)
run = run_sequence(
    seq,
    missing_fraction=sm.params.missing_fraction,
    seed=int(sm.wildcards.seed),
    tau=sm.params.tau,
    widths=tuple(sm.params.widths),
    tnh_options=dict(sm.params.tnh),
    progress=log.info,
    n_jobs=sm.threads,  # width criteria in parallel when the rule has 2 threads (table3_full drink)
    **dict(sm.params.regularizer),
)
log.info("\n%s", run.rows.to_string())
write_npz(
    sm.output.shapes,
    methods=np.array(list(run.shapes)),
    mask=run.mask,
    ground_truth=run.ground_truth,
    **{f"shape_{i}": X for i, X in enumerate(run.shapes.values())},
)
write_csv(sm.output.table, run.rows)
