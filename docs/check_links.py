"""Check a built HTML site for broken internal links and missing images.

``python docs/check_links.py docs/_build/html`` reads every page, follows every relative ``href`` and ``src``
(links to other sites are left alone: the build machine has no network) and checks that the file exists and,
for ``page.html#anchor``, that the page has an element with that id. Exit status 1 with one line per broken link,
0 when every link resolves. Sphinx's ``-W`` already fails on a missing image or an unresolved cross-reference in
the sources; this check covers what reaches the HTML by other ways (raw HTML, the gallery, theme templates).
"""

from __future__ import annotations

import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit


class _Page(HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids: set[str] = set()
        self.links: list[str] = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if a.get("id"):
            self.ids.add(a["id"])
        if tag == "a" and a.get("name"):
            self.ids.add(a["name"])
        for key in ("href", "src"):
            if a.get(key) and not (tag == "link" and a.get("rel") in ("preconnect", "dns-prefetch")):
                self.links.append(a[key])


def _parse(path: Path) -> _Page:
    p = _Page()
    p.feed(path.read_text(encoding="utf-8", errors="replace"))
    return p


def broken_links(root: Path) -> list[str]:
    """``'page: link (reason)'`` for every internal link of the site under ``root`` that does not resolve."""
    root = root.resolve()
    # _static/ holds the theme's template fragments (Jinja source, not pages)
    pages = {p: _parse(p) for p in sorted(root.rglob("*.html")) if "_static" not in p.relative_to(root).parts}
    out = []
    for page, parsed in pages.items():
        for link in parsed.links:
            parts = urlsplit(link)
            if parts.scheme or parts.netloc or link.startswith(("mailto:", "javascript:", "data:")):
                continue
            target = (page.parent / unquote(parts.path)).resolve() if parts.path else page
            if target.is_dir():
                target = target / "index.html"
            rel = page.relative_to(root)
            if not target.exists():
                out.append(f"{rel}: {link} (no such file)")
            elif parts.fragment and target.suffix == ".html":
                ids = pages[target].ids if target in pages else _parse(target).ids
                if unquote(parts.fragment) not in ids:
                    out.append(f"{rel}: {link} (no anchor '{parts.fragment}')")
    return out


def main(argv=None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1 or not Path(args[0]).is_dir():
        print("usage: python docs/check_links.py BUILT_HTML_DIR", file=sys.stderr)
        return 2
    bad = broken_links(Path(args[0]))
    for line in bad:
        print(line)
    n = len(list(Path(args[0]).rglob("*.html")))
    print(f"{n} pages, {len(bad)} broken internal link(s)", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
