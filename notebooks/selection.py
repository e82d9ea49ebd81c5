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
# # Selection: parameters from the data alone
#
# The paper sets τ and the kernel width γ by hand. A user with new data has no ground truth, so the
# only honest score of a setting is how well it predicts observed entries it was not shown:
# `nldr.model_selection` hides a share of the *observed* entries in each of several folds, completes
# the matrix from the rest, and keeps the setting with the smallest held-out error. This notebook
# compares, on Table 2's masks, the regularizer with the paper's values, with the CV-selected values,
# and with the best grid point judged against the complete matrix. That last row is an **oracle**:
# it sees ground truth, so it only shows how good the grid can be. The baselines get the same
# folds for their own knobs.
#
# The runs happened upstream (`snakemake -c all selection`); this notebook reads their outputs.

# %% tags=["parameters"]
configfile = ""  # "": config/config.yaml (the paper's protocol); or e.g. "config/quick.yaml"
workdir = ""  # folder the paths below are relative to; "": the repository (found from its Snakefile)
results = ""  # the results folder; "": the config's (results/, or results/quick/ for quick.yaml)
table = ""  # "": <results>/tables/selection.csv, results folder from the config
runs = []  # per-mask CSVs; empty: every file in <results>/runs/selection/
arrays = []  # per-mask CV curves (.npz); empty: those beside the CSVs
figures = []
settings = {}  # the experiment's config block as the pipeline ran it; empty: the config's
data_dir = ""  # folder holding oil/ and nrsfm/; "": the config's data.dir

# %%

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from IPython.display import Markdown, display

from nldr import tables
from nldr.experiments.notebook import locate

# the repository (by its Snakefile), the config and this run's files
nb = locate("selection", configfile, workdir, results, table, runs, arrays, settings, data_dir)
root, config, results, settings, data_dir = nb.root, nb.config, nb.results, nb.settings, nb.data_dir
table_path, run_paths, array_paths = nb.table, nb.runs, nb.arrays

# %% [markdown]
# ## The table
# Cells read *mean ± sd over masks*; for the paper-values row the paper's Table 2 is in
# parentheses.

# %%
result = pd.read_csv(table_path)
display(Markdown(tables.to_markdown(result, digits=3, metrics=["sse"], transpose=True)))

# %% [markdown]
# ## What CV chose, and what it cost
# `solves` is the selection's time divided by one solve at the paper's values on the same mask.

# %%
all_runs = nb.read_runs()  # the run files with their timings (seconds) beside them
cv = all_runs[all_runs["method"] == "Ours (CV)"]
summary = cv.groupby("p").agg(
    tau=("tau", "median"), gamma=("gamma", "median"), solves=("solves", "mean"), seconds=("seconds", "mean")
)
oracle = all_runs[all_runs["method"] == "Ours (oracle grid point)"].groupby("p")[["tau", "gamma"]].median()
summary.join(oracle.add_suffix(" (oracle)")).round(4)

# %% [markdown]
# ## CV curves against the oracle's
# For the first mask at each p: the held-out error per entry (left, what CV sees) and the SSE against
# the complete matrix (right, what the oracle sees), along τ, one line per γ. A good selection rule
# needs the minima of the two panels to agree.

# %%
first = {}
for path in array_paths:
    p = path.stem.split("_")[0]
    first.setdefault(p, path)
fig, axes = plt.subplots(len(first), 2, figsize=(9, 3 * len(first)), squeeze=False)
for row, (p, path) in enumerate(sorted(first.items())):
    data = np.load(path)
    for gamma in np.unique(data["cv_gamma"]):
        sel = data["cv_gamma"] == gamma
        axes[row][0].errorbar(
            data["cv_tau"][sel],
            data["cv_error"][sel],
            yerr=data["cv_error_sd"][sel],
            marker="o",
            ms=3,
            capsize=2,
            label=f"γ = {gamma:.3g}",
        )
        sel = data["oracle_gamma"] == gamma
        axes[row][1].plot(data["oracle_tau"][sel], data["oracle_sse"][sel], marker="o", ms=3)
    for ax, label in zip(
        axes[row], ["held-out MSE per entry (CV)", "SSE vs complete matrix (oracle)"], strict=True
    ):
        ax.set_xscale("log")
        ax.set_xlabel("τ")
        ax.set_title(f"{p.replace('p', 'p = ')}: {label}", fontsize=9)
    axes[row][0].legend(fontsize=7)
fig.tight_layout()
