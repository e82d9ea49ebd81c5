"""Trace-norm heuristic (TNH) with ground-truth cameras on the CMU mocap sequences: solvers and
missing-data protocols.

Run as ``OPENBLAS_NUM_THREADS=1 python benchmarks/bench_tnh.py SUBCOMMAND [options]``. The protocol of
the paper's Table 3 (linear columns): every ``--step``-th frame from the first (10: Table 3), 41
points, original units, ground-truth cameras; TNH by the private
``nldr.nrsfm._reconstruct.trace_norm_heuristic`` (what ``reconstruct(..., prior="tnh")`` runs, with
each solver's options); e3D by :func:`nldr.nrsfm.e3d`, the paper's TNH e3D from :mod:`nldr.paper`
beside it.

``solvers``: TNH's exact fit (the paper's tau = 1e-7 is numerically the exact-fit problem) by each of
``--solvers``: ``ADMM`` (``method="admm"``, the library's default), ``SCS`` and ``CLARABEL``
(``method="cvxpy"``; ``--eps`` sets SCS's eps_abs = eps_rel, ``--tau`` solves the penalised problem
instead of the exact fit). Settings: full data and, per ``--seeds``, ``--missing`` of the (frame,
point) observations removed (:func:`nldr.nrsfm.random_visibility_mask`; seed 2016 is Table 3's first
mask). The conic solvers run on subsampled sequences only (``--steps`` above 1: every frame is beyond
them); ``--skip-slow-scs`` skips SCS on drink with full data, its slowest case. A CLARABEL solve runs
in a child process stopped after ``--clarabel-timeout`` seconds. Wall seconds, iterations, e3D (and
after one global alignment), nuclear norm, largest reprojection residual; then, per setting, ADMM's
e3D and nuclear norm against SCS's. Writes ``--out``/tnh.csv.

``protocol``: which reading of "randomly removing 50 % of the image measurements" matches the paper's
TNH column with 50 % missing? TNH is convex with known cameras, so its e3D depends only on the data,
the mask and tau, not on the kernel solver: it checks the missing-data protocol independently. For
each sequence (every 10th frame) and ``--n-masks`` masks per reading (mask k with seed ``--seed`` + k;
the uniform masks are Table 3's), TNH's exact fit (ADMM) under each reading:

``uniform``
    ``round(0.5 F P)`` (frame, point) pairs hidden uniformly without replacement (Table 3's,
    :func:`nldr.nrsfm.random_visibility_mask`).
``per_frame``
    exactly half of each frame's points hidden (P odd: floor or ceil of P/2 alternately).
``per_track``
    exactly half of each point's frames hidden.
``runs``
    occlusion-like: each point hidden over contiguous runs of frames (run lengths geometric with
    mean ``--run-length``, gaps alike) so that about half its frames are hidden.
``coordinates``
    half of the 2FP image coordinates hidden independently (x and y of a point separately), the
    exact fit solved by :func:`exact_fit_coordinates` (the library's solvers take point masks);
    ``--check`` first verifies that solver against the library's ADMM on a point mask.
``penalised``
    the uniform masks, TNH solved as the paper's penalised problem at tau = 1e-7 (FISTA, in the
    data's units) instead of the exact fit; ``--penalised-max-iter`` bounds its iterations (the paper's
    own solver for that problem is not published). The library's FISTA for it,
    :func:`nldr.nrsfm._tnh.fista_tnh` with :func:`nldr.nrsfm._reprojection.visibility_weights`, is
    private (the step of Table 4's alternation); this reading measures that solver itself.

Prints per reading and sequence the mean ± sd of e3D over the masks and its relative difference to the
paper, and the mean absolute relative difference over the sequences; CPU seconds per solve. Writes
``--out``/missing_protocol.csv.

Usage (from the repository root)::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_tnh.py solvers --steps 10 1
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_tnh.py solvers --solvers SCS CLARABEL --seeds 0 1
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_tnh.py solvers --solvers SCS --eps 1e-5 1e-7 --tau 1e-4
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_tnh.py protocol --n-masks 5
"""

