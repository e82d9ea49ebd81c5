"""Benchmark: exact-fit TNH by ADMM (nldr.nrsfm._admm) against SCS, subsampled and full-length sequences.

Both through ``nldr.nrsfm.trace_norm_heuristic``: ``method="admm"`` and ``method="cvxpy"`` (SCS).

For each CMU mocap sequence (drink, pickup, yoga, stretch), ground-truth cameras, original units:

- every 10th frame (the paper's Table 3 protocol), full data and 50% of the (frame, point)
  observations removed (``random_visibility_mask``, seed 2016, as in results/runs/table3): ADMM
  time, iterations and e3D, against SCS (the cvxpy backend's default, eps 1e-6) time and e3D;
- every frame (drink 1102 frames, pickup 357, yoga 307, stretch 370), full data and 50% missing:
  ADMM only (SCS cannot handle these sizes).

SCS numbers are taken from results/runs/table3/<sequence>_{full,missing}_seed2016.{csv,npz} when those
files exist and hold the same mask (e3D and ||X||_* are recomputed from the stored TNH shapes; time and
iterations are the pipeline's, measured under whatever load the machine had then). Otherwise, or
with ``--rerun-scs``, SCS is run here; drink with full data is by far the slowest SCS solve,
``--skip-slow-scs`` skips it.

Usage (from the repository root; one BLAS thread by default, the machine is shared)::

    NLDR_DATA_MIRROR=/work/shared/data .venv/bin/python benchmarks/bench_tnh_admm.py
    .venv/bin/python benchmarks/bench_tnh_admm.py --sequences pickup --steps 10 --rerun-scs

Writes results/benchmarks/tnh_admm.csv (``--csv`` to change) and prints a summary table.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from nldr.datasets import load_mocap
from nldr.nrsfm import trace_norm_heuristic
from nldr.nrsfm._layout import random_visibility_mask, stack_to_rows
from nldr.nrsfm._metrics import e3d
from nldr.result import STATUS_NAMES

REPO = Path(__file__).resolve().parents[1]
SEQUENCES = ("drink", "pickup", "yoga", "stretch")
SEED = 2016
MISSING = 0.5
FIELDS = [
    "sequence",
    "step",
    "n_frames",
    "setting",
    "admm_time",
    "admm_iter",
    "admm_status",
    "admm_e3d",
    "admm_nuclear_norm",
    "admm_duality_gap",
    "admm_max_abs_residual",
    "scs_source",
    "scs_time",
    "scs_iter",
    "scs_e3d",
    "scs_nuclear_norm",
    "e3d_diff",
]


def nuclear_norm(X) -> float:
    return float(np.linalg.svd(X, compute_uv=False).sum())


def stored_scs(name: str, setting: str, mask: np.ndarray, X_gt: np.ndarray, P: int, runs_dir: Path):
    """SCS TNH from a table3 run (same sequence, setting, seed and mask), or None."""
    label = "full" if setting == "full" else "missing"
    csv_path = runs_dir / f"{name}_{label}_seed{SEED}.csv"
    npz_path = runs_dir / f"{name}_{label}_seed{SEED}.npz"
    if not (csv_path.is_file() and npz_path.is_file()):
        return None
    with open(csv_path, newline="") as fh:
        rows = [row for row in csv.DictReader(fh) if row["method"] == "TNH"]
    data = np.load(npz_path)
    methods = [str(m) for m in data["methods"]]
    if not rows or "TNH" not in methods or not np.array_equal(data["mask"], mask):
        return None
    if "SCS" not in rows[0]["message"]:
        return None
    X = data[f"shape_{methods.index('TNH')}"]
    if X.shape != X_gt.shape:
        return None
    return {
        "scs_source": str(csv_path.relative_to(REPO)) if csv_path.is_relative_to(REPO) else str(csv_path),
        "scs_time": float(rows[0]["seconds"]),
        "scs_iter": int(rows[0]["n_iter"]),
        "scs_e3d": e3d(X, X_gt, P),
        "scs_nuclear_norm": nuclear_norm(X),
    }


def run_scs(W2d, R, mask, X_gt, P):
    start = time.perf_counter()
    res = trace_norm_heuristic(W2d, R, mask, method="cvxpy", solver="SCS")
    return {
        "scs_source": f"run here ({res.message})",
        "scs_time": time.perf_counter() - start,
        "scs_iter": res.nit,
        "scs_e3d": e3d(res.x, X_gt, P),
        "scs_nuclear_norm": res.nuclear_norm,
    }


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sequences", nargs="+", default=list(SEQUENCES))
    parser.add_argument("--steps", nargs="+", type=int, default=[10, 1], help="frame subsampling steps")
    parser.add_argument("--tol", type=float, default=None, help="ADMM tolerance (default: solve_admm's)")
    parser.add_argument("--max-iter", type=int, default=None, help="ADMM iteration cap")
    parser.add_argument("--rerun-scs", action="store_true", help="run SCS instead of reusing table3 runs")
    parser.add_argument("--skip-slow-scs", action="store_true", help="never run SCS on drink full")
    parser.add_argument("--runs-dir", default=str(REPO / "results" / "runs" / "table3"))
    parser.add_argument("--threads", type=int, default=1, help="BLAS threads")
    parser.add_argument("--data-dir", default=None, help="data folder (default resources/)")
    parser.add_argument("--csv", default=str(REPO / "results" / "benchmarks" / "tnh_admm.csv"))
    args = parser.parse_args(argv)
    admm_options = {}
    if args.tol is not None:
        admm_options["tol"] = args.tol
    if args.max_iter is not None:
        admm_options["max_iter"] = args.max_iter

    rows = []
    header = (
        f"{'sequence':8} {'step':>4} {'F':>5} {'setting':8} {'ADMM[s]':>8} {'iters':>6} {'e3D ADMM':>9} "
        f"{'SCS[s]':>7} {'e3D SCS':>8} {'|diff|':>8}  ||X||_* ADMM/SCS - 1"
    )
    print(header, flush=True)
    with threadpool_limits(args.threads):
        for step in args.steps:
            for name in args.sequences:
                seq = load_mocap(name, data_dir=args.data_dir).subsample(step)
                F, P = seq.n_frames, seq.n_points
                W2d, X_gt = stack_to_rows(seq.W, 2), stack_to_rows(seq.S)
                for setting in ("full", "missing50"):
                    mask = (
                        np.ones((F, P), dtype=bool)
                        if setting == "full"
                        else random_visibility_mask(F, P, MISSING, random_state=SEED)
                    )
                    with warnings.catch_warnings(record=True) as caught:
                        warnings.simplefilter("always", RuntimeWarning)
                        res = trace_norm_heuristic(W2d, seq.R, mask, method="admm", **admm_options)
                    for w in caught:
                        print(f"  warning: {w.message}", flush=True)
                    row = {
                        "sequence": name,
                        "step": step,
                        "n_frames": F,
                        "setting": setting,
                        "admm_time": res.wall_time,
                        "admm_iter": res.nit,
                        "admm_status": STATUS_NAMES[res.status],
                        "admm_e3d": e3d(res.x, X_gt, P),
                        "admm_nuclear_norm": res.nuclear_norm,
                        "admm_duality_gap": res.duality_gap,
                        "admm_max_abs_residual": res.max_abs_residual,
                    }
                    scs = None
                    if step == 10:
                        slow = name == "drink" and setting == "full"
                        if not args.rerun_scs:
                            scs = stored_scs(name, setting, mask, X_gt, P, Path(args.runs_dir))
                        if scs is None and not (slow and args.skip_slow_scs):
                            scs = run_scs(W2d, seq.R, mask, X_gt, P)
                        if scs is None:
                            scs = {"scs_source": "skipped (--skip-slow-scs)"}
                    else:
                        scs = {"scs_source": "not run (step != 10)"}
                    row |= scs
                    row["e3d_diff"] = abs(row["admm_e3d"] - row["scs_e3d"]) if "scs_e3d" in row else ""
                    rows.append(row)
                    rel = (
                        f"{row['admm_nuclear_norm'] / row['scs_nuclear_norm'] - 1:+.1e}"
                        if "scs_nuclear_norm" in row
                        else ""
                    )
                    scs_time = f"{row['scs_time']:7.1f}" if "scs_time" in row else f"{'-':>7}"
                    scs_e3d = f"{row['scs_e3d']:8.5f}" if "scs_e3d" in row else f"{'-':>8}"
                    diff = f"{row['e3d_diff']:8.1e}" if row["e3d_diff"] != "" else f"{'-':>8}"
                    print(
                        f"{name:8} {step:>4} {F:>5} {setting:8} {row['admm_time']:8.2f} "
                        f"{row['admm_iter']:>6} {row['admm_e3d']:9.5f} {scs_time} {scs_e3d} {diff}  {rel}"
                        + ("" if res.success else f"  [{STATUS_NAMES[res.status]}]"),
                        flush=True,
                    )
    out = Path(args.csv)
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=FIELDS)
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {out}")
    return rows


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
