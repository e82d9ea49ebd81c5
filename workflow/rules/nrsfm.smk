# NRSfM with ground-truth cameras (Table 3): one job per (sequence, setting, seed) runs TNH and the
# kernel regularizer with each width criterion, and keeps the reconstructions for Figure 1.


rule table3_run:
    input:
        mocap=f"{DATA_DIR}/nrsfm/{{seq}}.mat",
    output:
        table="results/runs/table3/{seq}_{setting}_seed{seed}.csv",
        shapes="results/runs/table3/{seq}_{setting}_seed{seed}.npz",
    params:
        step=T3["step"],
        missing_fraction=lambda wildcards: 0.0 if wildcards.setting == "full" else T3["missing_fraction"],
        tau=T3["tau"],
        widths=T3["widths"],
        regularizer=T3["regularizer"],
        tnh=T3["tnh"],
        data_dir=lambda wildcards, input: data_dir_of(input.mocap),
    wildcard_constraints:
        seq=r"drink|pickup|yoga|stretch",
        setting=r"full|missing",
        seed=r"\d+",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/table3_run/{seq}_{setting}_seed{seed}.log",
    benchmark:
        "results/benchmarks/table3_run/{seq}_{setting}_seed{seed}.tsv"
    script:
        "../scripts/table3_run.py"


# Table 3 on every frame (config table3_full; not in the paper): TNH by a first-order exact fit.
use rule table3_run as table3_full_run with:
    output:
        table="results/runs/table3_full/{seq}_{setting}_seed{seed}.csv",
        shapes="results/runs/table3_full/{seq}_{setting}_seed{seed}.npz",
    params:
        step=T3F["step"],
        missing_fraction=lambda wildcards: 0.0 if wildcards.setting == "full" else T3["missing_fraction"],
        tau=T3["tau"],
        widths=T3["widths"],
        regularizer=T3["regularizer"],
        tnh=T3F["tnh"],
        data_dir=lambda wildcards, input: data_dir_of(input.mocap),
    threads: lambda wildcards: 2 if wildcards.seq == "drink" else 1  # 1102 x 1102 kernels: BLAS on 2 cores
    resources:
        mem_mb=4000,
        runtime=60,
    log:
        "logs/table3_full_run/{seq}_{setting}_seed{seed}.log",
    benchmark:
        "results/benchmarks/table3_full_run/{seq}_{setting}_seed{seed}.tsv"


# NRSfM with estimated cameras (Table 4): one job per (sequence, setting, seed) runs the tau search of
# TNH (each evaluation an alternation to convergence) and the kernel regularizer per width criterion.
rule table4_run:
    input:
        mocap=f"{DATA_DIR}/nrsfm/{{seq}}.mat",
    output:
        table="results/runs/table4/{seq}_{setting}_seed{seed}.csv",
        shapes="results/runs/table4/{seq}_{setting}_seed{seed}.npz",
    params:
        step=T4["step"],
        missing_fraction=lambda wildcards: 0.0 if wildcards.setting == "full" else T4["missing_fraction"],
        tnh=T4["tnh"],
        tau=T4["tau"],
        widths=T4["widths"],
        kernel=T4["kernel"],
        data_dir=lambda wildcards, input: data_dir_of(input.mocap),
    wildcard_constraints:
        seq=r"drink|pickup|yoga|stretch",
        setting=r"full|missing",
        seed=r"\d+",
    threads: 1
    resources:
        mem_mb=2000,
        runtime=60,
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/table4_run/{seq}_{setting}_seed{seed}.log",
    benchmark:
        "results/benchmarks/table4_run/{seq}_{setting}_seed{seed}.tsv"
    script:
        "../scripts/table4_run.py"
