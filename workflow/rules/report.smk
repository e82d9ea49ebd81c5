# The reproduction scorecard: every published number, ours beside it, its band, and provenance; then
# the overview notebook that presents it.


rule scorecard:
    input:
        tables=[table_files(e)[0] for e in PAPER],
        figures=[figure_path(f) for e in PAPER for f in e.figures],
        data=data_paths(sorted({rel for e in PAPER for rel in e.data_files(config)})),
        docs=str(REPO / "docs" / "REPRODUCTION.md"),  # embedded in the HTML page, which links to it
    output:
        md=f"{RESULTS}/report.md",
        html=report(f"{RESULTS}/scorecard.html", caption="../report/scorecard.rst", category="Scorecard"),
        csv=f"{RESULTS}/scorecard.csv",
    params:
        bands=config["scorecard"],
        config=config,
        repo=lambda w, input: str(Path(input.docs).parents[1]),  # <repo>/docs/REPRODUCTION.md
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
        notebook_path("00_overview"),
    params:
        results=lambda w, output: str(Path(output[0]).parents[1]),  # <results>/notebooks/<name>.ipynb
    conda:
        "../envs/nldr.yaml"
    log:
        f"{RESULTS}/logs/notebook/00_overview.log",
    localrule: True
    script:
        "../scripts/run_notebook.py"


# Every executed notebook as a standalone HTML page, shown inline in the HTML report.
rule notebook_html:
    input:
        f"{RESULTS}/notebooks/{{notebook}}.ipynb",
    output:
        report(
            f"{RESULTS}/notebooks/{{notebook}}.html",
            caption="../report/notebook.rst",
            category="Notebooks",
            labels={"notebook": "{notebook}"},
        ),
    wildcard_constraints:
        notebook="|".join([*NOTEBOOKS, "00_overview"]),
    conda:
        "../envs/nldr.yaml"
    log:
        f"{RESULTS}/logs/notebook_html/{{notebook}}.log",
    localrule: True
    script:
        "../scripts/notebook_html.py"
