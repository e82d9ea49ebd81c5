# Figures drawn from the gathered runs.


rule fig3:
    input:
        expand("results/runs/table1/std{std}_seed{seed}.csv", std=T1_STDS, seed=T1_SEEDS),
    output:
        report("results/figures/fig3.png", caption="../report/fig3.rst", category="Figures"),
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/fig3.log",
    localrule: True
    script:
        "../scripts/fig3.py"


rule fig1:
    input:
        shapes=[f.replace(".csv", ".npz") for f in T3_RUNS],
        mocap=expand(f"{DATA_DIR}/nrsfm/{{seq}}.mat", seq=T3["sequences"]),
    output:
        report("results/figures/fig1.png", caption="../report/fig1.rst", category="Figures"),
    params:
        data_dir=lambda wildcards, input: data_dir_of(input.mocap[0]),
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/fig1.log",
    localrule: True
    script:
        "../scripts/fig1.py"
