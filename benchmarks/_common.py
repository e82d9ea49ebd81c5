"""What every benchmark script shares: BLAS check, timing, options and CSV output.

- :func:`check_blas`: the scripts measure single-threaded BLAS, set by ``OPENBLAS_NUM_THREADS=1`` in
  the environment before Python starts. A ``threadpool_limits(1)`` called after ``import numpy`` does
  not reach a BLAS loaded later (scipy brings its own OpenBLAS), so the scripts rely on the variable
  and warn when it is not 1.
- :func:`timed`: the median of repeated calls by ``time.perf_counter`` (wall) or
  ``time.process_time`` (CPU of this process, for a machine shared with other jobs);
  :func:`cpu_and_wall`: both of one call.
- :func:`parser` and :func:`common_options`: ``--out`` (the folder the CSVs go to), ``--data-dir``,
  ``--repeats`` where a script repeats its timings, ``--quick`` (the smallest configuration, a smoke
  run).
- :func:`write_csv`, :func:`append_row` and :func:`done`: the CSVs under ``results/benchmarks/``; a
  script that appends row by row can be stopped and resumed (rows already written are skipped).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from collections.abc import Callable, Iterable
from pathlib import Path

OUT = Path("results/benchmarks")
CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}


def check_blas(*, measures_threads: bool = False) -> None:
    """Announce the BLAS threads the environment sets; warn unless ``OPENBLAS_NUM_THREADS=1``.

    ``measures_threads``: the script sets the threads of its own child processes, so nothing is
    required of the environment.
    """
    value = os.environ.get("OPENBLAS_NUM_THREADS")
    if measures_threads:
        print(f"BLAS threads set per case by this script (OPENBLAS_NUM_THREADS={value})", file=sys.stderr)
    elif value == "1":
        print("BLAS: OPENBLAS_NUM_THREADS=1 (one thread)", file=sys.stderr)
    else:
        print(
            f"warning: OPENBLAS_NUM_THREADS={value!r}, not 1: BLAS may run on several threads and the "
            "timings depend on the machine's load. Run as OPENBLAS_NUM_THREADS=1 python benchmarks/...",
            file=sys.stderr,
        )


def timed(fn: Callable[[], object], repeats: int = 1, clock: str = "wall") -> tuple[float, object]:
    """``(median seconds over repeats, the last call's result)``; clock ``"wall"`` or ``"cpu"``."""
    tick = CLOCKS[clock]
    seconds, out = [], None
    for _ in range(max(1, repeats)):
        start = tick()
        out = fn()
        seconds.append(tick() - start)
    return statistics.median(seconds), out


def cpu_and_wall(fn: Callable[[], object]) -> tuple[float, float, object]:
    """``(CPU seconds, wall seconds, result)`` of one call."""
    cpu, wall = time.process_time(), time.perf_counter()
    out = fn()
    return time.process_time() - cpu, time.perf_counter() - wall, out


def common_options(parser: argparse.ArgumentParser, *, repeats: int | None = None) -> argparse.ArgumentParser:
    """Add ``--out``, ``--data-dir``, ``--quick`` and (with a default) ``--repeats`` to ``parser``."""
    parser.add_argument("--out", type=Path, default=OUT, help=f"folder of the CSVs (default {OUT})")
    parser.add_argument(
        "--data-dir", default=None, help="data folder (default resources/, or $NLDR_DATA_MIRROR)"
    )
    parser.add_argument("--quick", action="store_true", help="smallest configuration: a smoke run")
    if repeats is not None:
        parser.add_argument(
            "--repeats", type=int, default=repeats, help=f"timings per item, median (default {repeats})"
        )
    return parser


def parser(doc: str, *, repeats: int | None = None, options: bool = True) -> argparse.ArgumentParser:
    """An argument parser whose help is the script's docstring (with the common options if
    ``options``; a script with subcommands adds them to each subcommand instead)."""
    out = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    return common_options(out, repeats=repeats) if options else out


def write_csv(rows, out: Path, name: str) -> Path:
    """Write ``rows`` (a DataFrame or a list of dicts) to ``out/name``; return the path."""
    import pandas as pd

    path = Path(out) / name
    path.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).to_csv(path, index=False)
    print(f"wrote {path}", file=sys.stderr)
    return path


def append_row(row: dict, out: Path, name: str) -> Path:
    """Append one row to ``out/name`` (the header when the file is new)."""
    import pandas as pd

    path = Path(out) / name
    path.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame([row]).to_csv(path, mode="a", header=not path.exists(), index=False)
    return path


def done(out: Path, name: str, columns: Iterable[str]) -> set[tuple]:
    """The ``columns`` of every row already in ``out/name`` (empty if there is no such file), with
    floats rounded to 10 digits so that a p read back from the CSV matches the one asked for."""
    import pandas as pd

    path = Path(out) / name
    if not path.exists():
        return set()
    frame = pd.read_csv(path)
    columns = list(columns)
    return {key(row) for row in frame[columns].itertuples(index=False)}


def key(values: Iterable) -> tuple:
    """A row's key for :func:`done`: floats rounded to 10 digits."""
    return tuple(round(v, 10) if isinstance(v, float) else v for v in values)
