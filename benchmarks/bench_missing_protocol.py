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
``penalised``
    the uniform masks, TNH solved as the paper's penalised problem at tau = 1e-7 (FISTA, in the
    data's units) instead of the exact fit; ``--penalised-max-iter`` bounds its iterations (the paper's
    own solver for that problem is not published).

Mask k of every reading uses seed ``seed + k`` (the uniform masks are Table 3's). Prints per reading
and sequence the mean ± sd of e3D over the masks and its relative difference to the paper, and the
mean absolute relative difference over the four sequences. Writes
results/benchmarks/missing_protocol.csv.

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

OUT = Path("results/benchmarks/missing_protocol.csv")
SEQUENCES = ("drink", "pickup", "yoga", "stretch")
READINGS = ("uniform", "per_frame", "per_track", "runs", "penalised")


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


def make_mask(reading, F, P, seed, run_length):
    if reading in ("uniform", "penalised"):
        return random_visibility_mask(F, P, 0.5, seed)
    if reading == "per_frame":
        return per_frame_mask(F, P, seed)
    if reading == "per_track":
        return per_track_mask(F, P, seed)
    if reading == "runs":
        return runs_mask(F, P, seed, run_length)
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
    args = parser.parse_args(argv)
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
                    if reading == "penalised":
                        res = trace_norm_heuristic(
                            W2d, seq.R, mask, tau=1e-7, method="fista", max_iter=args.penalised_max_iter
                        )
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
