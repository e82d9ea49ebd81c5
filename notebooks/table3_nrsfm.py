# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Table 3 and Figure 1: non-rigid structure from motion with known cameras
#
# Each frame f of a CMU mocap sequence shows 41 points through a known orthographic camera,
# $w_f = R_f s_f$. Recovering the 3D shapes $s_f$ from 2 of their 3 coordinates needs a prior.
# **TNH** asks the shape matrix to have a small trace norm (a *linear* low-rank prior); here it is
# solved in its exact-fit limit by ADMM (cvxpy's SCS agrees; docs/REPRODUCTION.md#table-3-tnh).
# The **kernel regularizer** starts from TNH and asks the
# shapes' RBF features to be low-rank instead (a *non-linear* prior), with τ = 1e-4 and the kernel
# width set from the TNH shapes by the maximum-distance ($d_{max}$) or median-distance ($d_{med}$)
# rule. Both are scored by the normalised mean 3D error e3D.
#
# The runs happened upstream (`snakemake -c all table3`); this notebook reads their outputs.

# %% tags=["parameters"]
configfile = ""  # "": config/config.yaml (the paper's protocol); or e.g. "config/quick.yaml"
workdir = ""  # folder the paths below are relative to; "": the repository (found from its Snakefile)
results = ""  # the results folder; "": the config's (results/, or results/quick/ for quick.yaml)
table = ""  # "": <results>/tables/table3.csv, results folder from the config
figures = []  # the pipeline's figure files (this notebook draws Figure 1 itself)
runs = []  # per-run CSVs; empty: every file in <results>/runs/table3/
arrays = []  # per-run reconstructions (.npz); empty: those beside the CSVs
settings = {}  # the experiment's config block as the pipeline ran it; empty: the config's
data_dir = ""  # folder holding oil/ and nrsfm/; "": the config's data.dir

# %%
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from IPython.display import HTML, Markdown, display
from matplotlib import animation

from nldr import tables
from nldr.experiments import get
from nldr.experiments._mocap import Reconstructions
from nldr.experiments.notebook import locate
from nldr.nrsfm import center_per_frame

# the repository (by its Snakefile), the config and this run's files
nb = locate("table3", configfile, workdir, results, table, runs, arrays, settings, data_dir)
root, config, results, settings, data_dir = nb.root, nb.config, nb.results, nb.settings, nb.data_dir
table_path, run_paths, array_paths = nb.table, nb.runs, nb.arrays

# %% [markdown]
# ## Table 3
# Cells read *ours (paper)*; with missing data *mean ± sd over seeded masks (paper)*. The paper
# shows one mask per sequence.

# %%
result = pd.read_csv(table_path)
display(Markdown(tables.to_markdown(result, metrics=["e3d"])))

# %% [markdown]
# Spread of the missing-data runs (one row per mask) and time per job:

# %%
all_runs = nb.read_runs()  # the run files with their timings (seconds) beside them
all_runs.pivot_table(
    index=["sequence", "missing_fraction", "seed"], columns="method", values="e3d", sort=False
).round(4)

# %%
all_runs.groupby(["sequence", "method"])["seconds"].median().unstack().round(1)

# %% [markdown]
# ## Figure 1
# Red wire-frame: ground truth; blue dots: the kernel regularizer; black crosses: TNH. Red circles
# mark points whose projection was observed in that frame, squares those that were missing. Drawn
# here from the runs by the pipeline's own code (`Table3.draw`, which calls `nldr.plotting.figure1`;
# change `n_frames` or `ours` there to explore); the pipeline's copies are `figures/fig1.{png,pdf,svg}`.

# %%
fig1_arrays = {p.stem: np.load(p) for p in array_paths}
fig = get("table3").draw("fig1", all_runs, fig1_arrays, data_dir)

# %% [markdown]
# ## A reconstructed sequence, turning
# The first missing-data run of the first sequence, one frame, seen from all around.

# %%
shape_files = [Path(a) for a in arrays] or [p.with_suffix(".npz") for p in run_paths]
npz = [p for p in shape_files if "_missing_" in p.name] or shape_files
rec = Reconstructions.from_arrays(np.load(npz[0]))
methods = list(rec.shapes)
P = rec.mask.shape[1]
f = rec.ground_truth.shape[0] // 2
gt = center_per_frame(rec.ground_truth, P)[f].reshape(3, P)
ours = center_per_frame(rec.shapes[methods[-1]], P)[f].reshape(3, P)
tnh = center_per_frame(rec.shapes["TNH"], P)[f].reshape(3, P)
fig = plt.figure(figsize=(4, 4))
ax = fig.add_subplot(projection="3d")
ax.scatter(*gt, color="red", s=12, label="ground truth")
ax.scatter(*ours, color="blue", s=6, label=methods[-1])
ax.scatter(*tnh, color="black", marker="x", s=8, label="TNH")
ax.set_axis_off()
ax.legend(fontsize=7)
ax.set_title(npz[0].stem, fontsize=8)
spin = animation.FuncAnimation(fig, lambda k: ax.view_init(elev=15, azim=k * 15), frames=24, interval=150)
plt.close(fig)
HTML(spin.to_jshtml())
