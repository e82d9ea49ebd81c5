# Oil-flow experiments: one job per (noise level, draw) for Table 1.


rule table1_run:
    input:
        train=oil_files("train"),
        test=oil_files("test"),
    output:
        "results/runs/table1/std{std}_seed{seed}.csv",
    params:
        gamma=T1["gamma"],
        center=T1["center"],
        max_rank=T1["max_rank"],
        taus=table1_taus(),
        data_dir=lambda wildcards, input: data_dir_of(input.train[0]),
    wildcard_constraints:
        std=r"[0-9.]+",
        seed=r"\d+",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/table1_run/std{std}_seed{seed}.log",
    benchmark:
        "results/benchmarks/table1_run/std{std}_seed{seed}.tsv"
    script:
        "../scripts/table1_run.py"
