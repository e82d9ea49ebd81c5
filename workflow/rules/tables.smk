# Gather runs into tables: tidy CSV (canonical) plus Markdown and LaTeX with the paper's numbers.


rule table1_table:
    input:
        expand("results/runs/table1/std{std}_seed{seed}.csv", std=T1_STDS, seed=T1_SEEDS),
    output:
        table_outputs("table1"),
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/table1_table.log",
    localrule: True
    script:
        "../scripts/table1_table.py"


rule table2_table:
    input:
        T2_RUNS,
    output:
        table_outputs("table2"),
    params:
        with_paper=True,
        caption=(
            f"Table 2: oil-flow completion (first {T2['n_rows']} training rows), sum of squared errors over "
            "the whole matrix, mean ± sd over seeded masks; paper in parentheses, – where not available."
        ),
        label="tab:table2",
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/table2_table.log",
    localrule: True
    script:
        "../scripts/table2_table.py"


use rule table2_table as table2_full_table with:
    input:
        T2F_RUNS,
    output:
        table_outputs("table2_full"),
    params:
        with_paper=False,
        caption=(
            f"Table 2 on {T2F['n_rows']} oil-flow training rows (not in the paper, which uses the first "
            f"{T2['n_rows']}): sum of squared errors over the whole matrix, mean ± sd over "
            f"{T2F['n_masks']} seeded masks per p."
        ),
        label="tab:table2-full",
    log:
        "logs/table2_full_table.log",


rule table3_table:
    input:
        T3_RUNS,
    output:
        table_outputs("table3"),
    params:
        paper="TABLE3",
        label="tab:table3",
        caption=(
            "Table 3: NRSfM with ground-truth cameras, normalised mean 3D error e3D; TNH (linear) against "
            "the kernel regularizer with the d_max and d_med widths; 50% missing: mean ± sd over seeded "
            "masks; paper in parentheses."
        ),
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/table3_table.log",
    localrule: True
    script:
        "../scripts/nrsfm_table.py"


rule table4_table:
    input:
        T4_RUNS,
    output:
        table_outputs("table4"),
    params:
        paper="TABLE4",
        label="tab:table4",
        caption=(
            "Table 4: NRSfM with cameras from rigid factorisation refined in alternation with the shapes, "
            "e3D after one global alignment; TNH with tau tuned per case on ground-truth e3D (an oracle, "
            "as in the paper) against the kernel regularizer (tau = 1e-4) with the d_max and d_med widths; "
            "paper in parentheses."
        ),
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/table4_table.log",
    localrule: True
    script:
        "../scripts/nrsfm_table.py"


# Table 3 on every frame beside Table 3 itself (every 10th frame), with the paper's numbers.
rule table3_full_table:
    input:
        runs=T3F_RUNS,
        subsampled=T3_RUNS,
    output:
        table_outputs("table3_full"),
    params:
        paper="TABLE3",
        label="tab:table3-full",
        labels=[every_nth_frame(T3F["step"]), every_nth_frame(T3["step"])],
        caption=(
            f"Table 3 on {every_nth_frame(T3F['step'])} (not in the paper) beside "
            f"{every_nth_frame(T3['step'])}: e3D with ground-truth cameras, TNH (exact fit, "
            f"{T3F['tnh']['solver']}) and the kernel regularizer; paper (every 10th frame) in parentheses."
        ),
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/table3_full_table.log",
    localrule: True
    script:
        "../scripts/nrsfm_table.py"
