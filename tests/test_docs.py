"""The documentation's links resolve: every relative link and ``#anchor`` in README.md and
docs/*.md points at a file that exists and, for a Markdown target, at a heading it has.

Links and headings are found by a Markdown parser (markdown-it-py, CommonMark plus GFM
tables), so a ``#`` line inside a code block is not a heading and a ``[x](y)`` inside one is
not a link. Heading anchors are GitHub's: the heading's text lower-cased, spaces turned into
``-``, everything but letters, digits, ``_`` and ``-`` dropped, and ``-1``, ``-2``, ...
appended to repeats (``mdit_py_plugins.anchors``, which follows GitHub's toc filter).

docs/scene_format.md names everything a scene file and the command line accept, read from the
registries: every object and light type (a section each, its table holding exactly the
reader's keys), the keys of every table, each choice by name (filters, anti-aliasing,
highlights, Fresnel modes, mesh shadings, texture wraps, tone maps, AOVs).
"""

from __future__ import annotations

import re
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


#: An output file named on a command line of the docs (``-o whitted.exr``, ``--png x.png``).
COMMAND_OUTPUT = re.compile(r"(?<![\w-])(?:-o|--output|--png|--hdr|--stats|--diff)\s+"
                            r"([\w./{}#%-]+\.[a-z]+)\b")
#: A file a Python example writes (``image.save("x.png")``).
SAVED = re.compile(r"""\.save\(\s*["']([^"']+)["']""")


def test_api_examples_write_no_file_a_documented_command_writes():
    # Both run from a checkout's root: an example that wrote the README's whitted.exr at
    # another size made the next `raytrace compare` of the README's render fail on sizes.
    commands = {f for page in PAGES for f in COMMAND_OUTPUT.findall(page.read_text("utf-8"))}
    saved = {f for page in ("docs/api.md", "README.md")
             for f in SAVED.findall((ROOT / page).read_text("utf-8"))}
    assert "whitted.exr" in commands and len(saved) > 5
    assert not saved & commands


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


# -- docs/scene_format.md names every registered type, key and choice ----------------------------
SCENE_FORMAT = ROOT / "docs" / "scene_format.md"


def sections(page: Path) -> dict[str, dict]:
    """Each heading of ``page`` by its text: its ``level``, its ``parent`` (the heading one
    level up), its ``tables`` (each a list of rows, each row its cells' inline Markdown) and
    its ``text`` (the page's lines from the heading to the next one)."""
    source = page.read_text(encoding="utf-8")
    lines = source.splitlines()
    tokens = _parser().parse(source)
    out: dict[str, dict] = {}
    stack: list[str] = []
    current = None
    for i, t in enumerate(tokens):
        if t.type == "heading_open":
            title, level = tokens[i + 1].content, int(t.tag[1])
            assert title not in out, f"{page.name}: two headings {title!r}"
            stack = [*stack[:level - 1], title]
            current = out[title] = {"level": level, "parent": stack[-2] if level > 1 else None,
                                    "tables": [], "start": t.map[0]}
        elif current is None:
            continue
        elif t.type == "table_open":
            current["tables"].append([])
        elif t.type == "tr_open":
            current["tables"][-1].append([])
        elif t.type == "inline" and tokens[i - 1].type in ("th_open", "td_open"):
            current["tables"][-1][-1].append(t.content)
    starts = sorted(s["start"] for s in out.values()) + [len(lines)]
    for s in out.values():
        end = starts[starts.index(s["start"]) + 1]
        s["text"] = "\n".join(lines[s["start"]:end])
    return out


def keys(section: dict) -> dict[str, list[str]]:
    """The rows of a section's tables by the code span of their first cell (`` `key` ``)."""
    found = {}
    for table in section["tables"]:
        for row in table[1:]:  # (the header row names the columns)
            m = re.fullmatch(r"`([^`]+)`", row[0].strip())
            if m:
                found[m.group(1)] = row
    return found


def quoted(cell: str) -> set[str]:
    """The ``"name"`` code spans of a table cell: the choices it lists."""
    return set(re.findall(r'`"([^"`]+)"`', cell))


@pytest.fixture(scope="module")
def doc() -> dict[str, dict]:
    return sections(SCENE_FORMAT)


