"""Figure 3: manifold error against rank, KPCA per rank and the closed form per rank it produced."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
from _pipeline import atomic_path, setup  # noqa: E402

from nldr.experiments.table1 import figure3_curves  # noqa: E402

sm = snakemake  # noqa: F821
log = setup(sm)
curves = figure3_curves(pd.concat([pd.read_csv(path) for path in sm.input], ignore_index=True))
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
with atomic_path(sm.output[0]) as tmp:
    fig.savefig(tmp, dpi=130, format="png")
log.info("wrote %s", sm.output[0])
