"""Benchmark: one evaluation of Table 4's TNH with estimated cameras, before and after the speed-up.

Each case runs :func:`~nldr.nrsfm._camera_refinement.tnh_with_camera_refinement` once, as the tau search
of :func:`~nldr.experiments._table4.run_sequence` does for every tau it tries (both private: this
measures that internal alternation, which the public :func:`nldr.nrsfm.reconstruct` runs inside its
search): CMU mocap, every 10th frame, 41 points, cameras from :func:`nldr.nrsfm.initialize_cameras`,
full data or 50 % of the (frame, point) observations hidden (``random_visibility_mask(F, P, 0.5,
2016)``), default tolerances (joint energy, 1e-8 over 10 outer iterations); e3D after one global
orthogonal alignment.

"Before" is the implementation the speed-up replaced (commit c0e25fc: FISTA to a fixed 1e-12 with a
full SVD per thresholding, the camera LM on the explicit Jacobian), timed on this machine (2 shared
cores, BLAS on 1 thread, other jobs running: timings vary by up to 50 % from run to run) and stored
in :data:`BEFORE`. ``--reference`` also reruns
:func:`~nldr.reference.nrsfm.tnh_with_camera_refinement_reference` (the fixed-tolerance,
full-SVD alternation on today's camera LM) next to the new code, under the same load.

The two implementations stop at slightly different points on the way to the same fixed point (and at
slightly different global rotations, which e3D aligns away), so e3D agrees only to the stopping
rule's own precision. ``--check`` fails if any e3D moves by more than 1e-4.

Wall seconds (``time.perf_counter``). Usage (from the repository root; ``--quick``: pickup, full
data, tau = 1)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_table4.py                 # all 32 cases
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_table4.py --sequences pickup yoga --taus 0.3 1 10 \
        --settings full
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_table4.py --reference     # also time the reference live
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_table4.py --run-sequence  # also one run_sequence (pickup)

Writes ``--out``/table4_tnh.csv (one row per sequence, setting and tau).
"""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd
from _common import check_blas, parser, timed, write_csv

from nldr.datasets import load_mocap
from nldr.nrsfm import e3d, initialize_cameras, random_visibility_mask, stack_to_rows
from nldr.nrsfm._camera_refinement import tnh_with_camera_refinement
from nldr.reference.nrsfm import tnh_with_camera_refinement_reference

# (seconds, outer iterations, e3D) of the replaced implementation, keyed "sequence/setting/tau".
BEFORE = {
    "pickup/full/0.1": (21.18, 1350, 0.12681052),
    "pickup/full/0.3": (6.07, 493, 0.12940338),
    "pickup/full/1": (1.42, 165, 0.14073292),
    "pickup/full/10": (0.44, 35, 0.35772598),
    "pickup/missing/0.1": (15.80, 704, 0.16927390),
    "pickup/missing/0.3": (4.25, 255, 0.17235101),
    "pickup/missing/1": (1.05, 87, 0.19820719),
    "pickup/missing/10": (0.28, 21, 0.52975821),
    "yoga/full/0.1": (26.43, 1729, 0.29560203),
    "yoga/full/0.3": (7.41, 630, 0.29570008),
    "yoga/full/1": (2.43, 212, 0.29401663),
    "yoga/full/10": (0.25, 25, 0.41248645),
    "yoga/missing/0.1": (22.82, 996, 0.20874708),
    "yoga/missing/0.3": (6.10, 337, 0.21121531),
    "yoga/missing/1": (1.74, 107, 0.23299955),
    "yoga/missing/10": (0.24, 22, 0.61572701),
    "drink/full/0.1": (166.58, 1402, 0.09436135),
    "drink/full/0.3": (19.75, 505, 0.09482350),
    "drink/full/1": (5.06, 167, 0.09847050),
    "drink/full/10": (0.79, 26, 0.15746572),
    "drink/missing/0.1": (99.14, 737, 0.09635248),
    "drink/missing/0.3": (26.51, 266, 0.09819872),
    "drink/missing/1": (11.58, 90, 0.10662939),
    "drink/missing/10": (2.44, 20, 0.25256985),
    "stretch/full/0.1": (72.03, 2406, 0.10933247),
    "stretch/full/0.3": (17.70, 842, 0.11124009),
    "stretch/full/1": (4.51, 313, 0.12243754),
    "stretch/full/10": (0.39, 30, 0.35987197),
    "stretch/missing/0.1": (37.74, 1004, 0.14986942),
    "stretch/missing/0.3": (9.05, 366, 0.15192582),
    "stretch/missing/1": (3.37, 129, 0.25663768),
    "stretch/missing/10": (0.45, 26, 0.50748213),
}
# One whole run_sequence (pickup, full data, seed 2016) with the replaced implementation: seconds, e3D
# of the tuned TNH.
BEFORE_RUN_SEQUENCE = (255.6, 0.12684797)


