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
# # Out of sample: new rows on a learned manifold
#
# The paper computes pre-images only for the rows it learned its manifold from, and names "online
# inference with pre-learned low-dimensional manifolds" as future work. `RobustKernelPCA.complete`
# does it: fit once on the 1000 oil-flow training rows, then complete each new row (from
# `DataTst.txt`, never seen in the fit) by the pre-image step: the missing entries minimise the
# feature-space distance of the row to the learned principal subspace, the observed ones stay. The
# peers are fitted on the same training rows; `Ours` is the transductive joint solve on a subset.
# Every knob was chosen by hold-out CV on training rows; the test rows' ground truth only scores.
#
# The runs happened upstream (`snakemake -c all out_of_sample`); this notebook reads their outputs.

# %% tags=["parameters"]
configfile = ""  # "": config/config.yaml (the full protocol); or e.g. "config/quick.yaml"
workdir = ""  # folder the paths below are relative to; "": the repository (found from its Snakefile)
results = ""  # the results folder; "": the config's (results/, or results/quick/ for quick.yaml)
table = ""  # "": <results>/tables/out_of_sample.csv
runs = []  # per-job CSVs; empty: every file in <results>/runs/out_of_sample/
arrays = []
figures = []
settings = {}  # the experiment's config block as the pipeline ran it; empty: the config's
data_dir = ""  # folder holding the data; "": the config's data.dir

# %%

from IPython.display import Markdown, display

from nldr import tables
from nldr.experiments.notebook import locate

# the repository (by its Snakefile), the config and this run's files
nb = locate("out_of_sample", configfile, workdir, results, table, runs, arrays, settings, data_dir)
root, results, settings, table_path, run_paths = nb.root, nb.results, nb.settings, nb.table, nb.runs

# %% [markdown]
# ## The table
# Cells read *mean ± sd over masks*. `sse`: all 1000 test rows; `sse_subset`: the rows `Ours`
# solved; `ms_per_row`: CPU milliseconds per test row of the completion step (fit excluded).

# %%
result = nb.read_table()  # the table with its timings (ms_per_row) after it
display(
    Markdown(
        tables.to_markdown(result, digits=3, metrics=["sse", "sse_subset", "ms_per_row"], transpose=True)
    )
)

# %% [markdown]
# ## The targets of issue 18
# `complete`'s SSE at most `KNNImputer`'s at every p, and under 20 ms per new row.

# %%
wide = result.pivot(index=["setting", "method"], columns="metric", values="value")
for setting, group in wide.groupby(level=0):
    c, k = group.loc[(setting, "complete")], group.loc[(setting, "KNNImputer")]
    print(
        f"{setting}: complete {c['sse']:.2f} ± {c['sse_sd']:.2f} "
        f"vs KNNImputer {k['sse']:.2f} ± {k['sse_sd']:.2f} "
        f"(ratio {c['sse'] / k['sse']:.3f}); {c['ms_per_row']:.2f} ms/row"
    )

# %% [markdown]
# ## Gross errors in the new rows: the Huber loss
# `corrupt=c` settings: a share c of the observed test entries carry gross errors. The hard limit
# (`complete`) and `KNNImputer` keep them; with finite rho every entry may move, and the Huber loss
# bounds the pull of each observed entry (rho and delta by CV on training rows corrupted the same way).

# %%
for setting, group in wide.groupby(level=0):
    if not setting.startswith("corrupt"):
        continue
    cells = {m: group.loc[(setting, m)] for m in group.index.get_level_values(1)}
    print(setting, "; ".join(f"{m} {v['sse']:.1f} ± {v['sse_sd']:.1f}" for m, v in cells.items()))

# %% [markdown]
# ## What CV chose, per mask

# %%
runs_frame = nb.read_runs()  # the run files with their timings (ms_per_row) beside them
display(runs_frame[["p", "seed", "method", "sse", "sse_subset", "ms_per_row", "params"]])
