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
# # Robust completion: a Huber data term against gross errors
#
# The paper closes by noting that its framework "could trivially incorporate robust functions like the
# L1 norm". This notebook measures that promise. The first 100 oil-flow rows are the clean matrix; a
# share of the observed entries (5 %, 10 %, 20 %) is replaced by gross errors of 3 to 6 column standard
# deviations, with nothing missing (p = 0) or a quarter missing (p = 0.25). Every method sees only the
# corrupted observed entries and chooses its knobs by hold-out CV on them, scored by the *absolute*
# error (the hidden entries are corrupted too). The score is the sum of squared errors against the
# clean matrix over every entry.
#
# - `Ours (LS)`: the regularizer with masked least squares (tau by CV);
# - `Ours (Huber)`: the regularizer with `nldr.data_terms.MaskedHuber` (tau by CV, delta = 1.345 x the
#   MAD scale of the least-squares residuals at the same tau);
# - `RPCA`: principal component pursuit by ADMM (`nldr._baselines.rpca`), lam by CV;
# - `SoftImpute`: its low-rank fit on every entry, lam by CV;
# - `KNNImputer`: fills missing entries and keeps the observed ones, outliers included.
#
# The runs happened upstream (`snakemake -c all robust`); this notebook reads their outputs.

# %% tags=["parameters"]
configfile = ""  # "": config/config.yaml (the full protocol); or e.g. "config/quick.yaml"
workdir = ""  # folder the paths below are relative to; "": the repository (found from its Snakefile)
results = ""  # the results folder; "": the config's (results/, or results/quick/ for quick.yaml)
table = ""  # "": <results>/tables/robust.csv
runs = []  # per-job CSVs; empty: every file in <results>/runs/robust/
arrays = []
figures = []
settings = {}  # the experiment's config block as the pipeline ran it; empty: the config's
data_dir = ""  # folder holding the data; "": the config's data.dir

# %%

import matplotlib.pyplot as plt
import pandas as pd
from IPython.display import Markdown, display

from nldr import tables
from nldr.experiments.notebook import locate

# the repository (by its Snakefile), the config and this run's files
nb = locate("robust", configfile, workdir, results, table, runs, arrays, settings, data_dir)
root, results, settings, table_path, run_paths = nb.root, nb.results, nb.settings, nb.table, nb.runs

# %% [markdown]
# ## The table
# Cells read *mean ± sd over seeds*.

# %%
result = pd.read_csv(table_path)
display(Markdown(tables.to_markdown(result, digits=2, metrics=["sse"], transpose=False)))

# %% [markdown]
# ## Huber against least squares and Robust PCA, seed by seed
# The ratio of the Huber regularizer's SSE to the least-squares regularizer's and to RPCA's, per seed
# (the target: at most 0.7 against LS, below 1 against RPCA, at 10 % corruption).

# %%
all_runs = nb.read_runs()  # the run files with their timings (seconds) beside them
wide = all_runs.pivot_table(index=["p", "corrupt", "seed"], columns="method", values="sse")
ratios = pd.DataFrame(
    {
        "Huber / LS": wide["Ours (Huber)"] / wide["Ours (LS)"],
        "Huber / RPCA": wide["Ours (Huber)"] / wide["RPCA"],
    }
)
ratios.groupby(["p", "corrupt"]).agg(["mean", "std", "max"]).round(3)

# %% [markdown]
# ## SSE against the corruption share

# %%
mean = all_runs.groupby(["p", "corrupt", "method"])["sse"].mean().unstack("method")
fig, axes = plt.subplots(1, mean.index.get_level_values("p").nunique(), figsize=(10, 3.5), squeeze=False)
for ax, (p, block) in zip(axes[0], mean.groupby(level="p"), strict=True):
    for method in block.columns:
        ax.plot(block.index.get_level_values("corrupt"), block[method], marker="o", label=method)
    ax.set_yscale("log")
    ax.set_xlabel("share of observed entries corrupted")
    ax.set_ylabel("SSE against the clean matrix")
    ax.set_title(f"p = {p:g} missing")
axes[0][0].legend(fontsize=8)
fig.tight_layout()

# %% [markdown]
# ## What CV chose, and what it cost
# Wall seconds per method and corruption share, selection included (the jobs shared two cores with
# other work; the CPU time of each job is in `results/benchmarks/robust/`).

# %%
all_runs.groupby(["p", "corrupt", "method"]).agg(seconds=("seconds", "mean")).unstack("method").round(2)

# %%
all_runs[all_runs["method"] == "Ours (Huber)"][["p", "corrupt", "seed", "params"]].head(12)
