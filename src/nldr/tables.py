"""Tables: tidy result frames -> the canonical CSV, Markdown and LaTeX, with the paper's numbers beside.

The canonical form of every table is a tidy frame with columns ``setting, method, metric, value,
paper`` (``paper`` empty where the paper publishes nothing). The renderers below pivot it to one row
per setting and one column per (method, metric), each cell showing ours and the paper's value.
"""

from __future__ import annotations

import html
import math

import pandas as pd

__all__ = ["TABLE_COLUMNS", "attach_paper", "to_csv", "to_markdown", "to_html", "to_latex"]

TABLE_COLUMNS = ["setting", "method", "metric", "value", "paper"]


def attach_paper(ours: pd.DataFrame, paper: pd.DataFrame) -> pd.DataFrame:
    """Join our (setting, method, metric, value) rows with the paper's; keep our row order."""
    missing = {"setting", "method", "metric", "value"} - set(ours.columns)
    if missing:
        raise ValueError(f"result frame lacks columns {sorted(missing)}")
    out = ours[["setting", "method", "metric", "value"]].merge(
        paper, on=["setting", "method", "metric"], how="left", validate="one_to_one"
    )
    return out[TABLE_COLUMNS]


def _fmt(x, digits: int) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "–"
    if isinstance(x, str):
        return x
    return f"{x:.{digits}g}"


def _wide(table: pd.DataFrame, digits: int, metrics=None, transpose: bool = False) -> pd.DataFrame:
    """Pivot to settings x (method metric); a metric ``<m>_sd`` is folded into ``<m>`` as 'mean ± sd'.

    ``metrics`` restricts the shown metrics (their ``_sd`` companions follow); with one metric the
    columns are labelled by method alone. ``transpose`` puts methods in rows, settings in columns.
    """
    if metrics is not None:
        keep = set(metrics) | {m + "_sd" for m in metrics}
        table = table[table["metric"].isin(keep)]
    lookup = {(r.setting, r.method, r.metric): (r.value, r.paper) for r in table.itertuples(index=False)}
    settings = list(dict.fromkeys(table["setting"]))
    columns = list(
        dict.fromkeys(
            (r.method, r.metric) for r in table.itertuples(index=False) if not r.metric.endswith("_sd")
        )
    )
    grid = {}
    for method, metric in columns:
        cells = []
        for setting in settings:
            if (setting, method, metric) not in lookup:
                cells.append("")
                continue
            value, paper = lookup[(setting, method, metric)]
            sd, paper_sd = lookup.get((setting, method, metric + "_sd"), (None, None))
            ours = _fmt(value, digits) + ("" if _isnan(sd) else f" ± {_fmt(sd, 2)}")
            if not _isnan(paper):
                ours += (
                    f" ({_fmt(paper, digits)}" + ("" if _isnan(paper_sd) else f" ± {_fmt(paper_sd, 2)}") + ")"
                )
            cells.append(ours)
        single = len({m for _, m in columns}) == 1
        grid[method if single else f"{method} {metric}"] = cells
    wide = pd.DataFrame(grid, index=pd.Index(settings, name="setting"))
    return wide.T.rename_axis("method") if transpose else wide


def _legend(table: pd.DataFrame) -> str:
    """The line under a rendered table: what its cells hold."""
    if pd.to_numeric(table["paper"], errors="coerce").notna().any():
        return "Cells: ours (paper)."
    return "Cells: ours; the paper publishes no numbers for this table."


def _isnan(x) -> bool:
    return x is None or (isinstance(x, float) and math.isnan(x))


def to_csv(table: pd.DataFrame) -> str:
    """The canonical CSV text (full precision)."""
    return table[TABLE_COLUMNS].to_csv(index=False, float_format="%.10g")


def to_markdown(
    table: pd.DataFrame, *, title: str = "", digits: int = 4, metrics=None, transpose: bool = False
) -> str:
    """A Markdown table: one row per setting (or per method), cells 'ours ± sd (paper)'."""
    wide = _wide(table, digits, metrics, transpose)
    header = [wide.index.name, *wide.columns]
    lines = [f"**{title}**", ""] if title else []
    lines.append("| " + " | ".join(header) + " |")
    lines.append("|" + "---|" * len(header))
    for setting, row in wide.iterrows():
        lines.append("| " + " | ".join([str(setting), *row.tolist()]) + " |")
    lines.append("")
    lines.append(_legend(table))
    return "\n".join(lines) + "\n"


# A small stylesheet for the HTML renderings (tables, scorecard): readable in a browser and inside
# Snakemake's report, which shows .html outputs inline.
STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; font-size: 14px;
       color: #1f2328; margin: 1em; line-height: 1.45; }
table { border-collapse: collapse; margin: 0.6em 0 1.2em 0; }
th, td { border: 1px solid #d0d7de; padding: 0.3em 0.65em; text-align: right; white-space: nowrap; }
th { background: #f3f4f6; }
td:first-child, th:first-child { text-align: left; }
tbody tr:nth-child(even) { background: #fafbfc; }
caption { caption-side: top; text-align: left; max-width: 60em; padding-bottom: 0.5em; }
.note { color: #57606a; }
"""


def html_page(title: str, body: str) -> str:
    """A standalone HTML document: ``body`` (HTML) under ``title`` with the :data:`STYLE` sheet."""
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>{html.escape(title)}</title>\n"
        f"<style>{STYLE}</style>\n</head>\n<body>\n{body}\n</body>\n</html>\n"
    )


def to_html(
    table: pd.DataFrame, *, title: str = "", digits: int = 4, metrics=None, transpose: bool = False
) -> str:
    """A standalone HTML page of the table (cells 'ours ± sd (paper)', the same grid as
    :func:`to_markdown`), for browsers and Snakemake's report."""
    wide = _wide(table, digits, metrics, transpose)
    flat = wide.reset_index().rename_axis(columns=None)  # the row labels as the first column
    grid = flat.to_html(escape=True, border=0, index=False, na_rep="–")
    if title:
        opening = grid.index(">", grid.index("<table")) + 1
        grid = grid[:opening] + f"<caption>{html.escape(title)}</caption>" + grid[opening:]
    body = grid + f'\n<p class="note">{_legend(table)}</p>'
    return html_page(title or "table", body)


def _tex_escape(s: str) -> str:
    return s.replace("_", r"\_").replace("%", r"\%").replace("–", "--")


def to_latex(
    table: pd.DataFrame,
    *,
    caption: str = "",
    label: str = "",
    digits: int = 4,
    metrics=None,
    transpose: bool = False,
) -> str:
    """A LaTeX tabular (booktabs rules), cells 'ours ± sd (paper)'."""
    wide = _wide(table, digits, metrics, transpose)
    cols = "l" + "c" * wide.shape[1]
    lines = [r"\begin{table}[t]", r"\centering"]
    if caption:
        lines.append(rf"\caption{{{_tex_escape(caption)}}}")
    if label:
        lines.append(rf"\label{{{label}}}")
    lines += [rf"\begin{{tabular}}{{{cols}}}", r"\toprule"]
    lines.append(" & ".join(_tex_escape(c) for c in [wide.index.name, *wide.columns]) + r" \\")
    lines.append(r"\midrule")
    for setting, row in wide.iterrows():
        lines.append(" & ".join(_tex_escape(str(c)) for c in [setting, *row.tolist()]) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}", r"\end{table}"]
    return "\n".join(lines) + "\n"