from __future__ import annotations

import multiprocessing as mp

import numpy as np
import pandas as pd
from _common import check_blas, common_options, parser, timed, write_csv

from nldr import paper
from nldr.datasets import load_mocap
from nldr.nrsfm import e3d, random_visibility_mask, stack_to_rows
from nldr.nrsfm._reconstruct import trace_norm_heuristic
from nldr.nrsfm._reprojection import visibility_weights
from nldr.nrsfm._tnh import fista_tnh
from nldr.result import STATUS_NAMES

SEQUENCES = ("drink", "pickup", "yoga", "stretch")
SOLVERS = ("ADMM", "SCS", "CLARABEL")
READINGS = ("uniform", "per_frame", "per_track", "runs", "coordinates", "penalised")
PAPER = paper.paper_frame(paper.TABLE3).query("method == 'TNH'").set_index("setting")["paper"]


def paper_e3d(name: str, missing: bool) -> float:
    """The paper's TNH e3D of a sequence (Table 3), full data or 50 % missing."""
    return float(PAPER[f"{name.capitalize()} {'missing50' if missing else 'full'}"])


# ---------------------------------------------------------------------------------------------- solvers


def solve(W2d, R, mask, solver, tau, eps, admm_options):
    if solver == "ADMM":
        return trace_norm_heuristic(W2d, mask, R, method="admm", **admm_options)
    options = None if eps is None else {"eps_abs": eps, "eps_rel": eps}
    return trace_norm_heuristic(W2d, mask, R, tau=tau, method="cvxpy", solver=solver, solver_options=options)


def _child(queue, args):
    try:
        queue.put(("ok", solve(*args)))
    except Exception as exc:  # report any failure to the parent instead of hanging it
        queue.put(("error", f"{type(exc).__name__}: {exc}"))


def solve_with_timeout(args, timeout):
    """Run :func:`solve` in a child process; return (result or None, message)."""
    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_child, args=(queue, args))
    child.start()
    try:
        kind, payload = queue.get(timeout=timeout)
    except Exception:  # queue.Empty: the solve did not finish in time
        child.terminate()
        child.join()
        return None, f"timeout > {timeout:g} s"
    child.join()
    return (payload, "") if kind == "ok" else (None, payload)


