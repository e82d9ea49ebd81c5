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

    Every point is inside its panel (log error axis); the closed form's line joins its best error per
    rank and the shaded band spans its best to worst over every tau giving that rank, drawn under the
    markers so no marker hides behind a bar.

    Parameters
    ----------
    curves : DataFrame
        :func:`nldr.experiments._table1.figure3_curves` output: ``noise_std, method`` ("KPCA" or
        "CFS"), ``rank, error, error_min, error_max`` (relative manifold errors, dimensionless).
    """
    import matplotlib.pyplot as plt
    from matplotlib.ticker import LogLocator, ScalarFormatter

    levels = sorted(curves["noise_std"].unique())
    fig, axes = plt.subplots(1, len(levels), figsize=(4.0 * len(levels), 3.5), squeeze=False)
    for ax, std in zip(axes[0], levels, strict=True):
        kpca = curves[(curves["noise_std"] == std) & (curves["method"] == "KPCA")].sort_values("rank")
        cfs = curves[(curves["noise_std"] == std) & (curves["method"] == "CFS")].sort_values("rank")
        ax.fill_between(
            cfs["rank"],
            cfs["error_min"],
            cfs["error_max"],
            color="tab:blue",
            alpha=0.18,
            lw=0,
            step=None,
            label="closed form: best to worst over tau",
            zorder=1,
        )
        ax.plot(kpca["rank"], kpca["error"], ":", marker="D", ms=3.5, color="0.35", label="KPCA", zorder=3)
        ax.plot(
            cfs["rank"],
            cfs["error"],
            "-",
            marker="*",
            ms=7,
            color="tab:blue",
            mec="white",
            mew=0.4,
            label="closed form (ours): best per rank",
            zorder=4,
        )
        values = np.concatenate([kpca["error"], cfs["error_min"], cfs["error_max"]])
        ax.set_yscale("log")
        ax.set_ylim(0.9 * values.min(), 1.1 * values.max())  # every point inside the panel
        ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.yaxis.set_major_formatter(ScalarFormatter())
        ax.yaxis.set_minor_formatter(ScalarFormatter() if values.max() / values.min() < 4 else "")
        ax.set_xlim(0, max(40, float(curves["rank"].max()) + 1))
        ax.set_title(f"noise std {std:g}")
        ax.set_xlabel("rank of the recovered kernel")
        ax.grid(alpha=0.3, which="both")
    axes[0][0].set_ylabel("relative kernel error\n" + r"$\|K_{est}-K_{gt}\|_F^2\, /\, \|K_{gt}\|_F^2$")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=3, fontsize=9, frameon=False)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    return fig


def _frame_numbers(n_shown: int, total: int | None) -> tuple[np.ndarray, str, str]:
    """1-based frame numbers in the sequence for ``n_shown`` frames taken every s-th from the first of
    ``total`` (s = ceil(total / n_shown), checked), the title pattern, and a note on the sampling;
    without ``total`` (or if no such s gives ``n_shown``), positions among the frames reconstructed."""
    if total:
        step = -(-total // n_shown)
        if -(-total // step) == n_shown:
            every = "every frame" if step == 1 else f"every {step}th frame from the first"
            return np.arange(n_shown) * step + 1, f"frame {{}} of {total}", f"{every} reconstructed"
    return np.arange(n_shown) + 1, f"reconstructed frame {{}} of {n_shown}", ""


def _sampling_note(notes: list) -> str:
    """'seq: note; seq: note.', or 'Every sequence: note.' when every sequence has the same note."""
    kinds = {n.split(": ", 1)[1] for n in notes if n}
    if len(kinds) == 1 and all(notes):
        return f"Every sequence: {kinds.pop()}."
    return "; ".join(n for n in notes if n) + "."


def figure1(
    reconstructions: Mapping,
    bones: Mapping,
    *,
    ours: str = "Kernel d_med",
    n_frames: int = 3,
    total_frames: Mapping | None = None,
):
    """Figure 1: sample frames per sequence: the ground-truth wire-frame (red), the kernel regularizer
    (blue dots) and TNH (black crosses); ground-truth points observed in the frame circled, missing
    ones in squares. One legend for the figure names every mark.

    Parameters
    ----------
    reconstructions : mapping of sequence name -> :class:`nldr.experiments._mocap.Reconstructions`
    bones : mapping of sequence name -> sequence of (i, j) point-index pairs (the skeleton)
    ours : str
        Method drawn as "ours" (falls back to the first non-TNH method).
    n_frames : int
        Evenly spaced frames per sequence.
    total_frames : mapping of sequence name -> int, optional
        Frames of the whole sequence, so panel titles give the frame's number in the sequence (the
        reconstructions hold every s-th frame from the first); without it, titles count the frames
        reconstructed.
    """
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from .nrsfm import center_per_frame

    sequences = list(reconstructions)
    fig = plt.figure(figsize=(3.4 * n_frames, 3.3 * len(sequences) + 0.8))
    label, notes = ours, []
    for row, seq in enumerate(sequences):
        rec = reconstructions[seq]
        label = ours if ours in rec.shapes else next(m for m in rec.shapes if m != "TNH")
        P = rec.mask.shape[1]
        gt = center_per_frame(rec.ground_truth, P)
        est = {m: center_per_frame(rec.shapes[m], P) for m in ("TNH", label)}
        F = gt.shape[0]
        numbers, title, note = _frame_numbers(F, (total_frames or {}).get(seq))
        notes.append(f"{seq}: {note}" if note else "")
        for col, f in enumerate(np.linspace(0, F - 1, n_frames + 2, dtype=int)[1:-1]):
            ax = fig.add_subplot(len(sequences), n_frames, row * n_frames + col + 1, projection="3d")
            g = gt[f].reshape(3, P)
            for i, j in bones[seq]:
                ax.plot(*g[:, [i, j]], color="red", lw=1)
            o = est[label][f].reshape(3, P)
            t = est["TNH"][f].reshape(3, P)
            ax.scatter(*o, color="blue", s=9, depthshade=False)
            ax.scatter(*t, color="black", marker="x", s=14, lw=0.8, depthshade=False)
            seen = rec.mask[f]
            ax.scatter(*g[:, seen], facecolors="none", edgecolors="red", s=34, lw=0.7, depthshade=False)
            ax.scatter(
                *g[:, ~seen], marker="s", facecolors="none", edgecolors="red", s=34, lw=0.7, depthshade=False
            )
            centre, half = g.mean(axis=1), 0.5 * np.ptp(g, axis=1).max()
            ax.set(
                xlim=centre[0] + [-half, half], ylim=centre[1] + [-half, half], zlim=centre[2] + [-half, half]
            )
            ax.set_box_aspect((1, 1, 1))  # equal scales: the skeleton is not stretched
            ax.set_title(f"{seq}, " + title.format(numbers[f]), fontsize=10)
            ax.set_axis_off()
            ax.view_init(elev=10, azim=-70)
    marks = [
        Line2D([], [], color="red", lw=1, label="ground truth (wire-frame)"),
        Line2D([], [], ls="", marker="o", ms=7, mfc="none", mec="red", label="ground truth, observed"),
        Line2D([], [], ls="", marker="s", ms=7, mfc="none", mec="red", label="ground truth, missing"),
        Line2D([], [], ls="", marker="o", ms=4, color="blue", label=f"ours ({label})"),
        Line2D([], [], ls="", marker="x", ms=6, color="black", label="TNH"),
    ]
    height = fig.get_figheight()
    fig.legend(
        handles=marks,
        loc="lower center",
        bbox_to_anchor=(0.5, 0.3 / height),
        ncol=len(marks),
        fontsize=10,
        frameon=False,
    )
    if any(notes):  # how the frames shown were sampled, once for the figure
        fig.text(
            0.5, 0.1 / height, _sampling_note(notes), ha="center", va="bottom", fontsize=9
        )
    fig.subplots_adjust(left=0.0, right=1.0, top=0.95, bottom=0.8 / height, wspace=0.0, hspace=0.08)
    return fig
