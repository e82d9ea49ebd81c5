"""Draw one figure from its experiment's runs (nldr.experiments -> nldr.plotting), PNG, atomically."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
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
with atomic_path(sm.output[0]) as tmp:
    fig.savefig(tmp, dpi=130, format="png")
log.info("wrote %s", sm.output[0])
