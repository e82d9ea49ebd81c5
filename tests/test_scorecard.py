"""The reproduction scorecard: each band kind decides by its definition, first matching rule wins."""

import math

import pandas as pd
import pytest

from nldr import scorecard


def frame(rows):
    return pd.DataFrame(rows, columns=["setting", "method", "metric", "value", "paper"])


@pytest.fixture
def tables():
    return {
        "t1": frame(
            [
                ("a", "M", "err", 1.04, 1.0),  # +4 %
                ("b", "M", "err", 1.06, 1.0),  # +6 %
                ("a", "N", "err", 0.5, 1.0),  # -50 %
                ("a", "N", "pct", 3.0, math.nan),  # not published: not scored
            ]
        ),
        "t2": frame(
            [
                ("p=0.1", "mean", "sse", 13.0, 10.0),
                ("p=0.1", "mean", "sse_sd", 1.0, 4.0),  # paper sd 4: |13 - 10| = 3 <= 4
                ("p=0.1", "Ours", "sse", 11.5, 10.0),
                ("p=0.1", "Ours", "sse_sd", 1.0, 4.0),  # paper + 0.25 sd = 11 < 11.5
            ]
        ),
        "t3": frame(
            [
                ("X missing50", "TNH", "e3d", 0.12, 0.10),  # +20 % of paper, 16.7 % of ours
                ("X missing50", "TNH", "e3d_min", 0.09, math.nan),
                ("X missing50", "TNH", "e3d_max", 0.13, math.nan),  # paper 0.10 inside [0.09, 0.13]
                ("Y missing50", "TNH", "e3d", 0.12, 0.10),
                ("Y missing50", "TNH", "e3d_min", 0.11, math.nan),
                ("Y missing50", "TNH", "e3d_max", 0.13, math.nan),  # outside, and 16.7 % > 15 %
                ("Mean full", "K", "e3d", 0.109, 0.10),
                ("Mean missing50", "K", "e3d", 0.111, 0.10),
            ]
        ),
    }


BANDS = [
    {"table": "t1", "metric": "err", "methods": ["M"], "kind": "rel", "tol": 0.05, "doc": "one"},
    {"table": "t1", "metric": "err", "kind": "none", "doc": "two"},
    {"table": "t2", "metric": "sse", "methods": ["mean"], "kind": "within_sd", "tol": 1.0},
    {"table": "t2", "metric": "sse", "methods": ["Ours"], "kind": "at_most_sd", "tol": 0.25},
    {"table": "t3", "metric": "e3d", "methods": ["TNH"], "kind": "range_or_rel", "tol": 0.15},
    {"table": "t3", "metric": "e3d", "settings": "^Mean", "kind": "at_most_rel", "tol": 0.10},
]


def test_every_kind_decides_by_its_definition(tables):
    scored = scorecard.score(tables, BANDS).set_index(["table", "setting", "method", "metric"])
    inside = scored["inside"].to_dict()
    assert inside[("t1", "a", "M", "err")] is True
    assert inside[("t1", "b", "M", "err")] is False
    assert inside[("t1", "a", "N", "err")] is None  # the second rule: reported, no band
    assert inside[("t2", "p=0.1", "mean", "sse")] is True
    assert inside[("t2", "p=0.1", "Ours", "sse")] is False
    assert inside[("t3", "X missing50", "TNH", "e3d")] is True
    assert inside[("t3", "Y missing50", "TNH", "e3d")] is False
    assert inside[("t3", "Mean full", "K", "e3d")] is True
    assert inside[("t3", "Mean missing50", "K", "e3d")] is False
    assert scored.loc[("t1", "b", "M", "err"), "rel_diff"] == pytest.approx(0.06)
    assert scored.loc[("t1", "a", "M", "err"), "doc"] == "one"


def test_only_published_headline_cells_are_scored_and_counted(tables):
    scored = scorecard.score(tables, BANDS)
    assert len(scored) == 3 + 2 + 4  # no sd/min/max companions, no unpublished cell
    assert scorecard.counts(scored) == {"cells": 9, "banded": 8, "inside": 4}


def test_unmatched_cells_have_no_band(tables):
    scored = scorecard.score(tables, [])
    assert (scored["kind"] == "none").all() and scored["inside"].isna().all()


def test_markdown_links_each_cell_to_its_explanation(tables):
    text = scorecard.to_markdown(scorecard.score(tables, BANDS))
    assert "### t1: 1 of 2 banded cells inside their band (3 published numbers)" in text
    assert "[one](../docs/REPRODUCTION.md#one)" in text and "**no**" in text


@pytest.mark.parametrize(
    "rule, match",
    [
        ({"metric": "e", "kind": "rel", "tol": 0.1}, "table"),
        ({"table": "t", "metric": "e", "kind": "close", "tol": 0.1}, "kind"),
        ({"table": "t", "metric": "e", "kind": "rel"}, "tol"),
        ({"table": "t", "metric": "e", "kind": "rel", "tol": -1}, "tol"),
    ],
)
def test_bad_rules_are_rejected_naming_the_key(rule, match):
    with pytest.raises(ValueError, match=match):
        scorecard.score({}, [rule])
