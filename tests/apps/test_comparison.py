"""allsky.compare() in a notebook: the headline table of allsky compare, the rows at hand."""

import html
import re

import pandas as pd
import pytest

import allsky
from allsky.apps.compare import format_compare, headline
from allsky.apps.comparison import Comparison


@pytest.fixture(scope="module")
def comparison():
    return allsky.compare(runs=4, workers=2, progress=False)


def test_the_repr_is_the_terminal_headline_table(comparison):
    c = comparison
    assert isinstance(c, Comparison) and isinstance(c, pd.DataFrame)
    page = c._repr_html_()
    title, rows, notes = c.headline()
    assert title.startswith("Calibration methods compared on the same vehicle (4 runs, seeds "
                            "1-4)")
    cells = [html.unescape(x) for x in re.findall(r"<t[dh][^>]*>(.*?)</t[dh]>", page)]
    assert cells[:3] == ["figure", "legacy (Modes 4-5)", "dither"]
    shown = [tuple(cells[i:i + 3]) for i in range(3, len(cells), 3)]
    assert shown == [(name.strip(), a, b) for name, a, b in rows]
    # the figures of the terminal's table, line for line
    text = format_compare(c._headline_result).splitlines()
    assert text[0] == title and html.escape(title) in page
    assert text[3:3 + len(rows)] == [f"  {name:<34}{a:>34}{b:>34}" for name, a, b in rows]
    assert all(html.escape(n) in page for n in notes)
    assert "8 rows, one per seed and method (legacy, dither)" in page


def test_the_rows_are_the_dataframe(comparison):
    c = comparison
    assert len(c) == 8 and list(c["method"][:2]) == ["legacy", "dither"]
    assert list(c["seed"]) == [1, 1, 2, 2, 3, 3, 4, 4]
    dither = c[c["method"] == "dither"]
    assert type(dither) is pd.DataFrame  # a selection is a plain frame, without the headline
    assert c.attrs["comparison"]["runs"] == 4
    assert repr(c).startswith("<Comparison: Calibration methods compared")


def test_headline_is_what_allsky_compare_prints():
    from allsky.config import load_scenario
    from allsky.studies.compare import compare

    result = compare(load_scenario(), runs=1, workers=1)
    title, rows, _ = headline(result)
    text = format_compare(result).splitlines()
    assert text[0] == title
    for (name, a, b), line in zip(rows, text[3:], strict=False):
        assert line == f"  {name:<34}{a:>34}{b:>34}"
