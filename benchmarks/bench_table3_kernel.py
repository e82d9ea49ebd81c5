"""Benchmark: Table 3's kernel stage (known cameras), L-BFGS on the shapes against L-BFGS in
camera-frame variables (:class:`~nldr.nrsfm.CameraFrameVariables`).

Each case is one Table 3 job's kernel solve: CMU mocap every 10th frame, 41 points, full data or 50 %
of the (frame, point) observations hidden (``random_visibility_mask(F, P, 0.5, seed)``), TNH (ADMM,
tol 1e-6) as the start, the width from the TNH shapes (d_max or d_med), tau = 1e-4 and the config's
penalty schedule (rho 1e-3 to 1e3, x10, tol 1e-12, gtol 1e-10) unless overridden. CPU seconds with
BLAS on one thread (``time.process_time``); the TNH is not timed. Widths by :func:`nldr.kernels.d_max_width`
and :func:`nldr.kernels.d_med_width`.

The answer is judged by its energy, never by e3D: ``energy`` is (1) at the last rho (the solver's
``fun``); ``ref_energy`` is the same energy of the reconstruction saved by a previous full run
(``--reference-runs``, default results/runs/table3: the ``.npz`` of each job), and ``rel_energy`` is
``energy / ref_energy - 1`` (negative: lower than the reference). e3D is reported beside it.

Usage (from the repository root; ``--quick``: pickup, full data, d_med, both variables)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_table3_kernel.py --sequences pickup stretch --seeds 2016
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_table3_kernel.py --depth-scale 0 100 --rho-growth 10 100
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_table3_kernel.py --all      # the 24 jobs of Table 3

``--depth-scale 0`` means L-BFGS on the shapes. Writes ``--out``/table3_kernel.csv (one row per case
and variant).
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pandas as pd
from _common import check_blas, parser, timed, write_csv

from nldr.datasets import load_mocap
from nldr.kernels import d_max_width, d_med_width
from nldr.nrsfm import (
    CameraFrameVariables,
    OrthographicReprojection,
    e3d,
    random_visibility_mask,
    stack_to_rows,
)
from nldr.nrsfm._reconstruct import trace_norm_heuristic
from nldr.regularizer import minimize_regularized, reduced_energy

TAU = 1e-4
WIDTHS = {"d_max": d_max_width, "d_med": d_med_width}


def reference_shapes(runs: Path, job_id: str) -> dict:
    """Method -> (shape, gamma) from a previous run's job (empty if that job is not there)."""
    npz, csv = runs / f"{job_id}.npz", runs / f"{job_id}.csv"
    if not npz.is_file() or not csv.is_file():
        return {}
    arrays, rows = np.load(npz), pd.read_csv(csv).set_index("method")
    return {
        str(m): (arrays[f"shape_{i}"], float(rows.loc[str(m), "gamma"]))
        for i, m in enumerate(arrays["methods"])
        if str(m).startswith("Kernel")
    }


