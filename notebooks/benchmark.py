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
# # Benchmark: our defaults against the imputers people use, beyond oil flow
#
# Not in the paper. `KernelRegularizerImputer()` with no arguments (its defaults choose its settings
# from the observed entries) against missForest (100 trees), the Bayesian GP-LVM with missing data
# (GPy), scikit-learn's KNNImputer and IterativeImputer (BayesianRidge), SoftImpute and the column
# means. Data: oil flow at 100 and 1000 rows, and the sets that ship inside scikit-learn (wine, breast
# cancer, diabetes, digits; row subsamples drawn with the config's seed). Missingness: MCAR at three
# rates, MAR (half the columns drive the other half's missingness) and MNAR (large values more likely
# hidden); `nldr.experiments._missingness` gives each formula.
#
# Every peer's knob is chosen by hold-out CV on the observed entries of each cell's first mask and
# reused on its other masks; ground truth only scores. RMSE is over the hidden entries, in units of
# each column's full-data sd, so data sets compare. The runs happened upstream
# (`snakemake -c 2 benchmark`); this notebook reads their outputs.

# %% tags=["parameters"]
configfile = ""  # "": config/config.yaml (the full protocol); or e.g. "config/quick.yaml"
workdir = ""  # folder the paths below are relative to; "": the repository (found from its Snakefile)
results = ""  # the results folder; "": the config's (results/, or results/quick/ for quick.yaml)
table = ""  # "": <results>/tables/benchmark.csv
runs = []  # per-job CSVs; empty: every file in <results>/runs/benchmark/
arrays = []
figures = []
settings = {}  # the experiment's config block as the pipeline ran it; empty: the config's
data_dir = ""  # folder holding the data; "": the config's data.dir

# %%
from pathlib import Path

import numpy as np
import pandas as pd
from IPython.display import Image, Markdown, display

from nldr import tables
from nldr.experiments._benchmark import ranks
from nldr.experiments.notebook import locate

nb = locate("benchmark", configfile, workdir, results, table, runs, arrays, settings, data_dir)
root, results, settings, table_path, run_paths = nb.root, nb.results, nb.settings, nb.table, nb.runs

# %% [markdown]
# ## Summary: mean rank and wins
# `mean_rank`: the mean over cells of each method's mean rank over the cell's masks (1 = best);
# `wins`: cells where the method had the lowest mean RMSE. Overall, per data set and per mechanism.

# %%
result = pd.read_csv(table_path)
summary = result[result["setting"].str.match(r"all$|dataset=|mechanism=")]
wide = summary.pivot_table(index="method", columns=["setting", "metric"], values="value", sort=False)
display(wide.round(2))

# %% [markdown]
# ## RMSE per cell (mean ± sd over the masks)

# %%
cells = result[~result["setting"].str.match(r"all$|dataset=|mechanism=")]
display(Markdown(tables.to_markdown(cells, digits=3, metrics=["rmse"], transpose=True)))

# %%
for figure in figures or [results / "figures/benchmark_ranks.png"]:
    if Path(figure).exists():
        display(Image(filename=str(figure)))

# %% [markdown]
# ## Oil flow: Table 2's error (SSE over the whole matrix), ours against missForest and GP-LVM
# Mean ± sd over the masks, and the ratio of the means (ours / peer).

# %%
runs_frame = pd.concat([pd.read_csv(p) for p in run_paths], ignore_index=True)
oil = runs_frame[runs_frame["dataset"].str.startswith("oil") & (runs_frame["mechanism"] == "MCAR")]
sse = oil.groupby(["dataset", "p", "method"])["sse"].agg(["mean", "std", "count"]).unstack("method")
display(sse.round(2))
means = sse["mean"]
for peer in [m for m in ("missForest", "GP-LVM") if m in means.columns and "Ours" in means.columns]:
    print(f"Ours / {peer}:", (means["Ours"] / means[peer]).round(3).to_dict())

# %% [markdown]
# ## CPU seconds per fit (mean over masks) and of each cell's tuning
# From the jobs' timings files (`results/timings/benchmark/`), apart from the run files, which are the
# same on every rerun; the tuned methods' names come from the jobs' arrays.

# %%
rows = []
for run, arr, times in zip(run_paths, nb.arrays, nb.timings, strict=True):
    measured_path = Path(times).with_suffix(".npz")
    if not (Path(arr).exists() and measured_path.exists()):
        continue
    frame = pd.read_csv(run)
    with np.load(arr) as data, np.load(measured_path) as measured:
        frame["cpu_seconds"] = measured["cpu_seconds"]
        methods = data["tune_methods"].tolist()
        tune = dict(zip(methods, measured["tune_cpu_seconds"].tolist(), strict=True))
    frame["tune_cpu_seconds"] = frame["method"].map(tune)
    rows.append(frame)
if rows:
    timing = pd.concat(rows, ignore_index=True)
    display(
        timing.groupby(["dataset", "method"])[["cpu_seconds", "tune_cpu_seconds"]]
        .mean()
        .unstack("method")
        .round(2)
    )

# %% [markdown]
# ## What CV chose, per cell

# %%
display(
    runs_frame[runs_frame["mask"] == 0][["cell", "method", "params"]].pivot(index="cell", columns="method")
)
cells_frame = ranks(runs_frame)