def run_solvers(args):
    if args.quick:
        args.sequences, args.steps, args.seeds = ["pickup"], [10], [2016]
    admm_options = {k: v for k, v in (("tol", args.tol), ("max_iter", args.max_iter)) if v is not None}
    rows = []
    for step in args.steps:
        for name in args.sequences:
            seq = load_mocap(name, data_dir=args.data_dir).subsample(step)
            F, P = seq.n_frames, seq.n_points
            W2d, X_gt = stack_to_rows(seq.W, 2), stack_to_rows(seq.S)
            settings = [("full", np.ones((F, P), dtype=bool))]
            settings += [
                (f"missing seed {s}", random_visibility_mask(F, P, args.missing, s)) for s in args.seeds
            ]
            for setting, mask in settings:
                for solver in args.solvers:
                    if solver != "ADMM" and step == 1:
                        continue
                    if solver == "SCS" and args.skip_slow_scs and name == "drink" and setting == "full":
                        continue
                    for eps in args.eps if solver == "SCS" else [None]:
                        call = (W2d, seq.R, mask, solver, args.tau, eps, admm_options)
                        if solver == "CLARABEL":
                            wall, (res, message) = timed(
                                lambda call=call: solve_with_timeout(call, args.clarabel_timeout)
                            )
                        else:
                            wall, res = timed(lambda call=call: solve(*call))
                            message = ""
                        row = {
                            "sequence": name, "step": step, "n_frames": F, "setting": setting,
                            "solver": solver, "eps": eps, "tau": 0.0 if solver == "ADMM" else args.tau or 0.0,
                            "paper_e3d": paper_e3d(name, setting != "full"), "wall_time": wall,
                        }  # fmt: skip
                        if res is None:
                            row["status"] = message
                        else:
                            row |= {
                                "e3d": e3d(res.x, X_gt, P), "e3d_aligned": e3d(res.x, X_gt, P, align=True),
                                "nit": res.nit, "nuclear_norm": res.nuclear_norm,
                                "max_abs_residual": res.max_abs_residual, "duality_gap": res.duality_gap,
                                "status": STATUS_NAMES.get(res.status, res.status), "message": res.message,
                            }  # fmt: skip
                        rows.append(row)
                        print(
                            f"{name:8} {F:>5} {setting:16} {solver:8} {str(eps or ''):>7} "
                            f"e3D {row.get('e3d', np.nan):8.5f} (paper {row['paper_e3d']:.4f}) "
                            f"{wall:8.2f} s {row.get('nit', '')!s:>6} it  {row['status']}",
                            flush=True,
                        )
    table = pd.DataFrame(rows)
    write_csv(table, args.out, "tnh.csv")
    if not table.empty and {"ADMM", "SCS"} <= set(table["solver"]) and "e3d" in table:
        keys = ["sequence", "n_frames", "setting"]
        admm = table[table["solver"] == "ADMM"]
        scs = table[table["solver"] == "SCS"].groupby(keys, as_index=False).first()
        both = admm.merge(scs, on=keys, suffixes=("", "_scs")).set_index(keys)
        both["e3d_diff"] = (both["e3d"] - both["e3d_scs"]).abs()
        both["nuclear_ratio_minus_1"] = both["nuclear_norm"] / both["nuclear_norm_scs"] - 1
        print("\nADMM against SCS:")
        cols = ["wall_time", "wall_time_scs", "e3d", "e3d_scs", "e3d_diff", "nuclear_ratio_minus_1"]
        print(both[cols].to_string(float_format=lambda v: f"{v:.3g}"))


# ---------------------------------------------------------------------------------------------- protocol


def per_frame_mask(F, P, seed):
    """Exactly half of each frame's points hidden (floor and ceil of P/2 alternately for odd P)."""
    rng = np.random.default_rng(seed)
    mask = np.ones((F, P), dtype=bool)
    for f in range(F):
        k = P // 2 + (P % 2) * (f % 2)
        mask[f, rng.choice(P, size=k, replace=False)] = False
    return mask


def per_track_mask(F, P, seed):
    """Exactly half of each point's frames hidden (transpose of :func:`per_frame_mask`)."""
    return per_frame_mask(P, F, seed).T.copy()


def runs_mask(F, P, seed, run_length=5.0):
    """Occlusion-like: per point, alternating visible and hidden runs of geometric length (mean
    ``run_length`` frames), random phase; about half of each track hidden."""
    rng = np.random.default_rng(seed)
    mask = np.ones((F, P), dtype=bool)
    for j in range(P):
        hidden = bool(rng.integers(2))
        f = 0
        while f < F:
            n = int(rng.geometric(1.0 / run_length))
            if hidden:
                mask[f : f + n, j] = False
            f += n
            hidden = not hidden
    # every frame needs at least one observed point (the exact fit stays defined)
    for f in np.flatnonzero(~mask.any(axis=1)):
        mask[f, rng.integers(P)] = True
    return mask


