import numpy as np
import pandas as pd
import pytest

from nldr import paper, tables


def test_attach_paper_keeps_rows_and_matches_the_paper():
    ours = pd.DataFrame(
        [("std=0.2", "KPCA", "manifold_error", 0.11), ("std=0.2", "KPCA", "best_rank", 7.0)],
        columns=["setting", "method", "metric", "value"],
    )
    out = tables.attach_paper(ours, paper.paper_frame(paper.TABLE1))
    assert list(out.columns) == tables.TABLE_COLUMNS
    assert out["paper"].iloc[0] == 0.1099 and np.isnan(out["paper"].iloc[1])


def test_renderers_show_ours_sd_and_paper():
    t = pd.DataFrame(
        [
            ("p=0.1", "Ours", "sse", 6.04, 6.0),
            ("p=0.1", "Ours", "sse_sd", 3.1, 3.0),
            ("p=0.5", "1-NN", "sse", np.nan, np.nan),
        ],
        columns=tables.TABLE_COLUMNS,
    )
    md = tables.to_markdown(t)
    assert "| p=0.1 | 6.04 ± 3.1 (6 ± 3) |" in md
    assert "–" in md  # not-available cells
    tex = tables.to_latex(t, caption="x_y", label="tab:x")
    assert "sse" not in tex and r"\label{tab:x}" in tex and "6.04 ± 3.1 (6 ± 3)" in tex
    assert "setting & Ours & 1-NN" in tex  # one metric: columns are the methods
    transposed = tables.to_markdown(t, transpose=True)
    assert "| method | p=0.1 | p=0.5 |" in transposed and "| Ours | 6.04 ± 3.1 (6 ± 3) |  |" in transposed
    two = pd.concat([t, t.assign(metric="seconds", paper=np.nan)])
    assert "Ours sse" in tables.to_markdown(two) and "seconds" not in tables.to_markdown(two, metrics=["sse"])
    back = pd.read_csv(pd.io.common.StringIO(tables.to_csv(t)))
    assert list(back.columns) == tables.TABLE_COLUMNS and back["value"].iloc[0] == 6.04


def test_attach_paper_rejects_frames_without_values():
    with pytest.raises(ValueError, match="value"):
        tables.attach_paper(pd.DataFrame({"setting": [], "method": [], "metric": []}), paper.paper_frame([]))


def test_paper_tables_have_every_published_cell():
    assert len(paper.TABLE1) == 12
    assert len(paper.TABLE2) == 6 * 4 * 2
    assert len(paper.TABLE3) == len(paper.TABLE4) == 5 * 6


def test_html_table_is_a_page_with_the_same_cells_as_markdown():
    t = pd.DataFrame(
        [
            ("p=0.1", "Ours", "sse", 6.04, 6.0),
            ("p=0.1", "Ours", "sse_sd", 3.1, 3.0),
            ("p=0.5", "1-NN", "sse", np.nan, np.nan),
        ],
        columns=tables.TABLE_COLUMNS,
    )
    page = tables.to_html(t, title="Table <2>", transpose=True)
    assert page.startswith("<!DOCTYPE html>") and "<style>" in page
    assert "<caption>Table &lt;2&gt;</caption>" in page  # the title, escaped
    assert "<th>method</th>" in page and "<th>p=0.1</th>" in page and "<th>p=0.5</th>" in page
    assert "<td>6.04 ± 3.1 (6 ± 3)</td>" in page
    # every cell of the Markdown rendering is a cell of the HTML one
    md_cells = {
        c.strip()
        for line in tables.to_markdown(t, transpose=True).splitlines()[2:]
        if line.startswith("| ")
        for c in line.strip("|").split("|")
    }
    assert all(f"<td>{c}</td>" in page for c in md_cells if c)


def test_legend_says_when_the_paper_has_no_numbers():
    t = pd.DataFrame([("p=0.1", "Ours", "sse", 6.04, 6.0)], columns=tables.TABLE_COLUMNS)
    assert "Cells: ours (paper)." in tables.to_markdown(t)
    assert "Cells: ours (paper)." in tables.to_html(t)
    none = t.assign(paper=np.nan)
    for text in (tables.to_markdown(none), tables.to_html(none)):
        assert "(paper)" not in text and "the paper publishes no numbers" in text
