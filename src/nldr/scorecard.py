"""Reproduction scorecard: every number the paper publishes, ours beside it, and whether ours is inside
the band agreed for it.

Bands are data (``config/config.yaml``, key ``scorecard``), one mapping per rule:

``table``
    Table name (``"table1"`` ...), the key under which its tidy frame is passed.
``metric``
    The metric the rule scores (``"e3d"``, ``"sse"`` ...).
``methods`` (optional)
    Methods the rule applies to; all when absent.
``settings`` (optional)
    Regular expression searched in the setting label (``"full$"``, ``"^Mean"``); all when absent.
``kind`` and ``tol``
    - ``rel``: ``|ours - paper| <= tol * paper``;
    - ``at_most_rel``: ``ours <= (1 + tol) * paper``;
    - ``within_sd``: ``|ours - paper| <= tol * paper_sd`` (the paper's standard deviation, metric
      ``<metric>_sd``);
    - ``at_most_sd``: ``ours <= paper + tol * paper_sd``;
    - ``range_or_rel``: the paper's value inside our ``[<metric>_min, <metric>_max]`` over seeds, or
      ``|ours - paper| <= tol * ours``;
    - ``none``: reported beside the paper without a band (the rule documents why).
``doc``
    Anchor in docs/REPRODUCTION.md that explains the cell's protocol and any gap.

Each published cell is scored by the first rule that matches it; a cell no rule matches is reported
with kind ``none``. The input frames are the project's tidy tables (``setting, method, metric, value,
paper``; see :mod:`nldr.tables`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence

import pandas as pd

__all__ = ["score", "counts", "to_markdown"]

KINDS = ("rel", "at_most_rel", "within_sd", "at_most_sd", "range_or_rel", "none")
SCORE_COLUMNS = [
    "table",
    "setting",
    "method",
    "metric",
    "paper",
    "ours",
    "rel_diff",
    "kind",
    "tol",
    "band",
    "inside",
    "doc",
]


def _check_rule(rule: Mapping, index: int) -> dict:
    rule = dict(rule)
    for key in ("table", "metric", "kind"):
        if key not in rule:
            raise ValueError(f"bands[{index}] has no {key!r}; each rule needs table, metric and kind")
    if rule["kind"] not in KINDS:
        raise ValueError(f"bands[{index}]['kind'] must be one of {KINDS}; got {rule['kind']!r}")
    if rule["kind"] != "none":
        tol = rule.get("tol")
        if isinstance(tol, bool) or not isinstance(tol, int | float) or not tol >= 0:
            raise ValueError(
                f"bands[{index}]['tol'] must be a number >= 0 for kind {rule['kind']!r}; got {tol!r}"
            )
    rule.setdefault("tol", math.nan)
    rule.setdefault("doc", "")
    rule["_pattern"] = re.compile(rule["settings"]) if rule.get("settings") else None
    return rule


def _matches(rule: dict, table: str, setting: str, method: str, metric: str) -> bool:
    if rule["table"] != table or rule["metric"] != metric:
        return False
    if rule.get("methods") is not None and method not in rule["methods"]:
        return False
    return rule["_pattern"] is None or rule["_pattern"].search(setting) is not None


def _nan(x) -> bool:
    return x is None or (isinstance(x, float) and math.isnan(x))


def _judge(kind: str, tol: float, ours: float, paper: float, extra: Mapping) -> tuple[str, object]:
    """(band text, inside) for one cell; inside is None when there is no band or no value."""
    if kind == "none":
        return "", None
    if _nan(ours):
        return "no value", False
    if kind == "rel":
        return f"within {tol:.0%} of the paper", bool(abs(ours - paper) <= tol * abs(paper))
    if kind == "at_most_rel":
        return f"at most paper + {tol:.0%}", bool(ours <= (1 + tol) * paper)
    if kind in ("within_sd", "at_most_sd"):
        sd = extra.get("paper_sd")
        if _nan(sd):
            return "paper has no sd", None
        if kind == "within_sd":
            return f"within {tol:g} paper sd", bool(abs(ours - paper) <= tol * sd)
        return f"at most paper + {tol:g} sd", bool(ours <= paper + tol * sd)
    lo, hi = extra.get("min"), extra.get("max")
    in_range = not (_nan(lo) or _nan(hi)) and lo <= paper <= hi
    return f"paper in our range, or within {tol:.0%} of ours", bool(
        in_range or abs(ours - paper) <= tol * ours
    )


def score(tables: Mapping[str, pd.DataFrame], bands: Sequence[Mapping]) -> pd.DataFrame:
    """One row per published number of every given table: paper, ours, relative difference, band.

    Parameters
    ----------
    tables : mapping of str to DataFrame
        Table name -> tidy frame with columns ``setting, method, metric, value, paper``.
    bands : sequence of mappings
        The rules described in the module docstring (first match wins).

    Returns
    -------
    DataFrame
        Columns :data:`SCORE_COLUMNS`. ``rel_diff`` is ``(ours - paper) / paper``; ``inside`` is True,
        False, or None where the cell has no band.
    """
    rules = [_check_rule(rule, i) for i, rule in enumerate(bands)]
    rows = []
    for name, table in tables.items():
        missing = {"setting", "method", "metric", "value", "paper"} - set(table.columns)
        if missing:
            raise ValueError(f"tables[{name!r}] lacks columns {sorted(missing)}")
        cells = {(r.setting, r.method, r.metric): (r.value, r.paper) for r in table.itertuples(index=False)}
        for (setting, method, metric), (value, paper) in cells.items():
            if _nan(paper) or metric.endswith(("_sd", "_min", "_max")):
                continue
            rule = next((r for r in rules if _matches(r, name, setting, method, metric)), None)
            kind = "none" if rule is None else rule["kind"]
            tol = math.nan if rule is None else rule["tol"]
            extra = {
                "paper_sd": cells.get((setting, method, metric + "_sd"), (None, None))[1],
                "min": cells.get((setting, method, metric + "_min"), (None, None))[0],
                "max": cells.get((setting, method, metric + "_max"), (None, None))[0],
            }
            band, inside = _judge(kind, tol, value, paper, extra)
            rows.append(
                {
                    "table": name,
                    "setting": setting,
                    "method": method,
                    "metric": metric,
                    "paper": paper,
                    "ours": value,
                    "rel_diff": math.nan if _nan(value) else (value - paper) / paper,
                    "kind": kind,
                    "tol": tol,
                    "band": band,
                    "inside": inside,
                    "doc": "" if rule is None else rule["doc"],
                }
            )
    return pd.DataFrame(rows, columns=SCORE_COLUMNS)


def counts(scored: pd.DataFrame) -> dict[str, int]:
    """Cells in total, cells with a band, and how many of those are inside it."""
    banded = scored[scored["inside"].notna()]
    return {
        "cells": len(scored),
        "banded": len(banded),
        "inside": int(banded["inside"].astype(bool).sum()),
    }


def to_markdown(scored: pd.DataFrame, *, doc_link: str = "../docs/REPRODUCTION.md", digits: int = 4) -> str:
    """Markdown: one section per table, one line per published cell, gaps linked to their explanation."""
    lines = []
    for name, group in scored.groupby("table", sort=False):
        c = counts(group)
        title = re.sub(r"^table(\d+)$", r"Table \1", name)
        lines += [
            f"### {title}: {c['inside']} of {c['banded']} banded cells inside their band"
            f" ({c['cells']} published numbers)",
            "",
            "| setting | method | metric | paper | ours | ours vs paper | band | inside | why |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in group.itertuples(index=False):
            inside = {True: "yes", False: "**no**", None: "–"}[None if r.inside is None else bool(r.inside)]
            why = f"[{r.doc}]({doc_link}#{r.doc})" if r.doc else ""
            rel = "" if _nan(r.rel_diff) else f"{r.rel_diff:+.1%}"
            ours = "–" if _nan(r.ours) else f"{r.ours:.{digits}g}"
            lines.append(
                f"| {r.setting} | {r.method} | {r.metric} | {r.paper:.{digits}g} | {ours} | {rel} | "
                f"{r.band or 'no band'} | {inside} | {why} |"
            )
        lines.append("")
    return "\n".join(lines)
