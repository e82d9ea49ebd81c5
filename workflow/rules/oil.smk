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


rule table2_run:
    input:
        train=oil_files("train"),
    output:
        "results/runs/table2/p{p}_seed{seed}.csv",
    params:
        n_rows=T2["n_rows"],
        gamma=T2["gamma"],
        methods=T2["methods"],
        data_dir=lambda wildcards, input: data_dir_of(input.train[0]),
    wildcard_constraints:
        p=r"0\.[0-9]+",
        seed=r"\d+",
    threads: 1
    resources:
        mem_mb=1000,
        runtime=20,
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/table2_run/p{p}_seed{seed}.log",
    benchmark:
        "results/benchmarks/table2_run/p{p}_seed{seed}.tsv"
    script:
        "../scripts/table2_run.py"


# Table 2's protocol on more rows (config table2_full; not in the paper): same script, same masks.
use rule table2_run as table2_full_run with:
    output:
        "results/runs/table2_full/p{p}_seed{seed}.csv",
    params:
        n_rows=T2F["n_rows"],
        gamma=T2["gamma"],
        methods=T2["methods"],
        data_dir=lambda wildcards, input: data_dir_of(input.train[0]),
    resources:
        mem_mb=2000,
        runtime=60,
    log:
        "logs/table2_full_run/p{p}_seed{seed}.log",
    benchmark:
        "results/benchmarks/table2_full_run/p{p}_seed{seed}.tsv"
