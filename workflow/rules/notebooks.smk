# Each table's target ends by executing its notebook (jupytext percent file -> papermill) into
# results/notebooks/, so the explained table and figure are themselves a result.


rule table1:
    input:
        notebook=str(REPO / "notebooks" / "table1_robust_kpca.py"),
        table="results/tables/table1.csv",
        figure="results/figures/fig3.png",
        runs=expand("results/runs/table1/std{std}_seed{seed}.csv", std=T1_STDS, seed=T1_SEEDS),
    output:
        "results/notebooks/table1_robust_kpca.ipynb",
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/notebooks/table1.log",
    localrule: True
    script:
        "../scripts/run_notebook.py"


rule table2:
    input:
        notebook=str(REPO / "notebooks" / "table2_completion.py"),
        table="results/tables/table2.csv",
        runs=T2_RUNS,
        train=oil_files("train"),
    output:
        "results/notebooks/table2_completion.ipynb",
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/notebooks/table2.log",
    localrule: True
    script:
        "../scripts/run_notebook.py"


rule table3:
    input:
        notebook=str(REPO / "notebooks" / "table3_nrsfm.py"),
        table="results/tables/table3.csv",
        figure="results/figures/fig1.png",
        runs=T3_RUNS,
        mocap=expand(f"{DATA_DIR}/nrsfm/{{seq}}.mat", seq=T3["sequences"]),
    output:
        "results/notebooks/table3_nrsfm.ipynb",
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/notebooks/table3.log",
    localrule: True
    script:
        "../scripts/run_notebook.py"


rule table4:
    input:
        notebook=str(REPO / "notebooks" / "table4_nrsfm_cameras.py"),
        table="results/tables/table4.csv",
        runs=T4_RUNS,
    output:
        "results/notebooks/table4_nrsfm_cameras.ipynb",
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/notebooks/table4.log",
    localrule: True
    script:
        "../scripts/run_notebook.py"


# Extra targets (speed and scale, not in the paper): the table alone, no notebook.
rule table2_full:
    input:
        table_outputs("table2_full"),
    localrule: True


rule table3_full:
    input:
        table_outputs("table3_full"),
    localrule: True
