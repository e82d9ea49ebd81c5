"""Execute a jupytext percent notebook with papermill into results/notebooks/ (atomic write).

The notebook's ``parameters`` cell is overridden with the rule's named inputs and with the rule's
``parameters`` param (the experiment's settings, the data folder), so the executed copy shows exactly
the files and settings of this run. Paths stay relative to Snakemake's working directory (the kernel
runs there, ``workdir="."``), so the executed copy names no absolute path of this machine. Its cell
ids are the cells' positions and it keeps no clock times, so two runs differ only in outputs that
print what was measured (times).
"""

import os
from pathlib import Path

import jupytext
import nbformat
import papermill
from _pipeline import atomic_path, setup

sm = snakemake  # noqa: F821
log = setup(sm)
parameters = {
    key: (str(value) if isinstance(value, str) else [str(v) for v in value])
    for key, value in sm.input.items()
    if key not in ("notebook", "data", "timings", "timing_table")  # timings: found beside the runs
}
parameters.update(workdir=".", results=sm.params.results)
parameters.update(dict(getattr(sm.params, "parameters", None) or {}))
notebook = jupytext.read(sm.input.notebook)
# A non-interactive MPLBACKEND (CI sets Agg) would stop the kernel from showing figures inline.
os.environ.pop("MPLBACKEND", None)
log.info("executing %s with %s", sm.input.notebook, sorted(parameters))
with atomic_path(sm.output[0]) as tmp:
    executed = papermill.execute_notebook(
        notebook,
        str(tmp),
        parameters=parameters,
        kernel_name="python3",
        cwd=str(Path.cwd()),
        progress_bar=False,
    )
    # papermill records where it read and wrote: name the source and the final file, not temporaries
    executed.metadata.papermill.update(input_path=sm.input.notebook, output_path=sm.output[0])
    if Path(sm.input.notebook).is_absolute():  # the rules name the notebook under the repository
        executed.metadata.papermill["input_path"] = f"notebooks/{Path(sm.input.notebook).name}"
    # what differs between two runs without being a result: random cell ids, and the clock times
    # papermill and nbclient record per cell and for the whole run (outputs that print a time still
    # differ: the notebooks show what the jobs measured)
    for i, cell in enumerate(executed.cells):
        cell.id = f"cell-{i}"
        cell.metadata.pop("execution", None)
        for key in ("start_time", "end_time", "duration"):
            cell.metadata.get("papermill", {}).pop(key, None)
    for key in ("start_time", "end_time", "duration"):
        executed.metadata.papermill.pop(key, None)
    nbformat.write(executed, str(tmp))
log.info("wrote %s", sm.output[0])
