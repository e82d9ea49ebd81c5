"""Gather an NRSfM table's runs (Table 3 or 4) into results/tables/<name>.{csv,md,tex}, paper beside."""

import pandas as pd
from _pipeline import setup, write_text

from nldr import paper, tables
from nldr.experiments.table3 import summarise

sm = snakemake  # noqa: F821
log = setup(sm)
runs = pd.concat([pd.read_csv(path) for path in sm.input], ignore_index=True)
table = tables.attach_paper(summarise(runs), paper.paper_frame(getattr(paper, sm.params.paper)))
csv_path, md_path, tex_path = sm.output
write_text(csv_path, tables.to_csv(table))
write_text(md_path, tables.to_markdown(table, title=sm.params.caption, metrics=["e3d"]))
write_text(
    tex_path, tables.to_latex(table, caption=sm.params.caption, label=sm.params.label, metrics=["e3d"])
)
log.info("\n%s", tables.to_markdown(table, metrics=["e3d"]))
