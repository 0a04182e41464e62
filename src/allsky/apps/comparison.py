"""The result of :func:`allsky.compare`: its rows, shown as the headline table.

In a notebook a comparison shows itself as ``allsky compare`` prints it: the
side-by-side table of the two methods (:func:`allsky.apps.compare.headline`)
rather than forty raw rows; the rows are the object itself, a pandas
DataFrame, one row per seed and method.
"""

import html
from typing import ClassVar

import pandas as pd

from allsky.apps.compare import headline

_CELL = "padding: 1px 8px; border-bottom: 1px solid #ddd"


class Comparison(pd.DataFrame):
    """The rows of a comparison (a DataFrame), shown in Jupyter as its headline table.

    One row per seed and method (:func:`allsky.apps.api.comparison_rows`);
    ``attrs["comparison"]`` holds the statistics over the runs and the
    predicted spreads, as ``allsky compare --json`` writes them. A frame
    derived from it (a selection, a ``groupby``) is a plain DataFrame.

    Examples
    --------
    >>> import allsky
    >>> c = allsky.compare(runs=2)       # in Jupyter: the headline table
    >>> c[c["method"] == "dither"]["scale_factor_error_ppm.roll"]
    """

    _metadata: ClassVar[list] = ["_headline_result"]

    @property
    def _constructor(self):
        return pd.DataFrame

    @classmethod
    def of(cls, rows: pd.DataFrame, result: dict) -> "Comparison":
        """A Comparison of the DataFrame ``rows`` and the study's statistics ``result``."""
        out = cls(rows)
        out.attrs.update(rows.attrs)
        out._headline_result = result
        return out

    def headline(self) -> tuple:
        """The headline table: ``(title, rows, notes)``, as ``allsky compare`` prints it."""
        return headline(self._headline_result)

    def _repr_html_(self) -> str:
        title, rows, notes = self.headline()
        esc = html.escape
        head = "".join(f'<th style="{_CELL}; text-align: {a}">{esc(h)}</th>' for h, a in
                       (("figure", "left"), ("legacy (Modes 4-5)", "right"),
                        ("dither", "right")))
        body = "".join(
            f'<tr><td style="{_CELL}; text-align: left; padding-left: '
            f'{8 + 12 * (len(name) - len(name.lstrip()))}px">{esc(name.strip())}</td>'
            f'<td style="{_CELL}; text-align: right">{esc(a)}</td>'
            f'<td style="{_CELL}; text-align: right">{esc(b)}</td></tr>'
            for name, a, b in rows)
        extra = "".join(f"<li>{esc(n)}</li>" for n in notes)
        methods = ", ".join(dict.fromkeys(str(m) for m in self["method"])) \
            if "method" in self else ""
        return (f'<div class="allsky-comparison" style="font-family: sans-serif; '
                f'font-size: 13px"><div><b>{esc(title)}</b></div>'
                f'<table style="border-collapse: collapse; margin: 4px 0" '
                f'class="allsky-headline"><tr>{head}</tr>{body}</table>'
                + (f'<ul style="margin: 2px 0">{extra}</ul>' if extra else "")
                + f'<div style="font-size: 11px; color: #555">the result is a DataFrame of '
                f"{len(self)} rows, one per seed and method ({esc(methods)}), "
                f"{len(self.columns)} columns: c.head(), c[c['method'] == 'dither'] ..."
                "</div></div>")

    def __repr__(self) -> str:
        title, _, _ = self.headline()
        return f"<Comparison: {title}; {len(self)} rows>\n" + pd.DataFrame.__repr__(self)
