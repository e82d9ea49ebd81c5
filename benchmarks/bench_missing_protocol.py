"""Experiment (issue 17, item 3): which reading of "randomly removing 50 % of the image measurements"
matches the paper's TNH column of Table 3 (ground-truth cameras, 50 % missing)?

TNH is convex, so its e3D with known cameras depends only on the data, the mask and tau, not on our
kernel solver: it checks the missing-data protocol independently. For each of the four sequences
(every 10th frame, as Table 3) and ``--n-masks`` seeded masks per reading, TNH's exact fit
(:func:`~nldr.nrsfm.trace_norm_heuristic`, ADMM, the Table 3 default) is solved under each reading:

``uniform``
    ``round(0.5 F P)`` (frame, point) pairs hidden uniformly without replacement (today's default,
    :func:`~nldr.nrsfm.random_visibility_mask`).
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
    own solver for that problem is not published).

Mask k of every reading uses seed ``seed + k`` (the uniform masks are Table 3's). Prints per reading
and sequence the mean ± sd of e3D over the masks and its relative difference to the paper, and the
mean absolute relative difference over the four sequences. Writes
results/benchmarks/missing_protocol.csv.

Measured (5 masks per reading, mean abs. relative difference to the paper over the four
sequences): uniform 9.1 %, per_frame 8.6 %, per_track 5.5 %, runs 50 %, coordinates 9.9 %; the
penalised form at tau = 1e-7 by FISTA is far from converged after 20000 iterations (pickup e3D
1.07, 174 CPU s), so it is no practical reading.

Usage (from the repository root)::

    .venv/bin/python benchmarks/bench_missing_protocol.py --n-masks 5
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
from threadpoolctl import threadpool_limits

from nldr import paper
from nldr.datasets import load_mocap
from nldr.nrsfm import e3d, random_visibility_mask, stack_to_rows, trace_norm_heuristic
from nldr.nrsfm._reprojection import visibility_weights
from nldr.nrsfm._tnh import fista_tnh

OUT = Path("results/benchmarks/missing_protocol.csv")
SEQUENCES = ("drink", "pickup", "yoga", "stretch")
READINGS = ("uniform", "per_frame", "per_track", "runs", "coordinates", "penalised")


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


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n-masks", type=int, default=5)
    parser.add_argument("--seed", type=int, default=2016)
    parser.add_argument("--readings", nargs="+", default=list(READINGS), choices=READINGS)
    parser.add_argument("--sequences", nargs="+", default=list(SEQUENCES), choices=SEQUENCES)
    parser.add_argument("--run-length", type=float, default=5.0)
    parser.add_argument("--penalised-max-iter", type=int, default=20000)
    parser.add_argument("--data", default=None, help="data directory (default: the project's)")
    parser.add_argument("--check", action="store_true", help="check exact_fit_coordinates first")
    args = parser.parse_args(argv)
    if args.check:
        seq = load_mocap("pickup", args.data).subsample(10)
        W2d, Xgt = stack_to_rows(seq.W, dim=2), stack_to_rows(seq.S, dim=3)
        F, P = W2d.shape[0], W2d.shape[1] // 2
        mask = random_visibility_mask(F, P, 0.5, args.seed)
        ours = exact_fit_coordinates(W2d, seq.R, np.repeat(mask[:, None, :], 2, axis=1))
        lib = trace_norm_heuristic(W2d, seq.R, mask).x
        print(f"check: e3d coordinate ADMM {e3d(ours, Xgt, P):.5f}, library ADMM {e3d(lib, Xgt, P):.5f}")
    table = paper.paper_frame(paper.TABLE3)
    rows = []
    with threadpool_limits(1):
        for name in args.sequences:
            seq = load_mocap(name, args.data).subsample(10)
            W2d, Xgt = stack_to_rows(seq.W, dim=2), stack_to_rows(seq.S, dim=3)
            F, P = W2d.shape[0], W2d.shape[1] // 2
            ref = table[(table.setting == f"{name.capitalize()} missing50") & (table.method == "TNH")]
            for reading in args.readings:
                for k in range(args.n_masks):
                    mask = make_mask(reading, F, P, args.seed + k, args.run_length)
                    cpu = time.process_time()
                    if reading == "coordinates":
                        x = exact_fit_coordinates(W2d, seq.R, mask)
                        res = type("Fit", (), {"x": x, "nit": 0})
                    elif reading == "penalised":
                        res = penalised_tnh(W2d, seq.R, mask, 1e-7, args.penalised_max_iter)
                    else:
                        res = trace_norm_heuristic(W2d, seq.R, mask)
                    rows.append(
                        {
                            "sequence": name,
                            "reading": reading,
                            "seed": args.seed + k,
                            "observed": float(mask.mean()),
                            "e3d": e3d(res.x, Xgt, P),
                            "paper": float(ref["paper"].iloc[0]),
                            "nit": int(res.nit),
                            "cpu_s": time.process_time() - cpu,
                        }
                    )
                    r = rows[-1]
                    print(
                        f"{name:8s} {reading:10s} seed {r['seed']} e3d {r['e3d']:.4f} "
                        f"(paper {r['paper']:.4f}) {r['nit']} it {r['cpu_s']:.1f} s",
                        flush=True,
                    )
    df = pd.DataFrame(rows)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(OUT, index=False)
    agg = df.groupby(["reading", "sequence"], sort=False).agg(
        mean=("e3d", "mean"), sd=("e3d", "std"), paper=("paper", "first")
    )
    agg["rel"] = agg["mean"] / agg["paper"] - 1
    print(agg.to_string(float_format=lambda v: f"{v:.4f}"))
    summary = agg.groupby("reading", sort=False)["rel"].agg(
        mean_abs_rel=lambda r: float(np.mean(np.abs(r))), mean_rel="mean"
    )
    print(summary.to_string(float_format=lambda v: f"{v:+.3f}"))


if __name__ == "__main__":
    main()
