"""The documentation site: its sources, its link check, and the site as built.

The site is built by ``.ci/run`` (the README's command). The tests of the
built site read it from ``ALLSKY_DOCS_SITE`` (``.ci/run`` sets it; a missing
site is then a failure) or from ``docs/_build/html`` when it is there (else
they are skipped, naming the command). The browser test opens the first
tutorial in Debian's chromium and drives the replay inline in it.
"""

import json
import os
import re
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS / "_ext"))

import api_reference
import site_links

from tests.apps.test_replay_browser import new_driver

#: The build command: README, .ci/run and docs/conf.py say the same.
BUILD = "sphinx-build -W -n -b html docs docs/_build/html"
TUTORIALS = ("first_mission", "calibration_comparison", "faults_and_campaigns")
#: Each tutorial's missions whose replay pages the site carries.
REPLAYS = {"first_mission": ["first_mission"], "calibration_comparison": ["dither_mission"],
           "faults_and_campaigns": ["voyager1_wrong_star"]}


# -- the sources -------------------------------------------------------------------------

def test_the_build_command_is_the_one_the_readme_and_ci_run():
    assert f"pip install '.[docs]' && {BUILD}" in (ROOT / "README.md").read_text()
    assert BUILD in (ROOT / ".ci" / "run").read_text()
    assert BUILD in (DOCS / "conf.py").read_text()


def test_every_document_is_in_the_site():
    index = (DOCS / "index.md").read_text()
    for page in sorted(DOCS.glob("*.md")):
        if page.stem != "index":
            assert f"\n{page.stem}\n" in index, f"docs/{page.name} is in no toctree"
    tutorials = (DOCS / "tutorials" / "index.md").read_text()
    for name in TUTORIALS:
        assert f"\n{name}\n" in tutorials and f"{{download}}`{name}.ipynb`" in tutorials


def test_the_api_reference_is_in_the_top_bar():
    """The theme's top bar shows the first header_links_before_dropdown toctree entries."""
    shown = int(re.search(r'"header_links_before_dropdown": (\d+)',
                          (DOCS / "conf.py").read_text()).group(1))
    entries = []
    for block in re.findall(r"```\{toctree\}\n(.*?)```", (DOCS / "index.md").read_text(),
                            re.DOTALL):
        entries += [ln.strip() for ln in block.splitlines()
                    if ln.strip() and not ln.startswith(":")]
    assert "api/index" in entries[:shown], entries[:shown]
    assert (DOCS / "api" / "index.md").read_text().startswith("# API reference\n")


def test_the_api_reference_gives_the_public_api_first_and_the_modules_as_internals():
    index = (DOCS / "api" / "index.md").read_text()
    assert index.index("## The Python API\n") < index.index("## Internals\n")
    assert re.search(r"## Internals\n.*```\{toctree\}\n[^`]*\npackages\n", index, re.DOTALL)
    assert (DOCS / "api" / "packages.md").read_text().startswith("# Internals\n")


def test_the_api_reference_lists_every_package_and_foundation_module():
    from allsky.layers import LAYERS, SRC

    listed = set(re.findall(r"^   (allsky\.\w+)$", (DOCS / "api" / "packages.md").read_text(),
                            re.MULTILINE))
    packages = {f"allsky.{layer.package}" for layer in LAYERS if layer.package}
    foundations = {f"allsky.{p.stem}" for p in SRC.glob("*.py") if p.stem != "__init__"
                   and p.stem != "__main__"}
    assert listed == packages | foundations


@pytest.mark.parametrize("name", TUTORIALS)
def test_each_tutorial_keeps_its_replays_and_links_them(name):
    nbformat = pytest.importorskip("nbformat", reason="pip install '.[docs]'")
    nb = nbformat.read(DOCS / "tutorials" / f"{name}.ipynb", as_version=4)
    assert all(not c.get("outputs") for c in nb.cells if c.cell_type == "code"), \
        "commit the tutorials without outputs: the site executes them"
    hidden = [c for c in nb.cells if "remove-cell" in c.metadata.get("tags", [])]
    saved = re.findall(r'"([\w-]+)\.html"', "".join(c.source for c in hidden))
    linked = re.findall(r'href="\.\./replays/([\w-]+)\.html"',
                        "".join(c.source for c in nb.cells if c.cell_type == "markdown"))
    assert saved == linked == REPLAYS[name]


# -- the link check and the reference's resolver -------------------------------------------

def test_the_link_check_finds_a_missing_page_and_a_missing_anchor(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "_static").mkdir()
    (tmp_path / "index.html").write_text(
        '<a href="a/page.html#part">ok</a> <a href="#top" id="top">top</a> '
        '<a href="https://example.org/x">external</a> <img src="data:,">'
        '<a href="a/gone.html">gone</a> <a href="a/page.html#nowhere">no anchor</a>'
        '<a href="a/">folder</a>')
    (tmp_path / "a" / "page.html").write_text('<h2 id="part">Part</h2><a href="../index.html">up'
                                              '</a>')
    (tmp_path / "a" / "index.html").write_text("<p>folder</p>")
    (tmp_path / "_static" / "macros.html").write_text('<a href="{{ pathto(x) }}">theme</a>')
    assert site_links.broken_links(tmp_path) == [
        "index.html: a/gone.html (no such file)",
        "index.html: a/page.html#nowhere (no element with id 'nowhere')"]