def exact_fit_coordinates(W2d, R, cmask, *, max_iter=20000, tol=1e-7):
    """min ||X||_* subject to R_f s_f(x_j)[c] = w_f(x_j)[c] for every observed coordinate (f, c, j).

    ADMM on X = Z: X <- projection onto the constraints of Z - U (the camera rows are orthonormal, so
    the projection is s - R_f^T diag(m) (R_f s - w) point by point), Z <- singular value thresholding of
    X + U at 1 / beta, U <- U + X - Z; beta balanced on the primal and dual residuals. Stops when both
    relative residuals are below ``tol``. cmask: bool (F, 2, P). Returns X (F, 3P).
    """
    F = R.shape[0]
    P = W2d.shape[1] // 2
    W3 = np.where(cmask, W2d.reshape(F, 2, P), 0.0)
    m = cmask.astype(float)

    def project(V):
        res = (np.einsum("fcd,fdp->fcp", R, V) - W3) * m
        return V - np.einsum("fcd,fcp->fdp", R, res)

    X = project(np.zeros((F, 3, P)))
    beta = 1.0 / max(np.linalg.norm(X.reshape(F, 3 * P), 2), 1e-12) * 10
    Z, U = X.copy(), np.zeros_like(X)
    for _ in range(max_iter):
        X = project(Z - U)
        Y = (X + U).reshape(F, 3 * P)
        u, sv, vt = np.linalg.svd(Y, full_matrices=False)
        Z_new = ((u * np.maximum(sv - 1.0 / beta, 0.0)) @ vt).reshape(F, 3, P)
        r = np.linalg.norm(X - Z_new) / max(np.linalg.norm(X), 1e-300)
        d = beta * np.linalg.norm(Z_new - Z) / max(beta * np.linalg.norm(U), 1e-300)
        U += X - Z_new
        Z = Z_new
        if r < tol and d < tol:
            break
        if r > 10 * d:
            beta *= 2.0
            U /= 2.0
        elif d > 10 * r:
            beta /= 2.0
            U *= 2.0
    return project(Z).reshape(F, 3 * P)


def penalised_tnh(W2d, R, mask, tau, max_iter):
    """The penalised TNH at ``tau`` by FISTA from zeros (the alternation's shape step, fista_tnh)."""
    F, P = mask.shape
    W3 = np.where(np.concatenate([mask, mask], axis=1), W2d, 0.0).reshape(F, 2, P)
    return fista_tnh(W3, visibility_weights(mask), R, np.zeros((F, 3, P)), 0.0, tau, max_iter, 1e-10)


def make_mask(reading, F, P, seed, run_length):
    if reading in ("uniform", "penalised"):
        return random_visibility_mask(F, P, 0.5, seed)
    if reading == "per_frame":
        return per_frame_mask(F, P, seed)
    if reading == "per_track":
        return per_track_mask(F, P, seed)
    if reading == "runs":
        return runs_mask(F, P, seed, run_length)
    if reading == "coordinates":
        cmask = np.ones(F * 2 * P, dtype=bool)
        cmask[np.random.default_rng(seed).choice(F * 2 * P, size=F * P, replace=False)] = False
        return cmask.reshape(F, 2, P)
    raise ValueError(f"reading must be one of {READINGS}; got {reading!r}")


def solve_reading(reading, W2d, R, mask, penalised_max_iter):
    """``(X, iterations)`` of TNH under one reading's mask."""
    if reading == "coordinates":
        return exact_fit_coordinates(W2d, R, mask), 0
    if reading == "penalised":
        res = penalised_tnh(W2d, R, mask, 1e-7, penalised_max_iter)
    else:
        res = trace_norm_heuristic(W2d, mask, R)
    return res.x, res.nit