def run_case(seq, setting, tau, reference):
    W2d = stack_to_rows(seq.W, dim=2)
    X_gt = stack_to_rows(seq.S, dim=3)
    F, P = W2d.shape[0], W2d.shape[1] // 2
    mask = np.ones((F, P), dtype=bool) if setting == "full" else random_visibility_mask(F, P, 0.5, 2016)
    R0 = initialize_cameras(W2d, mask)
    seconds, res = timed(lambda: tnh_with_camera_refinement(W2d, mask, R0, tau))
    row = {
        "after_seconds": seconds,
        "after_n_outer": res.nit,
        "after_e3d": e3d(res.x, X_gt, P, align=True),
        "after_converged": res.success,
    }
    if reference:
        seconds, ref = timed(lambda: tnh_with_camera_refinement_reference(W2d, mask, R0, tau))
        row.update(
            reference_seconds=seconds,
            reference_n_outer=ref.nit,
            reference_e3d=e3d(ref.x, X_gt, P, align=True),
        )
    return row


def main(argv=None):
    ap = parser(__doc__)
    ap.add_argument("--sequences", nargs="+", default=["pickup", "yoga", "drink", "stretch"])
    ap.add_argument("--settings", nargs="+", default=["full", "missing"], choices=["full", "missing"])
    ap.add_argument("--taus", nargs="+", type=float, default=[0.1, 0.3, 1.0, 10.0])
    ap.add_argument("--reference", action="store_true", help="also time the reference implementation")
    ap.add_argument("--run-sequence", action="store_true", help="also time run_sequence on pickup")
    ap.add_argument("--check", action="store_true", help="exit 1 if an e3D moved by more than 1e-4")
    args = ap.parse_args(argv)
    if args.quick:
        args.sequences, args.settings, args.taus = ["pickup"], ["full"], [1.0]
    check_blas()

    rows = []
    for name in args.sequences:
        seq = load_mocap(name, args.data_dir).subsample(10)
        for setting in args.settings:
            for tau in args.taus:
                key = f"{name}/{setting}/{tau:g}"
                row = {"sequence": name, "setting": setting, "tau": tau}
                if key in BEFORE:
                    b_sec, b_outer, b_e3d = BEFORE[key]
                    row.update(before_seconds=b_sec, before_n_outer=b_outer, before_e3d=b_e3d)
                row.update(run_case(seq, setting, tau, args.reference))
                row["speedup"] = row.get("before_seconds", np.nan) / row["after_seconds"]
                row["e3d_change"] = row["after_e3d"] - row.get("before_e3d", np.nan)
                rows.append(row)
                print(
                    f"{key:20s} before {row.get('before_seconds', np.nan):7.2f} s "
                    f"({row.get('before_n_outer', 0):5d} outer)  after {row['after_seconds']:6.2f} s "
                    f"({row['after_n_outer']:5d} outer)  x{row['speedup']:5.1f}  "
                    f"e3d {row['after_e3d']:.6f} (change {row['e3d_change']:+.1e})",
                    flush=True,
                )
    table = pd.DataFrame(rows)
    write_csv(table, args.out, "table4_tnh.csv")
    known = table.dropna(subset=["before_seconds"])
    if len(known):
        total_before, total_after = known["before_seconds"].sum(), known["after_seconds"].sum()
        speedup = known["speedup"]
        print(
            f"total {total_before:.1f} s -> {total_after:.1f} s: speed-up "
            f"x{total_before / total_after:.1f} (per case: median x{speedup.median():.1f}, "
            f"min x{speedup.min():.1f}, max x{speedup.max():.1f}); "
            f"largest |e3D change| {known['e3d_change'].abs().max():.1e}"
        )
    if args.reference:
        gap = (table["after_e3d"] - table["reference_e3d"]).abs().max()
        print(
            f"live reference {table['reference_seconds'].sum():.1f} s -> "
            f"{table['after_seconds'].sum():.1f} s; largest |e3D(after) - e3D(reference)| {gap:.1e}"
        )
    if args.run_sequence:
        from nldr.experiments._table4 import run_sequence

        seq = load_mocap("pickup", args.data_dir).subsample(10)
        seconds, run = timed(lambda: run_sequence(seq, missing_fraction=0.0, seed=2016))
        tnh = run.rows.set_index("method").loc["TNH"]
        print(
            f"run_sequence(pickup, full): {BEFORE_RUN_SEQUENCE[0]:.1f} s -> {seconds:.1f} s "
            f"(x{BEFORE_RUN_SEQUENCE[0] / seconds:.1f}); TNH e3d {BEFORE_RUN_SEQUENCE[1]:.6f} -> "
            f"{tnh['e3d']:.6f}, tau* {tnh['tau']:.4g}"
        )
    if args.check and len(known) and known["e3d_change"].abs().max() > 1e-4:
        print("e3D changed by more than 1e-4", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
