"""Figure 1: sample frames of each sequence with 50% missing data: ground-truth skeleton (red
wire-frame), the kernel regularizer (blue dots), TNH (black crosses); observed points circled,
missing ones marked by squares."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from _pipeline import atomic_path, setup  # noqa: E402

from nldr.datasets import load_mocap  # noqa: E402
from nldr.nrsfm import center_per_frame  # noqa: E402

sm = snakemake  # noqa: F821
log = setup(sm)
N_FRAMES = 3
OURS = "Kernel d_med"

# One reconstruction per sequence: the first missing-data run (else the full-data run).
chosen = {}
for path in sorted(sm.input.shapes):
    seq, setting = Path(path).stem.split("_")[:2]
    if seq not in chosen or (setting == "missing" and "_missing_" not in chosen[seq]):
        chosen[seq] = path
sequences = list(chosen)
fig = plt.figure(figsize=(3.2 * N_FRAMES, 3.0 * len(sequences)))
for row, seq in enumerate(sequences):
    data = np.load(chosen[seq])
    methods = list(data["methods"])
    shapes = {m: data[f"shape_{i}"] for i, m in enumerate(methods)}
    ours = OURS if OURS in shapes else next(m for m in methods if m != "TNH")
    P = data["mask"].shape[1]
    gt = center_per_frame(data["ground_truth"], P)
    est = {m: center_per_frame(shapes[m], P) for m in ("TNH", ours)}
    bones = load_mocap(seq, sm.params.data_dir).bones
    F = gt.shape[0]
    for col, f in enumerate(np.linspace(0, F - 1, N_FRAMES + 2, dtype=int)[1:-1]):
        ax = fig.add_subplot(len(sequences), N_FRAMES, row * N_FRAMES + col + 1, projection="3d")
        g = gt[f].reshape(3, P)
        for i, j in bones:
            ax.plot(*g[:, [i, j]], color="red", lw=1)
        o = est[ours][f].reshape(3, P)
        t = est["TNH"][f].reshape(3, P)
        ax.scatter(*o, color="blue", s=6, depthshade=False, label=f"ours ({ours})")
        ax.scatter(*t, color="black", marker="x", s=10, lw=0.7, depthshade=False, label="TNH")
        seen = data["mask"][f]
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
with atomic_path(sm.output[0]) as tmp:
    fig.savefig(tmp, dpi=120, format="png")
log.info("wrote %s", sm.output[0])
