"""Gather an experiment's runs into results/tables/<name>.{csv,md,html,tex}, the paper's numbers beside.

The table is computed from the run files with their timings beside them (``timings/``); its rows
whose metric is measured (times, nldr.experiments.base.is_measured) go to ``timings/<name>.csv``
instead, so that the tables repeat byte for byte between runs.
"""

from pathlib import Path

import pandas as pd
from _pipeline import setup, write_text

from nldr import tables
from nldr.experiments import get
from nldr.experiments.base import join_measured, split_measured_table

sm = snakemake  # noqa: F821
log = setup(sm)
experiment = get(sm.wildcards.experiment)


def concat(paths, timings):
    return pd.concat(
        [join_measured(pd.read_csv(p), pd.read_csv(t)) for p, t in zip(paths, timings, strict=True)],
        ignore_index=True,
    )


others = {}
for path, timing in zip(sm.input.others, sm.input.other_timings, strict=True):  # runs/<experiment>/<job>.csv
    files = others.setdefault(Path(path).parent.name, ([], []))
    files[0].append(path)
    files[1].append(timing)
table = experiment.table(
    concat(sm.input.runs, sm.input.timings), sm.config, {k: concat(*v) for k, v in others.items()}
)
table, measured = split_measured_table(table)
caption, render = sm.params.caption, experiment.render
write_text(sm.output.timings, tables.to_csv(measured))
write_text(sm.output.csv, tables.to_csv(table))
write_text(sm.output.md, tables.to_markdown(table, title=caption, **render))
write_text(sm.output.html, tables.to_html(table, title=caption, **render))
write_text(sm.output.tex, tables.to_latex(table, caption=caption, label=experiment.label, **render))
log.info("\n%s", tables.to_markdown(table, **render))