def test_every_table_of_a_scene_file_is_documented_key_by_key(doc):
    from raytrace.material import MATERIAL_KEYS, PATTERN_KEYS
    from raytrace.readers import scene_file
    from raytrace.readers.texture import TEXTURE_KEYS

    assert all(doc[k]["level"] == 2 for k in scene_file.TOP_KEYS)
    for title, want in (("render", scene_file.RENDER_KEYS), ("camera", scene_file.CAMERA_KEYS),
                        ("ambient", ("color",)), ("materials", MATERIAL_KEYS),
                        ("The checker pattern", PATTERN_KEYS),
                        ("Image textures", TEXTURE_KEYS)):
        assert set(keys(doc[title])) == set(want), title


@pytest.mark.parametrize("part", ["objects", "lights"])
def test_every_object_and_light_type_has_its_section_with_its_keys(doc, part):
    # One "### type" section under "## objects" or "## lights" per registered type, whose
    # table has exactly the keys the scene-file reader accepts for it (none missing, none
    # stale), its `type` row naming it.
    from raytrace.readers import scene_file

    registry, accepted = ((scene_file.OBJECT_TYPES, scene_file.OBJECT_KEYS) if part == "objects"
                          else (scene_file.LIGHT_TYPES, scene_file.LIGHT_KEYS))
    typed = {title for title, s in doc.items() if s["parent"] == part and "type" in keys(s)}
    assert typed == set(registry)
    for kind, cls in registry.items():
        table = keys(doc[kind])
        assert set(table) == set(accepted[cls]), kind
        assert quoted(table["type"][1]) == {kind}, kind


def test_every_choice_by_name_is_listed(doc):
    # Each key that takes a name lists every name of its registry, and only those.
    from raytrace.material import FRESNELS, HIGHLIGHTS
    from raytrace.readers.texture import WRAPS
    from raytrace.sampling import AA_MODES, FILTERS, TEXTURE_FILTERS
    from raytrace.scene import SHADINGS

    for title, key, names in (("render", "filter", FILTERS), ("render", "aa", AA_MODES),
                              ("render", "texture_filter", TEXTURE_FILTERS),
                              ("materials", "highlight", HIGHLIGHTS),
                              ("materials", "fresnel", FRESNELS), ("mesh", "shading", SHADINGS),
                              ("Image textures", "wrap", WRAPS),
                              ("The checker pattern", "pattern", ("checker",))):
        assert quoted(keys(doc[title])[key][1]) == set(names), (title, key)


def test_every_tone_map_and_aov_is_documented(doc):
    from raytrace.film.aov import AOVS
    from raytrace.film.tonemap import TONEMAPS
    from raytrace.sampling import AA_MODES, FILTERS, TEXTURE_FILTERS

    assert set(keys(doc["Tone maps"])) == set(TONEMAPS)
    assert doc["Tone maps"]["parent"] == "Command line"
    cli = doc["Command line"]["text"]
    assert f"[--aov {','.join(AOVS)}]" in cli
    described = set(re.findall(r"`(\w+)`\s+\(`", cli.split("`--aov` adds AOVs")[1]))
    assert set(AOVS) <= described  # each named, its channels in brackets after it
    assert f"[--filter {'|'.join(FILTERS)}]" in cli and f"[--aa {'|'.join(AA_MODES)}]" in cli
    assert f"[--texture-filter {'|'.join(TEXTURE_FILTERS)}]" in cli


def test_the_section_reader_finds_tables_and_choices(tmp_path):
    # The helpers above on a page made by hand.
    page = tmp_path / "p.md"
    page.write_text('# P\n\n## a\n\ntext\n\n### b\n\n| key | type |\n|---|---|\n'
                    '| `x` | `"u"` or `"v"` |\n| not a key | y |\n\n## c\n\nmore\n',
                    encoding="utf-8")
    s = sections(page)
    assert (s["b"]["parent"], s["c"]["parent"], s["b"]["level"]) == ("a", "P", 3)
    assert list(keys(s["b"])) == ["x"] and quoted(keys(s["b"])["x"][1]) == {"u", "v"}
    assert s["a"]["text"] == "## a\n\ntext\n" and s["c"]["text"].endswith("more")
