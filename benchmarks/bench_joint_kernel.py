"""Benchmark: Table 4's kernel stage with cameras and shapes optimised jointly, one start or several.

Each case is one Table 4 job (sequence, setting, mask seed): the kernel stage of
:func:`~nldr.experiments._table4.run_sequence` for both widths from the tuned TNH's cameras and shapes,
read from that job's output of a finished Table 4 run (``--runs``, default results/runs/table4, the
``cameras_0``/``shape_0`` arrays of ``<job>.npz``; the TNH search itself is not rerun). Variants:

* ``scaled``: the scaled L-BFGS of :mod:`~nldr.nrsfm._joint_kernel`, full schedule from the TNH solution;
* ``after``: ``scaled`` with the multi-start of :func:`~nldr.nrsfm._joint_kernel.joint_kernel_multistart`
  (Table 4's configuration).

The unscaled L-BFGS the scaling replaced (issue 16's "before") is no longer in the library; its
numbers stay in docs/PERFORMANCE.md.

CPU seconds by ``time.process_time`` with BLAS on one thread; the paper's energy at rho_max
(:func:`~nldr.nrsfm._joint_kernel.kernel_energy`) and e3D after one global alignment. ``ref_energy`` and
``ref_e3d`` are those of the kernel solutions stored in the run's npz (the code that produced the run).

Usage (from the repository root)::

    .venv/bin/python benchmarks/bench_joint_kernel.py --jobs pickup_full_seed2016 drink_full_seed2016
    .venv/bin/python benchmarks/bench_joint_kernel.py --variants after --runs /path/to/results/runs/table4

Writes results/benchmarks/joint_kernel.csv (one row per job, width and variant).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from nldr.datasets import load_mocap
from nldr.experiments._mocap import WIDTHS
from nldr.nrsfm import reconstruct
from nldr.nrsfm._joint_kernel import kernel_energy
from nldr.nrsfm._layout import stack_to_rows
from nldr.nrsfm._metrics import e3d

OUT = Path("results/benchmarks/joint_kernel.csv")
VARIANTS = {"scaled": dict(multistart=False), "after": dict(multistart=True)}
SCHEDULE = dict(tau=1e-4, rho0=1e-3, rho_growth=10.0, rho_max=10.0)  # config/config.yaml, table4


def kernel_stage(c, multistart: bool) -> dict:
    """Table 4's kernel stage from the run's TNH (``reconstruct``, the tables' one entry point): width
    -> (result, energy (1) at the last rho). With the multistart one call solves both widths."""
    start = SimpleNamespace(x=c["X"], R=c["R"])
    out = {}
    for width in ("d_max", "d_med") if not multistart else ("d_med",):
        rec = reconstruct(c["W2d"], c["mask"], prior="kernel", width=width, start=start,
                          multistart=multistart, **SCHEDULE)  # fmt: skip
        out.update({width: rec, **rec.other_widths})
    return {width: (rec, rec.fun) for width, rec in out.items()}


def case(job: str, runs: Path, data_dir, step: int = 10):
    """Tracks, mask, TNH start, ground truth and the run's own kernel solutions of one job."""
    sequence = job.split("_")[0]
    arrays = np.load(runs / f"{job}.npz")
    methods = [str(m) for m in arrays["methods"]]
    seq = load_mocap(sequence, data_dir).subsample(step)
    stored = {m.split()[-1]: (arrays[f"cameras_{i}"], arrays[f"shape_{i}"]) for i, m in enumerate(methods)}
    return dict(
        W2d=stack_to_rows(seq.W, dim=2),
        X_gt=stack_to_rows(seq.S, dim=3),
        mask=arrays["mask"],
        R=arrays[f"cameras_{methods.index('TNH')}"],
        X=arrays[f"shape_{methods.index('TNH')}"],
        stored=stored,
    )


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=Path, default=Path("results/runs/table4"))
    parser.add_argument("--jobs", nargs="*", help="job ids (default: every npz in --runs)")
    parser.add_argument("--variants", nargs="*", default=list(VARIANTS), choices=list(VARIANTS))
    parser.add_argument("--data-dir", default=None)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    jobs = args.jobs or sorted(p.stem for p in args.runs.glob("*.npz"))
    rows = []
    for job in jobs:
        c = case(job, args.runs, args.data_dir)
        P = c["mask"].shape[1]
        gammas = {width: WIDTHS[width](c["X"]) for width in ("d_max", "d_med")}
        for variant in args.variants:
            with threadpool_limits(1):
                start = time.process_time()
                out = kernel_stage(c, **VARIANTS[variant])
                cpu = time.process_time() - start
            for width, (res, energy) in out.items():
                R_ref, X_ref = c["stored"][width]
                ref = kernel_energy(
                    c["W2d"], c["mask"], R_ref, X_ref, gamma=gammas[width], tau=1e-4, rho=10.0
                )
                rows.append(
                    dict(
                        job=job,
                        width=width,
                        variant=variant,
                        cpu_job=cpu,
                        nit=res.nit,
                        energy=energy,
                        ref_energy=ref,
                        rel_energy=(energy - ref) / ref,
                        e3d=e3d(res.x, c["X_gt"], P, align=True),
                        ref_e3d=e3d(X_ref, c["X_gt"], P, align=True),
                        converged=res.success,
                        kept=res.message[:40],
                    )  # fmt: skip
                )
                r = rows[-1]
                print(
                    f"{job:26s} {width} {variant:6s} cpu(job)={cpu:6.2f}s nit={r['nit']:6d} "
                    f"rel.energy={r['rel_energy']:+.2e} e3d={r['e3d']:.5f} (run's {r['ref_e3d']:.5f})",
                    flush=True,
                )
    table = pd.DataFrame(rows)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out, index=False)
    per_job = table.groupby(["variant", "job"]).cpu_job.first().groupby("variant")
    print(per_job.agg(["sum", "mean", "max"]).rename(columns=lambda s: f"cpu_{s}").to_string())


if __name__ == "__main__":
    main()
