"""A notebook as a user runs it: a flight, its inline replay and a comparison.

The notebook is built here (nbformat) and executed in a Jupyter kernel
(nbclient), as the tutorials are. What it shows is then held to what the
user sees: the inline replay, opened in chromium inside a frame as wide as a
notebook's output area, is cut nowhere on the right; the comparison's table
is the one ``allsky compare`` prints, row for row. Without nbclient, a
kernel or chromium the tests are skipped, naming the install command.

The frame itself is 2 px wider than the output area (its border is added to
its 100 % width), so the area scrolls sideways by 2 px: an expected failure
(strict) until the frame's style counts its border.
"""

import contextlib
import html.parser
import io
import re
import time
from pathlib import Path

import pytest

from tests.apps.test_replay_browser import new_driver

INSTALL = "pip install '.[test]'"
REPLAY_CSS = (Path(__file__).resolve().parents[2] / "src" / "allsky" / "apps" / "replay_page"
              / "replay.css")
#: [px] content width of a notebook's output area (JupyterLab's, Notebook's, in a 1280 px
#: window, as measured), where the inline replay has to fit.
NOTEBOOK_OUTPUT_PX = 1123
#: The compare cell's seeds, as ``allsky compare --runs RUNS`` flies them.
RUNS = 4
CELLS = (
    "import allsky\n\nf = allsky.fly()\nf",
    "f.replay()",
    f"c = allsky.compare(runs={RUNS})\nc",
)
#: [s] bounds, not expectations: the notebook runs in about 20 s, the page is ready in 2.
CELL_TIMEOUT_S, READY_TIMEOUT_S = 300, 120


def two_column_px() -> int:
    """[px] the least window width of the replay's two columns, read from its stylesheet."""
    narrow = re.findall(r"@media \(max-width: (\d+)px\)", REPLAY_CSS.read_text())
    assert len(narrow) == 1, narrow
    return int(narrow[0]) + 1


@pytest.fixture(scope="module")
def executed(tmp_path_factory):
    """The notebook, executed: each cell's ``text/html`` output (None where it has none)."""
    nbformat = pytest.importorskip("nbformat", reason=f"nbformat missing: {INSTALL}")
    nbclient = pytest.importorskip("nbclient", reason=f"nbclient missing: {INSTALL}")
    pytest.importorskip("ipykernel", reason=f"ipykernel missing: {INSTALL}")
    folder = tmp_path_factory.mktemp("notebook")
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in CELLS])
    client = nbclient.NotebookClient(nb, timeout=CELL_TIMEOUT_S, kernel_name="python3",
                                     resources={"metadata": {"path": str(folder)}})
    client.execute()  # a cell that raises fails here, with its traceback
    shown = []
    for cell in nb.cells:
        stderr = [o.text for o in cell.outputs if o.output_type == "stream"
                  and o.name == "stderr"]
        assert not stderr, f"{cell.source!r} wrote on stderr: {stderr}"
        html_out = [o.data["text/html"] for o in cell.outputs
                    if o.output_type == "execute_result" and "text/html" in o.data]
        shown.append(html_out[0] if html_out else None)
    return shown


def test_the_flight_shows_its_summary(executed):
    assert 'class="allsky-flight"' in executed[0]
    assert "complete" in executed[0] and "true pointing error" in executed[0]


def _frame_widths() -> dict:
    """[px] output area widths: a notebook's, and either side of the replay's two columns."""
    return {"notebook": NOTEBOOK_OUTPUT_PX, "two columns - 1": two_column_px() - 1,
            "two columns": two_column_px()}


def _open_in_output_area(replay: str, width_px: int, folder: Path):
    """Chromium showing ``replay`` in an output area ``width_px`` wide; the driver."""
    assert replay.startswith('<iframe class="allsky-replay"')
    page = folder / "notebook.html"
    page.write_text('<!DOCTYPE html><meta charset="utf-8"><body style="margin: 0">'
                    f'<div id="output" style="width: {width_px}px; overflow-x: auto">{replay}'
                    "</div>")
    driver = new_driver()  # skips, naming the install command, without selenium or chromium
    from tests.apps.test_replay_browser import set_viewport

    set_viewport(driver, width_px + 100, 1000)
    driver.get(page.as_uri())
    return driver


