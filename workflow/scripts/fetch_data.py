"""Put one pinned raw data file in place (mirror copy or download), sha256-verified.

A DataError (missing, unreadable or corrupt source; failed download) ends the job with its message
alone: the message names the file and the fix, and a traceback would only bury it.
"""

import sys

from _pipeline import setup

from nldr.datasets import DataError, fetch

sm = snakemake  # noqa: F821
log = setup(sm)
log.info("fetching %s into %s", sm.wildcards.relpath, sm.params.data_dir)
try:
    log.info("verified %s", fetch(sm.wildcards.relpath, sm.params.data_dir))
except DataError as exc:
    log.error("DataError: %s", exc)
    sys.exit(1)
