"""A check of the HTML reports with the standard library: the page is well formed
(every element closed, in order), needs nothing from the network, and every picture it
shows is a file of the report folder."""

from __future__ import annotations

from html.parser import HTMLParser
from pathlib import Path

_VOID = {"meta", "br", "img", "line", "rect", "polyline", "text", "hr"}


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.images: list[str] = []
        self.links: list[str] = []
        self.open: list[str] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "img":
            self.images.append(attrs["src"])
        if tag == "a":
            self.links.append(attrs.get("href", ""))
        if tag in {"script", "link", "iframe"}:
            raise AssertionError(f"<{tag}> on a self-contained page")
        if tag not in _VOID:
            self.open.append(tag)

    def handle_endtag(self, tag):
        if tag in _VOID:
            return
        assert self.open and self.open.pop() == tag, tag

    def handle_data(self, data):
        self.text.append(data)


def check_page(path: Path) -> tuple[list[str], str]:
    """The pictures of the page at ``path`` (all checked to exist beside it, none from the
    network) and its text."""
    parser = _Page()
    parser.feed(path.read_text())
    parser.close()
    assert parser.open == [], parser.open  # every element closed, in order
    for src in parser.images + [h for h in parser.links if h]:
        assert "://" not in src and not src.startswith("//"), src
        assert (path.parent / src).is_file(), src
    return parser.images, " ".join(parser.text)
