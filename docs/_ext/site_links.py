"""Every internal link of the built site resolves: checked offline, after the build.

Sphinx checks cross-references (nitpicky mode) and MyST its own links while
it reads; what neither sees is the HTML they become, links written as raw
HTML (the tutorials' links to their replay pages) and the theme's own.
After an HTML build this extension reads every page of the site and reports,
as a build warning (an error under ``-W``), each ``href`` or ``src`` that
names no file of the site, and each ``#fragment`` that names no element of
its page. External addresses (a scheme such as https:, mailto:, data:) are
not followed: the build is offline.
"""

from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

#: The folder of the theme's assets: templates among them are not pages.
THEME_ASSETS = "_static"
#: Attributes holding a link.
LINK_ATTRIBUTES = ("href", "src")


class _Page(HTMLParser):
    """The links and the element ids of one HTML page."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.links, self.ids = [], set()

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if name in ("id", "name") and value:
                self.ids.add(value)
            elif name in LINK_ATTRIBUTES and value is not None and not (
                    tag == "link" and ("rel", "canonical") in attrs):
                self.links.append(value)


def read_page(path: Path) -> _Page:
    """Parse one HTML file: its links and ids."""
    page = _Page()
    page.feed(path.read_text(encoding="utf-8", errors="replace"))
    page.close()
    return page


def broken_links(site) -> list:
    """Every internal link of the HTML files under ``site`` that resolves to nothing.

    Parameters
    ----------
    site : path-like
        The built site's root folder.

    Returns
    -------
    list of str
        ``page: link (why)``, one per broken link, pages in sorted order.
    """
    site = Path(site).resolve()
    pages = {p: read_page(p) for p in sorted(site.rglob("*.html"))
             if THEME_ASSETS not in p.relative_to(site).parts}
    broken = []
    for path, page in pages.items():
        for link in page.links:
            parts = urlsplit(link)
            if parts.scheme or parts.netloc or link.startswith("//"):
                continue  # external (https:, mailto:, data:, javascript:): not followed
            target = path if not parts.path else (path.parent / unquote(parts.path)).resolve()
            if target.is_dir():
                target = target / "index.html"
            where = f"{path.relative_to(site)}: {link}"
            if site not in target.parents and target != site:
                broken.append(f"{where} (outside the site)")
            elif not target.is_file():
                broken.append(f"{where} (no such file)")
            elif parts.fragment and target.suffix == ".html":
                ids = pages[target].ids if target in pages else read_page(target).ids
                if unquote(parts.fragment) not in ids:
                    broken.append(f"{where} (no element with id {parts.fragment!r})")
    return broken


def _check(app, exception):
    if exception is not None or app.builder.format != "html":
        return
    from sphinx.util import logging

    logger = logging.getLogger(__name__)
    for problem in broken_links(app.outdir):
        logger.warning(f"broken internal link: {problem}", type="site_links")


def setup(app):
    """Check the built site's internal links when the build finishes."""
    app.connect("build-finished", _check)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
