"""Compare the tables and the scorecard of two results folders, cell by cell.

Made to measure how much the published numbers move when only the machine changes, e.g. the same
commit run with ``OPENBLAS_CORETYPE=Haswell`` and with the variable unset (docs/REPRODUCTION.md,
"Across BLAS kernels"). Both folders are the ``results`` directory of a pipeline run (``results`` for
the paper's protocol, ``results/quick`` for the quick one).

- Every ``tables/<name>.csv`` present in both folders: its cells are matched on
  ``(setting, method, metric)``, and for each table the script reports how many cells it compared,
  how many differ, and the largest relative difference ``|a - b| / max(|a|, |b|)`` with the cell it
  occurs in. A cell empty in one run only counts as a difference of ``inf``; a cell in one run only is
  counted as unmatched. The CSVs keep 10 significant digits, so relative differences below about
  5e-11 cannot be seen.
- With ``--runs EXPERIMENT``: the job CSVs ``runs/EXPERIMENT/*.csv`` present in both folders, for a
  partial run (e.g. only the full-data Table 4 jobs): per numeric column, the largest relative
  difference over every job and row.
- ``scorecard.csv``, when both folders have one: the banded cells whose verdict (inside or outside
  the band) differs between the two runs, and, for the bands relative to the paper (``rel``,
  ``at_most_rel``), the smallest distance of any cell of the first run to its band's edge (in units
  of our value, comparable with the table differences above).

Usage (from the repository root)::

    .venv/bin/python benchmarks/compare_tables.py /work/baseline/results/quick results/quick
    .venv/bin/python benchmarks/compare_tables.py A B --out results/benchmarks/compare_tables.csv
    .venv/bin/python benchmarks/compare_tables.py /work/baseline/results results --runs table4

Prints a Markdown summary; ``--out`` also writes the per-table summary as CSV. Exits with status 1
when a scorecard verdict flips, 0 otherwise.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from _common import parser as make_parser

KEY = ["setting", "method", "metric"]
SCORE_KEY = ["table", *KEY]
RUN_KEYS = {"seed", "missing_fraction", "p", "noise_std"}  # job CSV columns that name the job


def relative_difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``|a - b| / max(|a|, |b|)`` elementwise: 0 where both are equal (both NaN included), inf where
    exactly one is NaN."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    out = np.zeros(a.shape)
    both = np.isfinite(a) & np.isfinite(b)
    scale = np.maximum(np.abs(a), np.abs(b))
    differ = both & (a != b)
    out[differ] = np.abs(a - b)[differ] / scale[differ]
    out[np.isnan(a) != np.isnan(b)] = np.inf
    return out


def compare_table(a: pd.DataFrame, b: pd.DataFrame) -> dict:
    """Summary of the cell differences of two tidy tables (columns setting, method, metric, value)."""
    merged = a[[*KEY, "value"]].merge(
        b[[*KEY, "value"]], on=KEY, how="outer", suffixes=("_a", "_b"), indicator=True
    )
    both = merged[merged["_merge"] == "both"]
    rel = relative_difference(both["value_a"].to_numpy(), both["value_b"].to_numpy())
    row = {"cells": len(both), "unmatched": int((merged["_merge"] != "both").sum())}
    row["differing"] = int(np.count_nonzero(rel))
    if rel.size and rel.max() > 0:
        worst = both.iloc[int(np.argmax(rel))]
        row["max_rel_diff"] = float(rel.max())
        row["worst_cell"] = f"{worst['setting']} / {worst['method']} / {worst['metric']}"
        row["worst_values"] = f"{worst['value_a']:.10g} vs {worst['value_b']:.10g}"
    else:
        row.update(max_rel_diff=0.0, worst_cell="", worst_values="")
    return row


def compare_tables(first: Path, second: Path) -> pd.DataFrame:
    """One row per table CSV present in both ``first/tables`` and ``second/tables``."""
    rows = []
    for path in sorted((first / "tables").glob("*.csv")):
        other = second / "tables" / path.name
        if other.is_file():
            rows.append({"table": path.stem, **compare_table(pd.read_csv(path), pd.read_csv(other))})
    return pd.DataFrame(rows)


def compare_runs(first: Path, second: Path, experiment: str) -> pd.DataFrame:
    """One row per numeric column of the job CSVs ``runs/<experiment>/*.csv`` present in both folders
    (rows matched by position within a job; timing and key columns left out): the largest relative difference
    over every job and row, and where it occurs."""
    worst: dict[str, tuple[float, str, int]] = {}
    jobs = 0
    for path in sorted((first / "runs" / experiment).glob("*.csv")):
        other = second / "runs" / experiment / path.name
        if not other.is_file():
            continue
        a, b = pd.read_csv(path), pd.read_csv(other)
        if len(a) != len(b) or ("method" in a and not a["method"].equals(b["method"])):
            raise ValueError(f"{path.name}: the two runs have different rows")
        jobs += 1
        for col in a.select_dtypes("number").columns:
            if "seconds" in col or col in RUN_KEYS or col not in b:
                continue
            rel = relative_difference(a[col].to_numpy(), b[col].to_numpy())
            worst.setdefault(col, (0.0, "", 0))
            if rel.size and rel.max() > worst[col][0]:
                i = int(np.argmax(rel))
                where = f"{path.stem} / {a['method'].iloc[i]}" if "method" in a else f"{path.stem} row {i}"
                worst[col] = (float(rel.max()), where, jobs)
    return pd.DataFrame(
        [{"column": c, "jobs": jobs, "max_rel_diff": v, "where": w} for c, (v, w, _) in worst.items()]
    )


def _inside(value) -> bool | None:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    return str(value).strip().lower() == "true"


def band_margin(scored: pd.DataFrame) -> pd.Series:
    """Distance of our value to its band's edge, relative to our value, for ``rel`` and ``at_most_rel``
    bands (NaN for the other kinds): positive inside, negative outside."""
    ours, paper, tol = scored["ours"], scored["paper"], scored["tol"]
    rel = (tol * paper.abs() - (ours - paper).abs()) / ours.abs()
    at_most = ((1 + tol) * paper - ours) / ours.abs()
    margin = pd.Series(np.nan, index=scored.index)
    margin[scored["kind"] == "rel"] = rel
    margin[scored["kind"] == "at_most_rel"] = at_most
    return margin


def compare_scorecards(first: Path, second: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(verdict flips, the first run's banded cells with their band margin)."""
    a, b = pd.read_csv(first / "scorecard.csv"), pd.read_csv(second / "scorecard.csv")
    merged = a.merge(b[[*SCORE_KEY, "ours", "inside"]], on=SCORE_KEY, how="inner", suffixes=("", "_b"))
    flips = merged[
        [_inside(x) != _inside(y) for x, y in zip(merged["inside"], merged["inside_b"], strict=True)]
    ]
    banded = a[a["inside"].notna()].copy()
    banded["margin"] = band_margin(banded)
    return flips[[*SCORE_KEY, "paper", "ours", "ours_b", "band", "inside", "inside_b"]], banded


def markdown(frame: pd.DataFrame, digits: int = 3) -> str:
    """A Markdown table of ``frame`` (floats to ``digits`` significant digits)."""
    if frame.empty:
        return "(nothing to compare)"

    def cell(x) -> str:
        return f"{x:.{digits}g}" if isinstance(x, float) else str(x)

    lines = ["| " + " | ".join(map(str, frame.columns)) + " |", "|" + "---|" * len(frame.columns)]
    lines += ["| " + " | ".join(cell(x) for x in row) + " |" for row in frame.itertuples(index=False)]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = make_parser(__doc__, options=False)
    parser.add_argument("first", type=Path, help="results folder of the first run")
    parser.add_argument("second", type=Path, help="results folder of the second run")
    parser.add_argument("--out", type=Path, help="also write the per-table summary here (CSV)")
    parser.add_argument(
        "--runs", nargs="*", default=[], metavar="EXPERIMENT", help="also compare runs/EXPERIMENT/*.csv"
    )
    args = parser.parse_args(argv)
    for folder in (args.first, args.second):
        if not folder.is_dir():
            parser.error(f"{folder} is not a folder; pass a pipeline's results folder")
    print(f"## {args.first} vs {args.second}\n")
    if (args.first / "tables").is_dir() and (args.second / "tables").is_dir():
        summary = compare_tables(args.first, args.second)
        print(markdown(summary))
        if args.out is not None:
            args.out.parent.mkdir(parents=True, exist_ok=True)
            summary.to_csv(args.out, index=False)
    else:
        print("(no tables/ folder in both)")
    for experiment in args.runs:
        print(f"\n### Job CSVs of {experiment}\n")
        print(markdown(compare_runs(args.first, args.second, experiment)))
    if not ((args.first / "scorecard.csv").is_file() and (args.second / "scorecard.csv").is_file()):
        print("\n(no scorecard in both folders)")
        return 0
    flips, banded = compare_scorecards(args.first, args.second)
    n_inside = int(banded["inside"].map(_inside).sum())
    print(f"\nScorecard: {n_inside} of {len(banded)} banded cells inside in the first run; {len(flips)} flip")
    if len(flips):
        print(markdown(flips, 6))
    close = banded.dropna(subset=["margin"]).sort_values("margin", key=np.abs).head(3)
    if len(close):
        print("\nClosest to a band edge (relative to our value, rel / at_most_rel bands):")
        print(markdown(close[[*SCORE_KEY, "ours", "band", "inside", "margin"]], 4))
    return 1 if len(flips) else 0


if __name__ == "__main__":
    sys.exit(main())
