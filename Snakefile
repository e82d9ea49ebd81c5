# nldr: rebuild the tables and figures of Garg, Eriksson & Reid (2016).
#   snakemake -c all            every table of the paper, its figures, the scorecard
#   snakemake -c all table1     one experiment (its table, figures and executed notebook)
#   snakemake -c all --configfile config/quick.yaml    the small protocol, under results/quick/
# The rules are generic over the experiments of nldr.experiments (docs/ARCHITECTURE.md).
from pathlib import Path

from snakemake.utils import min_version, validate

min_version("9.0")


configfile: str(Path(workflow.basedir) / "config" / "config.yaml")


report: "workflow/report/workflow.rst"


validate(config, "workflow/schemas/config.schema.yaml")


include: "workflow/rules/common.smk"
include: "workflow/rules/data.smk"
include: "workflow/rules/experiments.smk"
include: "workflow/rules/report.smk"


rule all:
    default_target: True
    input:
        [target_of(e) for e in PAPER],
        rules.scorecard.output,
        notebook_path("00_overview"),
        notebook_path("00_overview", "html"),
