"""Benchmark: the TNH camera search (:func:`nldr.nrsfm._camera_refinement.tnh_camera_search`) at
Table 4's tau*, per job.

For each Table 4 job (CMU mocap, every 10th frame, 41 points; full data or 50 % of the (frame, point)
observations hidden by ``random_visibility_mask(F, P, 0.5, seed)``), at the job's tau* read from a
finished Table 4 run (``--runs``, the TNH row's ``tau``; the oracle's Brent search on e3D), this runs
the alternation from the rigid-factorisation cameras (what the tau search evaluated at tau*), then
:func:`~nldr.nrsfm._camera_refinement.tnh_camera_search` from its result. It reports TNH's energy (the
search's only criterion), e3D and the camera error (ground truth, reported, never used), and the
CPU seconds of each (``time.process_time``, BLAS on one thread).

Usage (from the repository root)::

    .venv/bin/python benchmarks/bench_camera_search.py --runs results/runs/table4
    .venv/bin/python benchmarks/bench_camera_search.py --sequences yoga stretch --seeds 2016 2017

Writes results/benchmarks/camera_search.csv (one row per job).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from nldr.datasets import load_mocap
from nldr.nrsfm._camera_refinement import tnh_camera_search, tnh_with_camera_refinement
from nldr.nrsfm._factorization import initialize_cameras
from nldr.nrsfm._layout import random_visibility_mask, stack_to_rows
from nldr.nrsfm._metrics import camera_error, e3d

OUT = Path("results/benchmarks/camera_search.csv")


def tau_star(runs: Path, sequence: str, setting: str, seed: int) -> float:
    rows = pd.read_csv(runs / f"{sequence}_{setting}_seed{seed}.csv")
    return float(rows.loc[rows["method"] == "TNH", "tau"].iloc[0])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=Path, default=Path("results/runs/table4"))
    ap.add_argument("--data", type=Path, default=None)
    ap.add_argument("--sequences", nargs="+", default=["drink", "pickup", "yoga", "stretch"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[2016, 2017, 2018, 2019, 2020])
    ap.add_argument("--settings", nargs="+", default=["full", "missing"])
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    rows = []
    with threadpool_limits(1):
        for name in args.sequences:
            seq = load_mocap(name, args.data).subsample(10)
            W2d, X_gt = stack_to_rows(seq.W, dim=2), stack_to_rows(seq.S, dim=3)
            F, P = W2d.shape[0], W2d.shape[1] // 2
            for setting in args.settings:
                for seed in args.seeds if setting == "missing" else args.seeds[:1]:
                    full = setting == "full"
                    mask = np.ones((F, P), bool) if full else random_visibility_mask(F, P, 0.5, seed)
                    tau = tau_star(args.runs, name, setting, seed)
                    t0 = time.process_time()
                    start = tnh_with_camera_refinement(W2d, mask, initialize_cameras(W2d, mask), tau)
                    t1 = time.process_time()
                    found = tnh_camera_search(W2d, mask, start, tau)
                    t2 = time.process_time()
                    row = dict(
                        sequence=name,
                        setting=setting,
                        seed=seed,
                        tau=tau,
                        energy_before=start.fun,
                        energy_after=found.fun,
                        e3d_before=e3d(start.x, X_gt, P, align=True),
                        e3d_after=e3d(found.x, X_gt, P, align=True),
                        camera_error_before=camera_error(start.R, seq.R),
                        camera_error_after=camera_error(found.R, seq.R),
                        alternations=found.search["n_alternations"],
                        cpu_alternation=t1 - t0,
                        cpu_search=t2 - t1,
                        message=found.message,
                    )
                    rows.append(row)
                    print(
                        f"{name:8s} {setting:7s} {seed}: E {row['energy_before']:.6g} -> "
                        f"{row['energy_after']:.6g}, "
                        f"e3D {row['e3d_before']:.4f} -> {row['e3d_after']:.4f}, camera "
                        f"{row['camera_error_before']:.1f} -> {row['camera_error_after']:.1f} deg, search "
                        f"{row['cpu_search']:.1f} CPU s ({row['alternations']} alternations)",
                        flush=True,
                    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).to_csv(args.out, index=False)
    print(f"wrote {args.out}; search CPU total {sum(r['cpu_search'] for r in rows):.1f} s")


if __name__ == "__main__":
    main()
