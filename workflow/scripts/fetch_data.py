"""Put one pinned raw data file in place (mirror copy or download), sha256-verified."""

from _pipeline import setup

from nldr.datasets import fetch

sm = snakemake  # noqa: F821
log = setup(sm)
log.info("fetching %s into %s", sm.wildcards.relpath, sm.params.data_dir)
log.info("verified %s", fetch(sm.wildcards.relpath, sm.params.data_dir))
