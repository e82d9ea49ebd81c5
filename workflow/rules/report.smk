# The reproduction scorecard: every published number, ours beside it, its band, and provenance.


rule scorecard:
    input:
        tables=expand("results/tables/{name}.csv", name=["table1", "table2", "table3", "table4"]),
        figures=["results/figures/fig3.png", "results/figures/fig1.png"],
        data=oil_files("train")
        + oil_files("test")
        + expand(f"{DATA_DIR}/nrsfm/{{seq}}.mat", seq=sorted(set(T3["sequences"]) | set(T4["sequences"]))),
    output:
        md=report("results/report.md", caption="../report/scorecard.rst", category="Scorecard"),
        csv="results/scorecard.csv",
    params:
        bands=config["scorecard"],
        config=config,
        repo=str(REPO),
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/report.log",
    localrule: True
    script:
        "../scripts/report.py"


rule overview:
    input:
        notebook=str(REPO / "notebooks" / "00_overview.py"),
        scorecard="results/scorecard.csv",
        report="results/report.md",
    output:
        "results/notebooks/00_overview.ipynb",
    conda:
        "../envs/nldr.yaml"
    log:
        "logs/notebooks/overview.log",
    localrule: True
    script:
        "../scripts/run_notebook.py"