def run_protocol(args):
    if args.quick:
        args.sequences, args.n_masks = ["pickup"], 1
        args.readings = [r for r in args.readings if r != "penalised"]
    if args.check:
        seq = load_mocap("pickup", args.data_dir).subsample(10)
        W2d, Xgt = stack_to_rows(seq.W, dim=2), stack_to_rows(seq.S, dim=3)
        F, P = W2d.shape[0], W2d.shape[1] // 2
        mask = random_visibility_mask(F, P, 0.5, args.seed)
        ours = exact_fit_coordinates(W2d, seq.R, np.repeat(mask[:, None, :], 2, axis=1))
        lib = trace_norm_heuristic(W2d, mask, seq.R).x
        print(f"check: e3d coordinate ADMM {e3d(ours, Xgt, P):.5f}, library ADMM {e3d(lib, Xgt, P):.5f}")
    rows = []
    for name in args.sequences:
        seq = load_mocap(name, args.data_dir).subsample(10)
        W2d, Xgt = stack_to_rows(seq.W, dim=2), stack_to_rows(seq.S, dim=3)
        F, P = W2d.shape[0], W2d.shape[1] // 2
        for reading in args.readings:
            for k in range(args.n_masks):
                mask = make_mask(reading, F, P, args.seed + k, args.run_length)
                call = (reading, W2d, seq.R, mask, args.penalised_max_iter)
                cpu, (x, nit) = timed(lambda call=call: solve_reading(*call), clock="cpu")
                row = {
                    "sequence": name, "reading": reading, "seed": args.seed + k,
                    "observed": float(mask.mean()), "e3d": e3d(x, Xgt, P), "paper": paper_e3d(name, True),
                    "nit": int(nit), "cpu_s": cpu,
                }  # fmt: skip
                rows.append(row)
                print(
                    f"{name:8s} {reading:10s} seed {row['seed']} e3d {row['e3d']:.4f} "
                    f"(paper {row['paper']:.4f}) {row['nit']} it {row['cpu_s']:.1f} s",
                    flush=True,
                )
    df = pd.DataFrame(rows)
    write_csv(df, args.out, "missing_protocol.csv")
    agg = df.groupby(["reading", "sequence"], sort=False).agg(
        mean=("e3d", "mean"), sd=("e3d", "std"), paper=("paper", "first")
    )
    agg["rel"] = agg["mean"] / agg["paper"] - 1
    print(agg.to_string(float_format=lambda v: f"{v:.4f}"))
    summary = agg.groupby("reading", sort=False)["rel"].agg(
        mean_abs_rel=lambda r: float(np.mean(np.abs(r))), mean_rel="mean"
    )
    print(summary.to_string(float_format=lambda v: f"{v:+.3f}"))


def main(argv=None):
    ap = parser(__doc__, options=False)
    sub = ap.add_subparsers(dest="command", required=True)

    sol = common_options(sub.add_parser("solvers", help="ADMM, SCS and CLARABEL on Table 3's TNH"))
    sol.add_argument("--sequences", nargs="+", default=list(SEQUENCES), choices=SEQUENCES)
    sol.add_argument("--steps", nargs="+", type=int, default=[10], help="keep every step-th frame")
    sol.add_argument("--solvers", nargs="+", default=["ADMM", "SCS"], type=str.upper, choices=SOLVERS)
    sol.add_argument("--eps", nargs="+", type=float, default=[None], help="SCS eps_abs = eps_rel values")
    sol.add_argument("--tau", type=float, default=None, help="penalised TNH at this tau (cvxpy)")
    sol.add_argument("--seeds", nargs="*", type=int, default=[2016], help="mask seeds (none: full data only)")
    sol.add_argument("--missing", type=float, default=0.5, help="share of observations removed")
    sol.add_argument("--tol", type=float, default=None, help="ADMM tolerance (default: the library's)")
    sol.add_argument("--max-iter", type=int, default=None, help="ADMM iteration cap")
    sol.add_argument("--skip-slow-scs", action="store_true", help="no SCS on drink with full data")
    sol.add_argument("--clarabel-timeout", type=float, default=120.0)
    sol.set_defaults(run=run_solvers)

    pro = common_options(sub.add_parser("protocol", help="readings of '50 %% missing' against the paper"))
    pro.add_argument("--n-masks", type=int, default=5)
    pro.add_argument("--seed", type=int, default=2016)
    pro.add_argument("--readings", nargs="+", default=list(READINGS), choices=READINGS)
    pro.add_argument("--sequences", nargs="+", default=list(SEQUENCES), choices=SEQUENCES)
    pro.add_argument("--run-length", type=float, default=5.0)
    pro.add_argument("--penalised-max-iter", type=int, default=20000)
    pro.add_argument("--check", action="store_true", help="check exact_fit_coordinates first")
    pro.set_defaults(run=run_protocol)

    args = ap.parse_args(argv)
    check_blas()
    args.run(args)


if __name__ == "__main__":
    main()
