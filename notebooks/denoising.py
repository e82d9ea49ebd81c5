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
# # Denoising scikit-learn's digits
#
# The paper lists denoising as an application it did not show. Here the 8 x 8 digits that ship with
# scikit-learn, scaled to [0, 1], get Gaussian noise; four denoisers clean them: the regularizer
# (`Ours`, transductive on the noisy test images alone), `RobustKernelPCA` fitted on noisy training
# images and applied by its pre-image step (`complete` with every pixel observed), scikit-learn's
# `KernelPCA(fit_inverse_transform=True)` as in scikit-learn's own denoising example, and `PCA`.
# No method sees a clean image before scoring: every knob is chosen by held-out-pixel CV on the
# noisy images (hide a random half of each image's pixels, predict them from the rest, score against
# their noisy values; the noise on a hidden pixel is independent of its prediction, so the expected
# score is the clean error plus a constant).
#
# The runs happened upstream (`snakemake -c all denoising`); this notebook reads their outputs.

# %% tags=["parameters"]
configfile = ""  # "": config/config.yaml (the full protocol); or e.g. "config/quick.yaml"
workdir = ""  # folder the paths below are relative to; "": the repository (found from its Snakefile)
results = ""  # the results folder; "": the config's (results/, or results/quick/ for quick.yaml)
table = ""  # "": <results>/tables/denoising.csv
runs = []  # per-job CSVs; empty: every file in <results>/runs/denoising/
arrays = []
figures = []
settings = {}  # the experiment's config block as the pipeline ran it; empty: the config's
data_dir = ""  # folder holding the data; "": the config's data.dir

# %%
from pathlib import Path

import pandas as pd
from IPython.display import Image, Markdown, display

from nldr import tables
from nldr.experiments.notebook import locate

# the repository (by its Snakefile), the config and this run's files
nb = locate("denoising", configfile, workdir, results, table, runs, arrays, settings, data_dir)
root, results, settings, table_path, run_paths = nb.root, nb.results, nb.settings, nb.table, nb.runs

# %% [markdown]
# ## The table
# Mean squared error per pixel against the clean test images, *mean ± sd over seeds*. `mse`: all test
# images (Ours: NaN, it solves a subset); `mse_subset`: the images Ours solved.

# %%
result = pd.read_csv(table_path)
display(Markdown(tables.to_markdown(result, digits=4, metrics=["mse", "mse_subset"], transpose=True)))

# %% [markdown]
# ## The target of issue 18
# Ours or RobustKernelPCA at most the MSE of scikit-learn's KernelPCA at every noise level (compared
# on the images each method solved: RobustKernelPCA and KernelPCA on all, Ours on the subset).

# %%
wide = result.pivot(index=["setting", "method"], columns="metric", values="value")
for setting, group in wide.groupby(level=0):
    kp = group.loc[(setting, "KernelPCA")]
    line = [f"KernelPCA {kp['mse']:.5f} (subset {kp['mse_subset']:.5f})"]
    if (setting, "RobustKernelPCA") in group.index:
        line.append(f"RobustKernelPCA {group.loc[(setting, 'RobustKernelPCA')]['mse']:.5f}")
    if (setting, "Ours") in group.index:
        line.append(f"Ours (subset) {group.loc[(setting, 'Ours')]['mse_subset']:.5f}")
    print(setting + ": " + "; ".join(line))

# %% [markdown]
# ## The images

# %%
for figure in figures or [results / "figures/denoising_digits.png"]:
    if Path(figure).exists():
        display(Image(filename=str(figure)))

# %% [markdown]
# ## What CV chose, per seed

# %%
runs_frame = pd.concat([pd.read_csv(p) for p in run_paths], ignore_index=True)
display(runs_frame[["noise", "seed", "method", "mse", "mse_subset", "params"]])
