"""Build the documentation site with warnings as errors, then check every on-site link and image of the
built pages (the file exists, its #anchor too). Sphinx, furo and MyST: the `docs` extra.

    frictiongym docs [--out build/docs] [--linkcheck]

--linkcheck also runs Sphinx's linkcheck builder on the external addresses (it needs the network).
Open OUT/index.html; the leaderboard page is OUT/leaderboard/index.html.
"""

from __future__ import annotations

import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

from frictiongym.scripts.options import parser

DOCS = Path(__file__).resolve().parents[1] / "docs"


class _Links(HTMLParser):
    """The ids, and the href/src targets, of one HTML page."""

    def __init__(self) -> None:
        super().__init__()
        self.ids: set[str] = set()
        self.targets: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        for k, v in attrs:
            if k in ("id", "name") and v:
                self.ids.add(v)
            if k in ("href", "src") and v and tag in ("a", "img", "link", "script"):
                self.targets.append(v)


def broken_links(site: Path) -> list[str]:
    """Every on-site link of the built site whose file or #anchor is missing, as 'page: target'."""
    pages: dict[Path, _Links] = {}
    for page in site.rglob("*.html"):
        parser = _Links()
        parser.feed(page.read_text(encoding="utf-8", errors="replace"))
        pages[page.resolve()] = parser
    broken = []
    for page, links in sorted(pages.items()):
        for target in links.targets:
            url = urlsplit(target)
            if url.scheme or url.netloc or target.startswith(("data:", "mailto:", "javascript:")):
                continue
            path = (page.parent / unquote(url.path)).resolve() if url.path else page
            if path.is_dir():
                path = path / "index.html"
            if not path.exists():
                broken.append(f"{page.relative_to(site.resolve())}: {target}")
            elif url.fragment and path in pages and unquote(url.fragment) not in pages[path].ids:
                broken.append(f"{page.relative_to(site.resolve())}: {target} (no such anchor)")
    return broken


def build(out: Path, linkcheck: bool = False) -> list[str]:
    """Build the site into out/ with warnings as errors; the problems found (empty: none)."""
    from sphinx.cmd.build import build_main  # the docs extra, optional: main names it when it is missing

    if build_main(["-W", "--keep-going", "-q", "-b", "html", str(DOCS), str(out)]) != 0:
        return [f"sphinx-build {DOCS} failed (its warnings above)"]
    problems = broken_links(out)
    if linkcheck and build_main(["-q", "-b", "linkcheck", str(DOCS), str(out / "_linkcheck")]) != 0:
        problems.append(f"external links: see {out / '_linkcheck' / 'output.txt'}")
    return problems


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("--out", type=Path, default=Path("build/docs"), help="the site's folder")
    ap.add_argument("--linkcheck", action="store_true", help="also check external links (network)")
    args = ap.parse_args(argv)
    try:
        problems = build(args.out, args.linkcheck)
    except ImportError as e:
        print(f"frictiongym docs: {e.name} is missing: pip install -e '.[docs]'", file=sys.stderr)
        return 1
    for p in problems:
        print(f"frictiongym docs: {p}", file=sys.stderr)
    if not problems:
        print(args.out / "index.html")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
