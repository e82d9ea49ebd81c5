# Shared helpers: paths and the parameter grids derived from the config.
import numpy as np

REPO = Path(workflow.basedir)
DATA_DIR = config["data"]["dir"]
T1 = config["table1"]
T1_STDS = [f"{s:g}" for s in T1["noise_std"]]
T1_SEEDS = [T1["seed"] + k for k in range(T1["n_draws"])]
T2 = config["table2"]
T2_PS = [f"{p:g}" for p in T2["p"]]
T2_SEEDS = [T2["seed"] + k for k in range(T2["n_masks"])]
T3 = config["table3"]
T3_RUNS = [f"results/runs/table3/{seq}_full_seed{T3['seed']}.csv" for seq in T3["sequences"]] + [
    f"results/runs/table3/{seq}_missing_seed{T3['seed'] + k}.csv"
    for seq in T3["sequences"]
    for k in range(T3["n_seeds"])
]
T4 = config["table4"]
T4_RUNS = [f"results/runs/table4/{seq}_full_seed{T4['seed']}.csv" for seq in T4["sequences"]] + [
    f"results/runs/table4/{seq}_missing_seed{T4['seed'] + k}.csv"
    for seq in T4["sequences"]
    for k in range(T4["n_seeds"])
]
T2_RUNS = expand("results/runs/table2/p{p}_seed{seed}.csv", p=T2_PS, seed=T2_SEEDS)
# Extra targets (speed and scale, not in the paper): Table 2 on more rows, Table 3 on every frame.
T2F = config["table2_full"]
T2F_RUNS = expand(
    "results/runs/table2_full/p{p}_seed{seed}.csv",
    p=T2_PS,
    seed=[T2["seed"] + k for k in range(T2F["n_masks"])],
)
T3F = config["table3_full"]
T3F_RUNS = [f"results/runs/table3_full/{seq}_full_seed{T3['seed']}.csv" for seq in T3["sequences"]] + [
    f"results/runs/table3_full/{seq}_missing_seed{T3['seed'] + k}.csv"
    for seq in T3["sequences"]
    for k in range(T3F["n_seeds"])
]


def every_nth_frame(step):
    """'every frame', 'every 2nd frame', ..., 'every 10th frame' (for captions)."""
    suffix = {1: "st", 2: "nd", 3: "rd"}.get(step % 10 if step % 100 not in (11, 12, 13) else 0, "th")
    return "every frame" if step == 1 else f"every {step}{suffix} frame"


def table1_taus():
    tau = T1["tau"]
    return np.geomspace(tau["min"], tau["max"], tau["num"]).tolist()


def table_outputs(name):
    """CSV (canonical), Markdown (shown in the HTML report, caption workflow/report/<name>.rst), LaTeX."""
    # (a line may not start with `report`: Snakemake's parser would take it for the keyword)
    markdown = report(f"results/tables/{name}.md", caption=f"../report/{name}.rst", category="Tables")
    return [f"results/tables/{name}.csv", markdown, f"results/tables/{name}.tex"]


def data_dir_of(path):
    """The data directory holding ``path`` (e.g. resources/oil/DataTrn.txt -> resources)."""
    return str(Path(path).parent.parent)


def oil_files(split):
    tag = {"train": "Trn", "test": "Tst", "validation": "Vdn"}[split]
    return [f"{DATA_DIR}/oil/Data{tag}.txt", f"{DATA_DIR}/oil/Data{tag}Lbls.txt"]
