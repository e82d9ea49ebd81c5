"""Render an executed notebook as a standalone HTML page (nbconvert's lab template), atomically."""

import nbformat
from _pipeline import setup, write_text
from nbconvert import HTMLExporter

sm = snakemake  # noqa: F821
log = setup(sm)
notebook = nbformat.read(sm.input[0], as_version=4)
exporter = HTMLExporter(template_name="lab")
exporter.embed_images = True  # figures inside the page, so it reads anywhere
body, _ = exporter.from_notebook_node(notebook)
write_text(sm.output[0], body)
log.info("wrote %s (%d kB)", sm.output[0], len(body) // 1024)
