"""Two runs' outputs compared byte for byte (the determinism test, tests/cluster/slurm_pipeline.py).

A run file (``runs/<experiment>/<job>.csv``) also records how long its job took: wall and CPU seconds,
and in the selection experiments a ratio of two CPU times. Those cells are measurements of the machine,
not results; every other cell, and every other file (tables, figures, ``.npz`` arrays), must match
byte for byte.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

MEASURED = frozenset({"seconds", "cpu_seconds", "solves"})  # run-file columns that time the job


def _cells(data: bytes) -> tuple[list[str], list[list[str]]]:
    """The CSV's header and rows as written (text, not numbers), without the measured columns."""
    rows = list(csv.reader(io.StringIO(data.decode())))
    keep = [i for i, name in enumerate(rows[0]) if name not in MEASURED] if rows else []
    return [rows[0][i] for i in keep] if rows else [], [[row[i] for i in keep] for row in rows[1:]]


def difference(first: Path, second: Path) -> str | None:
    """None when ``second`` reproduces ``first``; otherwise what differs (for a message).

    Byte for byte, except that a run CSV (a ``runs`` folder in its path) may differ in the
    :data:`MEASURED` columns only."""
    a, b = first.read_bytes(), second.read_bytes()
    if a == b:
        return None
    if first.suffix == ".csv" and "runs" in first.parts:
        (head_a, rows_a), (head_b, rows_b) = _cells(a), _cells(b)
        if head_a == head_b and rows_a == rows_b:
            return None
        pairs = [(ra, rb) for ra, rb in zip(rows_a, rows_b, strict=False) if ra != rb][:3]
        return f"cells other than {sorted(MEASURED)} differ: {pairs or 'header or row count'}"
    if first.suffix in (".csv", ".md", ".html", ".tex", ".svg"):
        lines = zip(a.decode().splitlines(), b.decode().splitlines(), strict=False)
        return f"lines differ: {[pair for pair in lines if pair[0] != pair[1]][:4]}"
    return f"bytes differ ({len(a)} and {len(b)} bytes)"


def measured_only(first: Path, second: Path) -> bool:
    """True when the two files differ, and only in measured columns."""
    return first.read_bytes() != second.read_bytes() and difference(first, second) is None
