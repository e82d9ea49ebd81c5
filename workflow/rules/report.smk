# The reproduction scorecard: every published number, ours beside it, its band, and provenance; then
# the overview notebook that presents it.


rule scorecard:
    input:
        tables=[table_files(e)[0] for e in PAPER],
        figures=[figure_path(f) for e in PAPER for f in e.figures],
        data=data_paths(sorted({rel for e in PAPER for rel in e.data_files(config)})),
    output:
        md=report(f"{RESULTS}/report.md", caption="../report/scorecard.rst", category="Scorecard"),
        csv=f"{RESULTS}/scorecard.csv",
    params:
        bands=config["scorecard"],
        config=config,
        repo=str(REPO),
        benchmarks=f"{RESULTS}/benchmarks",
    conda:
        "../envs/nldr.yaml"
    log:
        f"{RESULTS}/logs/scorecard.log",
    localrule: True
    script:
        "../scripts/report.py"


rule overview:
    input:
        notebook=str(REPO / "notebooks" / "00_overview.py"),
        scorecard=rules.scorecard.output.csv,
        report=rules.scorecard.output.md,
    output:
        f"{RESULTS}/notebooks/00_overview.ipynb",
    conda:
        "../envs/nldr.yaml"
    log:
        f"{RESULTS}/logs/notebook/00_overview.log",
    localrule: True
    script:
        "../scripts/run_notebook.py"
