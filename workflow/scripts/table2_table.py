"""Gather Table 2's runs (or table2_full's) into results/tables/<name>.{csv,md,tex}, paper beside."""

import pandas as pd
from _pipeline import setup, write_text

from nldr import paper, tables
from nldr.experiments.table2 import summarise

sm = snakemake  # noqa: F821
log = setup(sm)
runs = pd.concat([pd.read_csv(path) for path in sm.input], ignore_index=True)
published = paper.paper_frame(paper.TABLE2 if sm.params.with_paper else [])
table = tables.attach_paper(summarise(runs), published)
caption = sm.params.caption
csv_path, md_path, tex_path = sm.output
write_text(csv_path, tables.to_csv(table))
write_text(md_path, tables.to_markdown(table, title=caption, digits=3, metrics=["sse"], transpose=True))
write_text(
    tex_path,
    tables.to_latex(table, caption=caption, label=sm.params.label, digits=3, metrics=["sse"], transpose=True),
)
log.info("\n%s", tables.to_markdown(table, digits=3))
