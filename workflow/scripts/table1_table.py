"""Gather Table 1's runs into results/tables/table1.{csv,md,tex} with the paper's numbers beside."""

import pandas as pd
from _pipeline import setup, write_text

from nldr import paper, tables
from nldr.experiments.table1 import summarise

sm = snakemake  # noqa: F821
log = setup(sm)
runs = pd.concat([pd.read_csv(path) for path in sm.input], ignore_index=True)
table = tables.attach_paper(summarise(runs), paper.paper_frame(paper.TABLE1))
caption = (
    "Table 1: relative manifold error of KPCA (best rank) and the closed-form robust KPCA (best tau) "
    "on noisy oil flow, and 1-NN test error (%); mean ± sd over noise draws, paper in parentheses."
)
csv_path, md_path, tex_path = sm.output
write_text(csv_path, tables.to_csv(table))
write_text(md_path, tables.to_markdown(table, title=caption))
write_text(tex_path, tables.to_latex(table, caption=caption, label="tab:table1"))
log.info("\n%s", tables.to_markdown(table))
