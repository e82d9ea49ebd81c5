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
# # Table 1 and Figure 3: closed-form robust KPCA on noisy oil flow
#
# The paper's first experiment checks the C-step of its regularizer on its own. Gaussian noise is
# added to the 1000 oil-flow training points; the RBF kernel of the noisy data is then denoised
# either by **KPCA** (keep the r leading eigenpairs) or by the **closed form** (CFS) of
#
# $$\min_C\ \tau\|C\|_* + \tfrac{\rho}{2}\|K - C^\top C\|_F^2 ,$$
#
# which keeps the eigenvectors and maps every eigenvalue $\lambda$ to $l^2$, with $l$ the best
# non-negative root of $l^3 - \lambda l + \tau/(2\rho) = 0$ (or zero). Each estimate is scored by
# its distance to the kernel of the clean data, and the best setting of each method by 1-NN
# classification of the 1000 clean test points projected onto its manifold.
#
# The heavy work ran upstream in the pipeline (`snakemake -c all table1`); this notebook reads its
# outputs. Run it in Jupyter from the repository after the pipeline, or let the pipeline execute it.

# %% tags=["parameters"]
configfile = ""  # "": config/config.yaml (the paper's protocol); or e.g. "config/quick.yaml"
workdir = ""  # folder the paths below are relative to; "": the repository (found from its Snakefile)
results = ""  # the results folder; "": the config's (results/, or results/quick/ for quick.yaml)
table = ""  # "": <results>/tables/table1.csv, results folder from the config
figures = []  # the pipeline's figure files (this notebook draws Figure 3 itself)
runs = []  # per-draw CSVs; empty: every file in <results>/runs/table1/
arrays = []  # per-draw arrays (none for Table 1)
settings = {}  # the experiment's config block as the pipeline ran it; empty: the config's
data_dir = ""  # folder holding oil/ and nrsfm/; "": the config's data.dir

# %%

import numpy as np
import pandas as pd
from IPython.display import Markdown, display

from nldr import tables
from nldr.experiments._table1 import figure3_curves
from nldr.experiments.notebook import locate
from nldr.plotting import figure3
from nldr.robust_kpca import rank_penalty_threshold, shrink_eigenvalues

# the repository (by its Snakefile), the config and this run's files
nb = locate("table1", configfile, workdir, results, table, runs, arrays, settings, data_dir)
root, config, results, settings, data_dir = nb.root, nb.config, nb.results, nb.settings, nb.data_dir
table_path, run_paths, array_paths = nb.table, nb.runs, nb.arrays

# %% [markdown]
# ## What the closed form does to a spectrum
# Eigenvalues at or below $\lambda^\star = 3\,(b^2/2)^{1/3}$, $b = \tau/(2\rho)$, vanish; larger ones
# shrink, the smaller the more. This is why the closed form can beat hard truncation: it also damps
# the noisy tail of the components it keeps.

# %%
lam = np.geomspace(0.05, 50, 9)
for tau in (1.0, 10.0):
    l = shrink_eigenvalues(lam, tau, 1.0)
    print(f"tau={tau:5.1f}  threshold={rank_penalty_threshold(tau, 1.0):.3f}")
    print("   lambda:", np.round(lam, 3))
    print("   l^2   :", np.round(l**2, 3))

# %% [markdown]
# ## Table 1
# Cells read *ours ± sd over noise draws (paper)*. Manifold error is
# $\|K_{est}-K_{gt}\|_F^2/\|K_{gt}\|_F^2$ on centred kernels; classification error in percent.

# %%
result = pd.read_csv(table_path)
display(Markdown(tables.to_markdown(result)))

# %% [markdown]
# Relative difference to the paper for the published numbers:

# %%
published = result.dropna(subset=["paper"]).copy()
published["rel_diff_pct"] = 100 * (published["value"] - published["paper"]) / published["paper"]
published.round(4)

# %% [markdown]
# ## Figure 3
# KPCA at every rank (dotted), and the closed form at every rank its tau sweep produced: the line
# joins the best error per rank, the shaded band spans best to worst over all tau giving that rank.
# Drawn here from the runs by `nldr.plotting.figure3`, the function the pipeline draws
# `figures/fig3.{png,pdf,svg}` with.

# %%
all_runs = pd.concat([pd.read_csv(p) for p in run_paths], ignore_index=True)
fig = figure3(figure3_curves(all_runs))

# %% [markdown]
# ## Which settings won, per draw

# %%
all_runs[all_runs["best"]][
    ["noise_std", "seed", "method", "tau", "rank", "manifold_error", "classification_error"]
].sort_values(["noise_std", "method", "seed"])
