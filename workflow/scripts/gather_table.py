"""Gather an experiment's runs into results/tables/<name>.{csv,md,html,tex}, the paper's numbers beside."""

from pathlib import Path

import pandas as pd
from _pipeline import setup, write_text

from nldr import tables
from nldr.experiments import get

sm = snakemake  # noqa: F821
log = setup(sm)
experiment = get(sm.wildcards.experiment)


def concat(paths):
    return pd.concat([pd.read_csv(path) for path in paths], ignore_index=True)


others = {}
for path in sm.input.others:  # runs/<experiment>/<job>.csv
    others.setdefault(Path(path).parent.name, []).append(path)
table = experiment.table(concat(sm.input.runs), sm.config, {k: concat(v) for k, v in others.items()})
caption, render = sm.params.caption, experiment.render
write_text(sm.output.csv, tables.to_csv(table))
write_text(sm.output.md, tables.to_markdown(table, title=caption, **render))
write_text(sm.output.html, tables.to_html(table, title=caption, **render))
write_text(sm.output.tex, tables.to_latex(table, caption=caption, label=experiment.label, **render))
log.info("\n%s", tables.to_markdown(table, **render))