@pytest.mark.parametrize("width", ["notebook", "two columns - 1", "two columns"])
def test_the_inline_replay_fits_its_frame(executed, tmp_path, width):
    """Inside the frame, at an output area's width: no sideways scroll, no panel cut."""
    from selenium.webdriver.common.by import By

    driver = _open_in_output_area(executed[1], _frame_widths()[width], tmp_path)
    try:
        [frame] = driver.find_elements(By.CSS_SELECTOR, "iframe.allsky-replay")
        frame_width = driver.execute_script("return arguments[0].clientWidth", frame)
        driver.switch_to.frame(frame)
        deadline = time.monotonic() + READY_TIMEOUT_S
        while not driver.execute_script("return Boolean(window.allsky && window.allsky.ready)"):
            assert time.monotonic() < deadline, "the inline replay never became ready"
            time.sleep(0.2)
        content = driver.execute_script("return document.documentElement.scrollWidth")
        assert content <= frame_width, (f"the replay is {content} px wide in a frame of "
                                        f"{frame_width} px: cut on the right")
        panels = driver.execute_script(
            "return Array.from(document.querySelectorAll('[id$=\"-panel\"]'))"
            ".map((p) => [p.id, p.getBoundingClientRect().right]);")
        assert panels and all(right <= frame_width + 0.5 for _, right in panels), panels
    finally:
        driver.quit()


def test_the_inline_frame_fits_the_output_area(executed, tmp_path):
    """The frame itself in a notebook's output area: the area does not scroll sideways."""
    driver = _open_in_output_area(executed[1], NOTEBOOK_OUTPUT_PX, tmp_path)
    try:
        area = driver.execute_script(
            "const o = document.getElementById('output'); return [o.scrollWidth, o.clientWidth]")
        assert area[0] <= area[1], f"the output area scrolls sideways: {area} px"
    finally:
        driver.quit()


class _Rows(html.parser.HTMLParser):
    """The text of each row of the table of class ``allsky-headline``."""

    def __init__(self):
        super().__init__()
        self.rows, self._in_table, self._cell = [], False, None

    def handle_starttag(self, tag, attrs):
        if tag == "table" and "allsky-headline" in (dict(attrs).get("class") or ""):
            self._in_table = True
        elif self._in_table and tag == "tr":
            self.rows.append([])
        elif self._in_table and tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag == "table":
            self._in_table = False
        elif self._in_table and tag in ("td", "th") and self._cell is not None:
            self.rows[-1].append("".join(self._cell).strip())
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def terminal_table(text: str) -> tuple:
    """``allsky compare``'s headline table as printed: ``(title, [(figure, legacy, dither)])``.

    A row is the figure's name, then each method's value right-aligned in its
    column (:func:`allsky.apps.compare.format_compare`): three fields apart by
    two spaces or more. The table ends at the first line that is not one.
    """
    lines = text.splitlines()
    header = next(i for i, ln in enumerate(lines) if ln.lstrip().startswith("figure"))
    rows = []
    for line in lines[header + 1:]:
        row = re.fullmatch(r"  \s*(\S.*?) {2,}(\S.*?) {2,}(\S.*)", line)
        if row is None:
            break
        rows.append(row.groups())
    return lines[0], rows


def test_the_comparison_shows_the_headline_table_of_allsky_compare(executed):
    from allsky.apps import cli

    shown = _Rows()
    shown.feed(executed[2])
    assert shown.rows[0] == ["figure", "legacy (Modes 4-5)", "dither"]
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        assert cli.main(["compare", "--runs", str(RUNS), "--quiet"]) == 0
    title, rows = terminal_table(out.getvalue())
    assert f"<b>{title}</b>" in executed[2]
    assert [tuple(r) for r in shown.rows[1:]] == rows
