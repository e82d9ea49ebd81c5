"""The paper's figures, drawn from the pipeline's outputs; importable by the pipeline and notebooks alike.

Each function takes tidy frames or arrays (never paths) and returns a matplotlib Figure; the caller
saves or shows it. matplotlib is imported inside the functions, so the solver library does not need it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

__all__ = ["figure3", "figure1"]


def figure3(curves: pd.DataFrame):
    """Figure 3: manifold error against rank, one panel per noise level.

    Parameters
    ----------
    curves : DataFrame
        :func:`nldr.experiments.table1.figure3_curves` output: ``noise_std, method`` ("KPCA" or
        "CFS"), ``rank, error, error_min, error_max`` (relative manifold errors, dimensionless).
    """
    import matplotlib.pyplot as plt

    levels = sorted(curves["noise_std"].unique())
    fig, axes = plt.subplots(1, len(levels), figsize=(4.2 * len(levels), 3.6), sharey=False, squeeze=False)
    for ax, std in zip(axes[0], levels, strict=True):
        kpca = curves[(curves["noise_std"] == std) & (curves["method"] == "KPCA")]
        cfs = curves[(curves["noise_std"] == std) & (curves["method"] == "CFS")]
        ax.plot(kpca["rank"], kpca["error"], ":", marker="D", ms=3, color="tab:gray", label="KPCA")
        ax.errorbar(
            cfs["rank"],
            cfs["error"],
            yerr=[cfs["error"] - cfs["error_min"], cfs["error_max"] - cfs["error"]],
            fmt="-*",
            ms=6,
            color="tab:blue",
            ecolor="tab:blue",
            capsize=2,
            label="closed form (range over tau)",
        )
        upper = min(1.0, 2.5 * float(kpca["error"].min()))
        ax.set_ylim(0.8 * float(cfs["error_min"].min()), upper)
        ax.set_xlim(0, 40)
        ax.set_title(f"noise std {std:g}")
        ax.set_xlabel("rank of the recovered kernel")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(r"$\|K_{est}-K_{gt}\|_F^2 / \|K_{gt}\|_F^2$")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    return fig


def figure1(reconstructions: Mapping, bones: Mapping, *, ours: str = "Kernel d_med", n_frames: int = 3):
    """Figure 1: sample frames per sequence, ground-truth wire-frame (red), the kernel regularizer
    (blue dots) and TNH (black crosses); observed points circled, missing ones in squares.

    Parameters
    ----------
    reconstructions : mapping of sequence name -> :class:`nldr.experiments.mocap.Reconstructions`
    bones : mapping of sequence name -> sequence of (i, j) point-index pairs (the skeleton)
    ours : str
        Method drawn as "ours" (falls back to the first non-TNH method).
    n_frames : int
        Evenly spaced frames per sequence.
    """
    import matplotlib.pyplot as plt

    from .nrsfm import center_per_frame

    sequences = list(reconstructions)
    fig = plt.figure(figsize=(3.2 * n_frames, 3.0 * len(sequences)))
    for row, seq in enumerate(sequences):
        rec = reconstructions[seq]
        label = ours if ours in rec.shapes else next(m for m in rec.shapes if m != "TNH")
        P = rec.mask.shape[1]
        gt = center_per_frame(rec.ground_truth, P)
        est = {m: center_per_frame(rec.shapes[m], P) for m in ("TNH", label)}
        F = gt.shape[0]
        for col, f in enumerate(np.linspace(0, F - 1, n_frames + 2, dtype=int)[1:-1]):
            ax = fig.add_subplot(len(sequences), n_frames, row * n_frames + col + 1, projection="3d")
            g = gt[f].reshape(3, P)
            for i, j in bones[seq]:
                ax.plot(*g[:, [i, j]], color="red", lw=1)
            o = est[label][f].reshape(3, P)
            t = est["TNH"][f].reshape(3, P)
            ax.scatter(*o, color="blue", s=6, depthshade=False, label=f"ours ({label})")
            ax.scatter(*t, color="black", marker="x", s=10, lw=0.7, depthshade=False, label="TNH")
            seen = rec.mask[f]
            ax.scatter(*g[:, seen], facecolors="none", edgecolors="red", s=30, lw=0.6, depthshade=False)
            ax.scatter(
                *g[:, ~seen], marker="s", facecolors="none", edgecolors="red", s=30, lw=0.6, depthshade=False
            )
            ax.set_title(f"{seq}, frame {f + 1}/{F}", fontsize=8)
            ax.set_axis_off()
            ax.view_init(elev=10, azim=-70)
            if row == 0 and col == 0:
                ax.legend(fontsize=6, loc="upper left")
    fig.tight_layout()
    return fig
