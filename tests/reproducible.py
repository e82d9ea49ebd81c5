"""Two runs' outputs compared byte for byte (the determinism test, tests/cluster/slurm_pipeline.py).

Every file under ``<results>/tables``, ``<results>/runs`` and ``<results>/figures`` must match byte
for byte, run files included: what a job measures of the machine (wall and CPU seconds, ratios of
times) is written apart, under ``<results>/timings`` (nldr.experiments.base.split_measured), and is
the only output allowed to differ.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

#: the folders whose every file two clean runs must write byte for byte
COMPARED = ("tables", "runs", "figures")


def _changed_columns(a: bytes, b: bytes) -> list[str]:
    """Header names of the CSV columns whose cells differ (all columns if the headers differ)."""
    ra, rb = list(csv.reader(io.StringIO(a.decode()))), list(csv.reader(io.StringIO(b.decode())))
    if not ra or not rb or ra[0] != rb[0] or len(ra) != len(rb):
        return ["<header or row count>"]
    return [
        name
        for i, name in enumerate(ra[0])
        if any(x[i] != y[i] for x, y in zip(ra[1:], rb[1:], strict=True) if len(x) > i and len(y) > i)
    ]


def difference(first: Path, second: Path) -> str | None:
    """None when ``second`` has the bytes of ``first``; otherwise what differs (for a message)."""
    a, b = first.read_bytes(), second.read_bytes()
    if a == b:
        return None
    if first.suffix == ".csv":
        lines = zip(a.decode().splitlines(), b.decode().splitlines(), strict=False)
        changed = [pair for pair in lines if pair[0] != pair[1]][:3]
        return f"columns {_changed_columns(a, b)} differ, e.g. lines {changed}"
    if first.suffix in (".md", ".html", ".tex", ".svg"):
        lines = zip(a.decode().splitlines(), b.decode().splitlines(), strict=False)
        return f"lines differ: {[pair for pair in lines if pair[0] != pair[1]][:4]}"
    return f"bytes differ ({len(a)} and {len(b)} bytes)"


def output_files(root: Path, results: str, folders=COMPARED) -> dict[Path, Path]:
    """Every file under ``root/results/<folder>`` for each of ``folders``, by its path relative to
    ``root``."""
    return {
        p.relative_to(root): p
        for sub in folders
        for p in sorted((root / results / sub).rglob("*"))
        if p.is_file()
    }


def compare_runs(first: Path, second: Path, results: str, folders=COMPARED) -> tuple[int, list[str]]:
    """Every output file of two runs under ``folders`` (:func:`output_files`): how many both wrote,
    and each problem (a folder the first run left empty, a file only one run wrote, a file whose
    bytes differ)."""
    a, b = output_files(first, results, folders), output_files(second, results, folders)
    problems = [
        f"{rel} only in the {'first' if rel in a else 'second'} run" for rel in sorted(a.keys() ^ b.keys())
    ]
    for sub in folders:
        if not any(rel.parts[len(Path(results).parts)] == sub for rel in a):
            problems.append(f"the first run wrote nothing under {results}/{sub}")
    both = sorted(a.keys() & b.keys())
    problems += [f"{rel}: {why}" for rel in both if (why := difference(a[rel], b[rel])) is not None]
    return len(both), problems
