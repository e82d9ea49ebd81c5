# nldr: rebuild the tables and figures of Garg, Eriksson & Reid (2016).
#   snakemake -c all            every target
#   snakemake -c all table1     one table (its CSV/Markdown/LaTeX and its executed notebook)
from pathlib import Path

from snakemake.utils import min_version, validate

min_version("9.0")


configfile: str(Path(workflow.basedir) / "config" / "config.yaml")


report: "workflow/report/workflow.rst"


validate(config, "workflow/schemas/config.schema.yaml")


include: "workflow/rules/common.smk"
include: "workflow/rules/data.smk"
include: "workflow/rules/oil.smk"
include: "workflow/rules/nrsfm.smk"
include: "workflow/rules/tables.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/notebooks.smk"
include: "workflow/rules/report.smk"


rule all:
    default_target: True
    input:
        rules.table1.output,
        rules.fig3.output,
        rules.table2.output,
        rules.table3.output,
        rules.fig1.output,
        rules.table4.output,
        rules.scorecard.output,
        rules.overview.output,
