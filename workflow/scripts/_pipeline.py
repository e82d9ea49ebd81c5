"""Glue shared by the pipeline scripts: logging, BLAS thread pinning, atomic file writes.

No maths here: scripts unpack Snakemake's inputs, call the library, and write through these helpers
so that a file under results/ is either complete or absent (write to a temporary name, then rename).
"""

from __future__ import annotations

import logging
import os
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

try:  # the installed package (make setup), or else this checkout's own src/ (e.g. snakemake --use-conda)
    import nldr  # noqa: F401
except ImportError:
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "src"))


def setup(snakemake) -> logging.Logger:
    """Send log records to the rule's log file and pin BLAS threads to the rule's ``threads``.

    The library keeps its one-thread rule for small problems but does not replace the rule's threads
    by the idle cores it sees on larger ones (``NLDR_AUTO_THREADS=small``, nldr._threads): a job's
    results must not depend on the machine's load."""
    from threadpoolctl import threadpool_limits

    os.environ.setdefault("NLDR_AUTO_THREADS", "small")
    log_file = snakemake.log[0] if len(snakemake.log) else None
    handlers = [logging.StreamHandler(sys.stderr)]
    if log_file:
        Path(log_file).parent.mkdir(parents=True, exist_ok=True)
        handlers.append(logging.FileHandler(log_file, mode="w"))
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s", handlers=handlers, force=True)
    threadpool_limits(int(getattr(snakemake, "threads", 1) or 1))
    log = logging.getLogger(snakemake.rule)
    log.info("compute: %s", compute_fingerprint())
    return log


def compute_fingerprint() -> str:
    """One line naming what decides the floating-point bits of a run: the BLAS libraries with their
    kernel architecture and thread count, and the CPU features numpy dispatches on. Two runs whose
    tables differ in the last digits can be compared by this line in their logs."""
    import numpy as np
    from threadpoolctl import threadpool_info

    libs = ", ".join(
        f"{i.get('internal_api')} {i.get('version')} {i.get('architecture') or '-'} x{i.get('num_threads')}"
        for i in threadpool_info()
    )
    try:
        from numpy._core._multiarray_umath import __cpu_features__ as features
    except ImportError:  # numpy < 2
        from numpy.core._multiarray_umath import __cpu_features__ as features
    top = [name for name in ("AVX512_SKX", "AVX512F", "AVX2", "FMA3") if features.get(name)]
    return f"numpy {np.__version__} [{' '.join(top) or 'baseline'}]; {libs}"


@contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; rename it onto ``path`` only if the block succeeds."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix or ".tmp")
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    finally:
        Path(tmp).unlink(missing_ok=True)


def write_text(path, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def write_csv(path, frame) -> None:
    """Write a DataFrame as CSV atomically (full precision, no index)."""
    with atomic_path(path) as tmp:
        frame.to_csv(tmp, index=False, float_format="%.10g")


def write_npz(path, **arrays) -> None:
    """Write arrays to a compressed .npz atomically."""
    import numpy as np

    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