def test_the_resolver_follows_python_names():
    from allsky.sim import recorder

    assert api_reference._lookup("allsky.sim.telemetry.COLUMNS") is recorder.COLUMNS
    assert api_reference._lookup("allsky.sim.aot") is None
    assert api_reference._lookup("allsky.sim.mission.Mission.summary") is not None
    assert api_reference._lookup("allsky.sim.mission.Mission.no_such_method") is None


# -- the site as built ------------------------------------------------------------------

def _site():
    given = os.environ.get("ALLSKY_DOCS_SITE")
    site = ROOT / (given or "docs/_build/html")  # a relative path: from the checkout
    if not (site / "index.html").exists():
        if given:
            pytest.fail(f"ALLSKY_DOCS_SITE={given}: no site built there ({BUILD})")
        pytest.skip(f"the site is not built: pip install '.[docs]' && {BUILD}")
    return site


def test_the_built_site_has_every_page_tutorial_and_replay():
    site = _site()
    for page in ("index", "cli", "configuration", "telemetry", "blocks", "api/index",
                 "api/packages", "api/generated/allsky.apps.api", *(
                     f"tutorials/{name}" for name in TUTORIALS)):
        assert (site / f"{page}.html").exists(), page
    for name in TUTORIALS:
        text = (site / "tutorials" / f"{name}.html").read_text()
        assert "Traceback" not in text and 'class="output stderr"' not in text, name
        for replay in REPLAYS[name]:
            page = (site / "replays" / f"{replay}.html").read_text()
            assert "default-src 'none'" in page, replay
    assert site_links.broken_links(site) == []


#: [s] bounds, not expectations: the page is ready in about a second.
LOAD_TIMEOUT_S, READY_TIMEOUT_S = 180, 120


def test_the_first_tutorial_plays_its_replay_inline_offline(saved_states):
    site = _site()
    driver = new_driver()  # skips, naming the install command, without selenium or chromium
    from selenium.webdriver.common.by import By

    try:
        driver.set_page_load_timeout(LOAD_TIMEOUT_S)
        driver.get((site / "tutorials" / "first_mission.html").as_uri())
        [frame] = driver.find_elements(By.CSS_SELECTOR, "iframe.allsky-replay")
        driver.switch_to.frame(frame)
        deadline = time.monotonic() + READY_TIMEOUT_S
        while not driver.execute_script("return Boolean(window.allsky && window.allsky.ready)"):
            assert time.monotonic() < deadline, "the inline replay never became ready"
            time.sleep(0.2)
        state = driver.execute_script("return window.allsky.state()")
        assert state["mode"] == "1" and state["target"] == "Sirius"
        # The tutorial's mission is the default one: the page's modes are the flight's.
        m = saved_states["mission"]
        for record in m.timeline:
            middle = 0.5 * (record.start_s + record.end_s)
            shown = driver.execute_script("return window.allsky.seek(arguments[0])", middle)
            assert shown["mode"] == record.mode, (middle, shown)
        driver.switch_to.default_content()
        requests = [json.loads(e["message"])["message"]["params"].get("request", {})
                    .get("url", "") for e in driver.get_log("performance")]
        remote = [u for u in requests if u and not u.startswith(("file:", "data:", "about:"))]
        assert remote == [], "the site and its replay must make no network request"
        # The theme says on a first visit that no light or dark mode was stored yet.
        errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"
                  and "invalid theme mode" not in e["message"]]
        assert errors == []
    finally:
        driver.quit()


def test_the_api_reference_is_in_the_top_bar_of_a_1280_px_window():
    """Chromium at 1280x720: "API reference" is a link of the top bar, not under "More"."""
    site = _site()
    driver = new_driver()  # 1280x720
    try:
        driver.get((site / "index.html").as_uri())
        shown = driver.execute_script("""
            return Array.from(document.querySelectorAll('.bd-header a.nav-link'))
              .filter((a) => a.textContent.trim() === 'API reference')
              .map((a) => ({visible: a.getClientRects().length > 0 && a.offsetWidth > 0,
                            inMenu: a.closest('.dropdown-menu') !== null,
                            inNavbar: a.closest('.navbar-nav') !== null}));""")
        width = driver.execute_script("return window.innerWidth")
        assert width == 1280, width
        assert shown, "no link 'API reference' in the top bar"
        assert all(not s["inMenu"] for s in shown), shown
        assert any(s["visible"] and s["inNavbar"] for s in shown), shown
    finally:
        driver.quit()


@pytest.mark.parametrize("query, first", [("fly", "allsky.fly"), ("compare", "allsky.compare"),
                                          ("Flight", "allsky.Flight")])
def test_the_site_search_gives_the_public_name_first(query, first):
    """The search page, offline in chromium: the public name before the modules' pages."""
    site = _site()
    driver = new_driver()
    try:
        driver.get((site / "search.html").as_uri() + f"?q={query}")
        deadline = time.monotonic() + READY_TIMEOUT_S
        links = []
        while time.monotonic() < deadline:
            links = driver.execute_script(
                "return Array.from(document.querySelectorAll('#search-results li a'))"
                ".map((a) => a.textContent.trim());")
            if links:
                break
            time.sleep(0.2)
        assert links and links[0] == first, links[:5]
    finally:
        driver.quit()
