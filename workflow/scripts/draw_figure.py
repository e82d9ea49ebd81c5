"""Draw one figure from its experiment's runs (nldr.experiments -> nldr.plotting) as PNG (the report,
notebooks), PDF and SVG (vector, for papers and slides), each written atomically."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
# text stays text (editable); svg.hashsalt fixes the SVG's clip-path and glyph ids, which matplotlib
# otherwise draws at random, so the same runs give the same SVG bytes
matplotlib.rcParams.update({"pdf.fonttype": 42, "svg.fonttype": "none", "svg.hashsalt": "nldr"})
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from _pipeline import atomic_path, setup  # noqa: E402

from nldr.experiments import figure_owner  # noqa: E402

sm = snakemake  # noqa: F821
log = setup(sm)
figure = sm.wildcards.figure
runs = pd.concat([pd.read_csv(path) for path in sm.input.runs], ignore_index=True)
arrays = {Path(path).stem: np.load(path) for path in sm.input.arrays}
fig = figure_owner(figure).draw(figure, runs, arrays, sm.params.data_dir)
for fmt in ("png", "pdf", "svg"):
    with atomic_path(sm.output[fmt]) as tmp:
        # no creation date in the vector files: the same runs give the same bytes
        stamp = {"pdf": {"CreationDate": None}, "svg": {"Date": None}}.get(fmt)
        fig.savefig(tmp, dpi=200, format=fmt, metadata=stamp)
    log.info("wrote %s", sm.output[fmt])
