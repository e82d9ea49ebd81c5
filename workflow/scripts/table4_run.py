"""One (sequence, setting, seed) of Table 4: tuned TNH with estimated cameras, then the kernel method."""

import numpy as np
from _pipeline import setup, write_csv, write_npz

from nldr.datasets import load_mocap
from nldr.experiments.table4 import run_sequence

sm = snakemake  # noqa: F821
log = setup(sm)
seq = load_mocap(sm.wildcards.seq, sm.params.data_dir).subsample(sm.params.step)
log.info("%s: %d frames, %d points, setting %s", seq.name, seq.n_frames, seq.n_points, sm.wildcards.setting)
tnh, kernel = dict(sm.params.tnh), dict(sm.params.kernel)
run = run_sequence(
    seq,
    missing_fraction=sm.params.missing_fraction,
    seed=int(sm.wildcards.seed),
    log10_tau_bounds=tuple(tnh["log10_tau_bounds"]),
    xatol=tnh["xatol"],
    tnh_max_outer=tnh.get("max_outer", 20_000),
    tnh_tol=tnh.get("tol", 1e-8),
    tau=sm.params.tau,
    widths=tuple(sm.params.widths),
    kernel_max_outer=kernel.pop("max_outer", 20),
    kernel_tol=kernel.pop("tol", 1e-4),
    progress=log.info,
    **kernel,
)
log.info("\n%s", run.rows.to_string())
log.info("TNH tau search (tau, e3d): %s", [(round(t, 5), round(e, 5)) for t, e in run.tau_search])
write_npz(
    sm.output.shapes,
    methods=np.array(list(run.shapes)),
    mask=run.mask,
    ground_truth=run.ground_truth,
    rigid_cameras=run.cameras["rigid"],
    tau_search=np.array(run.tau_search),
    **{f"shape_{i}": X for i, X in enumerate(run.shapes.values())},
    **{f"cameras_{i}": run.cameras[m] for i, m in enumerate(run.shapes)},
)
write_csv(sm.output.table, run.rows)
