"""Gather an NRSfM table's runs (Table 3, 4 or table3_full) into results/tables/<name>.{csv,md,tex}.

For table3_full the input also names Table 3's runs (``subsampled``): each method then appears twice,
"<method>, every frame" for the full-length runs and "<method>, every 10th frame" for Table 3's, and
the paper's numbers sit beside the latter (the paper ran only the subsampled sequences).
"""

import pandas as pd
from _pipeline import setup, write_text

from nldr import paper, tables
from nldr.experiments.table3 import summarise

sm = snakemake  # noqa: F821
log = setup(sm)


def gather(paths) -> pd.DataFrame:
    return summarise(pd.concat([pd.read_csv(path) for path in paths], ignore_index=True))


published = paper.paper_frame(getattr(paper, sm.params.paper))
if "subsampled" in sm.input.keys():
    full, sub = gather(sm.input.runs), gather(sm.input.subsampled)
    full_label, sub_label = sm.params.labels
    paired = []
    for method in dict.fromkeys(sub["method"]):
        paired.append(tables.attach_paper(full[full["method"] == method], published.iloc[:0]))
        paired[-1]["method"] = f"{method}, {full_label}"
        paired.append(tables.attach_paper(sub[sub["method"] == method], published))
        paired[-1]["method"] = f"{method}, {sub_label}"
    table = pd.concat(paired, ignore_index=True)
    order = {s: i for i, s in enumerate(dict.fromkeys(sub["setting"]))}
    table = table.sort_values("setting", key=lambda s: s.map(order), kind="stable").reset_index(drop=True)
else:
    table = tables.attach_paper(gather(sm.input), published)
csv_path, md_path, tex_path = sm.output
write_text(csv_path, tables.to_csv(table))
write_text(md_path, tables.to_markdown(table, title=sm.params.caption, metrics=["e3d"]))
write_text(
    tex_path, tables.to_latex(table, caption=sm.params.caption, label=sm.params.label, metrics=["e3d"])
)
log.info("\n%s", tables.to_markdown(table, metrics=["e3d"]))
