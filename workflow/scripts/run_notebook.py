"""Execute a jupytext percent notebook with papermill into results/notebooks/ (atomic write).

The notebook's ``parameters`` cell is overridden with the rule's named inputs (absolute paths) and
with the rule's ``parameters`` param (the experiment's settings, the data folder), so the executed copy
shows exactly the files and settings of this run.
"""

import os
from pathlib import Path

import jupytext
import papermill
from _pipeline import atomic_path, setup

sm = snakemake  # noqa: F821
log = setup(sm)
parameters = {
    key: (str(Path(value).resolve()) if isinstance(value, str) else [str(Path(v).resolve()) for v in value])
    for key, value in sm.input.items()
    if key not in ("notebook", "data")
}
parameters.update(dict(getattr(sm.params, "parameters", None) or {}))
notebook = jupytext.read(sm.input.notebook)
# A non-interactive MPLBACKEND (CI sets Agg) would stop the kernel from showing figures inline.
os.environ.pop("MPLBACKEND", None)
log.info("executing %s with %s", sm.input.notebook, sorted(parameters))
with atomic_path(sm.output[0]) as tmp:
    papermill.execute_notebook(
        notebook,
        str(tmp),
        parameters=parameters,
        kernel_name="python3",
        cwd=str(Path.cwd()),
        progress_bar=False,
    )
log.info("wrote %s", sm.output[0])
