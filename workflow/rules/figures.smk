# Figures drawn from the gathered runs.


rule fig3:
    input:
        expand("results/runs/table1/std{std}_seed{seed}.csv", std=T1_STDS, seed=T1_SEEDS),
    output:
        "results/figures/fig3.png",
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/fig3.log",
    localrule: True
    script:
        "../scripts/fig3.py"
