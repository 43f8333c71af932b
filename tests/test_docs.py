"""The documentation's links resolve: every relative link and ``#anchor`` in README.md and
docs/*.md points at a file that exists and, for a Markdown target, at a heading it has.

Links and headings are found by a Markdown parser (markdown-it-py, CommonMark plus GFM
tables), so a ``#`` line inside a code block is not a heading and a ``[x](y)`` inside one is
not a link. Heading anchors are GitHub's: the heading's text lower-cased, spaces turned into
``-``, everything but letters, digits, ``_`` and ``-`` dropped, and ``-1``, ``-2``, ...
appended to repeats (``mdit_py_plugins.anchors``, which follows GitHub's toc filter).
"""

from __future__ import annotations

from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest
from markdown_it import MarkdownIt
from mdit_py_plugins.anchors import anchors_plugin

ROOT = Path(__file__).resolve().parent.parent
PAGES = sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md")])


def _parser() -> MarkdownIt:
    return (MarkdownIt("commonmark").enable(["table", "strikethrough"])
            .use(anchors_plugin, min_level=1, max_level=6))


def _tokens(page: Path) -> list:
    """The page's tokens, inline children flattened in."""
    out = []
    for token in _parser().parse(page.read_text(encoding="utf-8")):
        out.append(token)
        out.extend(token.children or ())
    return out


def anchors(page: Path) -> set[str]:
    """The ``#fragment`` names a Markdown page defines: its headings' GitHub anchors."""
    return {t.attrGet("id") for t in _tokens(page) if t.type == "heading_open"}


def links(page: Path) -> list[str]:
    """Every link and image target on the page, in order."""
    found = []
    for t in _tokens(page):
        if t.type == "link_open":
            found.append(t.attrGet("href"))
        elif t.type == "image":
            found.append(t.attrGet("src"))
    return found


def broken_links(page: Path, root: Path = ROOT) -> list[str]:
    """``"target: problem"`` for each relative link of ``page`` that does not resolve.

    A link with a scheme (``https:``, ``mailto:``) is not checked. A path is taken relative
    to the page's folder and must exist inside ``root``; a fragment must be an anchor of the
    target page (of ``page`` itself for a bare ``#fragment``) when that is Markdown.
    """
    problems = []
    cache: dict[Path, set[str]] = {}
    for target in links(page):
        parts = urlsplit(target)
        if parts.scheme or parts.netloc:
            continue
        path = (page.parent / unquote(parts.path)).resolve() if parts.path else page
        if not path.is_relative_to(root.resolve()):
            problems.append(f"{target}: points outside the repository")
            continue
        if not path.exists():
            problems.append(f"{target}: no such file")
            continue
        if parts.fragment and path.suffix == ".md":
            if path not in cache:
                cache[path] = anchors(path)
            if unquote(parts.fragment) not in cache[path]:
                problems.append(f"{target}: {path.name} has no heading with anchor "
                                f"#{parts.fragment}")
    return problems


def test_pages_are_found():
    names = {p.relative_to(ROOT).as_posix() for p in PAGES}
    assert {"README.md", "docs/architecture.md", "docs/performance.md",
            "docs/knobs.md"} <= names


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_every_relative_link_and_anchor_resolves(page):
    assert broken_links(page) == []


def summary(page: Path) -> list:
    """The tokens between a page's title and its first section heading."""
    tokens = _tokens(page)
    heads = [i for i, t in enumerate(tokens) if t.type == "heading_open"]
    first_section = next((i for i in heads if tokens[i].tag != "h1"), len(tokens))
    return tokens[heads[0] + 1:first_section] if heads else []


@pytest.mark.parametrize("page", sorted((ROOT / "docs").glob("*.md")), ids=lambda p: p.name)
def test_every_page_opens_with_a_short_summary(page):
    """docs/STYLE: a page opens with a summary a newcomer reads in a minute (at most 400 words,
    about two minutes' reading at most), linking to at least three of the page's sections."""
    head = summary(page)
    words = sum(len(t.content.split()) for t in head if t.type in ("text", "code_inline"))
    own = [t.attrGet("href") for t in head if t.type == "link_open"
           and t.attrGet("href").startswith("#")]
    assert 0 < words <= 400, f"{page.name}: {words} words before the first section"
    assert len(set(own)) >= 3, f"{page.name}: the summary links to {own}"


def test_github_anchor_rules():
    """Anchors as GitHub makes them, worked out by hand from headings used in docs/."""
    page = ROOT / "docs" / "shading.md"
    have = anchors(page)
    assert "whitted-recursion-reflection-and-refraction" in have   # ':' dropped
    assert "mesh-shading-flat-smooth-gouraud" in have              # ',' dropped
    rec = anchors(ROOT / "docs" / "recursion.md")
    assert "--stats-and-imagestats-key-by-key" in rec   # code spans keep their text, '.' dropped


def test_checker_reports_broken_links(tmp_path):
    """The checker itself fails on each kind of broken link (and only on those)."""
    (tmp_path / "other.md").write_text("# Other page\n\n## A section: here\n",
                                       encoding="utf-8")
    (tmp_path / "pic.png").write_bytes(b"")
    page = tmp_path / "page.md"
    page.write_text(
        "# Page\n\n## Repeat\n\n## Repeat\n\n"
        "[ok](other.md#a-section-here) [ok](#repeat-1) ![ok](pic.png) [ok](https://x.org/#n)\n"
        "[gone](missing.md) [bad anchor](other.md#a-section) [self](#nowhere)\n"
        "[out](../../etc/passwd)\n\n"
        "```md\n[in code](nothing.md)\n# not a heading\n```\n"
        "| a | b |\n|---|---|\n| [in table](table.md) | x |\n",
        encoding="utf-8")
    assert broken_links(page, root=tmp_path) == [
        "missing.md: no such file",
        "other.md#a-section: other.md has no heading with anchor #a-section",
        "#nowhere: page.md has no heading with anchor #nowhere",
        "../../etc/passwd: points outside the repository",
        "table.md: no such file",
    ]
    assert "not-a-heading" not in anchors(page)
