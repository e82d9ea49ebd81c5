"""Gather Table 3's runs into results/tables/table3.{csv,md,tex} with the paper's numbers beside."""

import pandas as pd
from _pipeline import setup, write_text

from nldr import paper, tables
from nldr.experiments.table3 import summarise

sm = snakemake  # noqa: F821
log = setup(sm)
runs = pd.concat([pd.read_csv(path) for path in sm.input], ignore_index=True)
table = tables.attach_paper(summarise(runs), paper.paper_frame(paper.TABLE3))
caption = (
    "Table 3: NRSfM with ground-truth cameras, normalised mean 3D error e3D; TNH (linear) against the "
    "kernel regularizer with the d_max and d_med widths; 50% missing: mean ± sd over seeded masks; "
    "paper in parentheses."
)
csv_path, md_path, tex_path = sm.output
write_text(csv_path, tables.to_csv(table))
write_text(md_path, tables.to_markdown(table, title=caption, metrics=["e3d"]))
write_text(tex_path, tables.to_latex(table, caption=caption, label="tab:table3", metrics=["e3d"]))
log.info("\n%s", tables.to_markdown(table, metrics=["e3d"]))