def run_case(name, frac, seed, widths, variants, data_dir, runs, step=10):
    seq = load_mocap(name, data_dir).subsample(step)
    W2d, X_gt = stack_to_rows(seq.W, dim=2), stack_to_rows(seq.S, dim=3)
    F, P = W2d.shape[0], W2d.shape[1] // 2
    mask = np.ones((F, P), dtype=bool) if frac == 0 else random_visibility_mask(F, P, frac, seed)
    data_term = OrthographicReprojection(W2d, mask, seq.R)
    job_id = f"{name}_{'full' if frac == 0 else 'missing'}_seed{seed}"
    ref = reference_shapes(runs, job_id)
    tnh = trace_norm_heuristic(W2d, mask, seq.R, method="admm", tol=1e-6)
    out = []
    for width in widths:
        gamma = WIDTHS[width](tnh.x)
        for variant in variants:
            opts = dict(variant)
            depth_scale = opts.pop("depth_scale")
            opts["options"] = {key: opts.pop(key) for key in ("tol", "gtol", "stage_tol")}  # solver options
            opts["options"]["scale"] = 1.0  # Table 3's units (config table3.regularizer.scale)
            if depth_scale:
                opts["variables"] = CameraFrameVariables(seq.R, mask, depth_scale)
            cpu, res = timed(
                lambda gamma=gamma, opts=opts: minimize_regularized(
                    data_term, tnh.x, gamma=gamma, tau=TAU, center=False, **opts
                ),
                clock="cpu",
            )
            row = {
                "job": job_id, "width": width, "F": F, "depth_scale": depth_scale,
                "rho_growth": opts["rho_growth"], "stage_tol": opts["options"]["stage_tol"],
                "cpu_seconds": cpu, "nit": res.nit, "converged": res.success, "energy": res.fun,
                "e3d": e3d(res.x, X_gt, P),
            }  # fmt: skip
            if f"Kernel {width}" in ref:
                S_ref, gamma_ref = ref[f"Kernel {width}"]
                ref_energy, _ = reduced_energy(
                    S_ref, data_term, gamma=gamma_ref, tau=TAU, rho=opts["rho_max"]
                )
                row.update(
                    ref_energy=ref_energy, rel_energy=res.fun / ref_energy - 1.0, ref_e3d=e3d(S_ref, X_gt, P)
                )
                row["rel_e3d"] = row["e3d"] / row["ref_e3d"] - 1.0
            print(
                " ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()),
                flush=True,
            )
            out.append(row)
    return out


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--sequences", nargs="+", default=["pickup", "stretch"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[2016], help="mask seeds of the 50 %% setting")
    ap.add_argument("--no-full", action="store_true", help="skip the full-data setting")
    ap.add_argument(
        "--all", action="store_true", help="Table 3's 24 jobs (4 sequences, full + seeds 2016-2020)"
    )
    ap.add_argument("--widths", nargs="+", default=["d_max", "d_med"])
    ap.add_argument("--depth-scale", nargs="+", type=float, default=[0.0, 100.0])
    ap.add_argument("--rho-growth", nargs="+", type=float, default=[10.0])
    ap.add_argument("--stage-tol", nargs="+", type=float, default=[1e-12])
    ap.add_argument("--tol", type=float, default=1e-12)
    ap.add_argument("--gtol", type=float, default=1e-10)
    ap.add_argument("--rho-max", type=float, default=1e3)
    ap.add_argument("--step", type=int, default=10, help="every step-th frame (table3_full: 1)")
    ap.add_argument("--reference-runs", type=Path, default=Path("results/runs/table3"))
    args = ap.parse_args(argv)
    if args.quick:
        args.sequences, args.seeds, args.widths = ["pickup"], [], ["d_med"]
    check_blas()
    if args.all:
        args.sequences, args.seeds, args.no_full = (
            ["drink", "pickup", "yoga", "stretch"],
            list(range(2016, 2021)),
            False,
        )
    settings = ([] if args.no_full else [(0.0, 2016)]) + [(0.5, s) for s in args.seeds]
    variants = [
        dict(
            depth_scale=b,
            rho0=1e-3,
            rho_growth=g,
            rho_max=args.rho_max,
            tol=args.tol,
            gtol=args.gtol,
            stage_tol=st,
        )
        for b, g, st in itertools.product(args.depth_scale, args.rho_growth, args.stage_tol)
    ]
    rows = []
    for name in args.sequences:
        for frac, seed in settings:
            case = (name, frac, seed, args.widths, variants, args.data_dir, args.reference_runs, args.step)
            rows += run_case(*case)
    table = pd.DataFrame(rows)
    write_csv(table, args.out, "table3_kernel.csv")
    keys = ["depth_scale", "rho_growth", "stage_tol"]
    cols = ["cpu_seconds", "nit"] + [c for c in ("rel_energy", "rel_e3d") if c in table]
    print(table.groupby(keys)[cols].agg(["sum", "max"] if "rel_energy" not in table else "max").to_string())
    print(table.groupby(keys)["cpu_seconds"].sum().rename("total CPU s").to_string())


if __name__ == "__main__":
    main()
