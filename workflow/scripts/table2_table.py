"""Gather Table 2's runs into results/tables/table2.{csv,md,tex} with the paper's numbers beside."""

import pandas as pd
from _pipeline import setup, write_text

from nldr import paper, tables
from nldr.experiments.table2 import summarise

sm = snakemake  # noqa: F821
log = setup(sm)
runs = pd.concat([pd.read_csv(path) for path in sm.input], ignore_index=True)
table = tables.attach_paper(summarise(runs), paper.paper_frame(paper.TABLE2))
caption = (
    "Table 2: oil-flow completion (first 100 training rows), sum of squared errors over the whole "
    "matrix, mean ± sd over seeded masks; paper in parentheses, – where not available."
)
csv_path, md_path, tex_path = sm.output
write_text(csv_path, tables.to_csv(table))
write_text(md_path, tables.to_markdown(table, title=caption, digits=3, metrics=["sse"], transpose=True))
write_text(
    tex_path,
    tables.to_latex(table, caption=caption, label="tab:table2", digits=3, metrics=["sse"], transpose=True),
)
log.info("\n%s", tables.to_markdown(table, digits=3))
