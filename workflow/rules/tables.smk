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
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/table2_table.log",
    localrule: True
    script:
        "../scripts/table2_table.py"


rule table3_table:
    input:
        T3_RUNS,
    output:
        table_outputs("table3"),
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/table3_table.log",
    localrule: True
    script:
        "../scripts/table3_table.py"
