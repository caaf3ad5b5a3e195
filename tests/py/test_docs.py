"""The documentation holds together: README.md stays short, and every
relative link and anchor in README.md, CHANGELOG.md and docs/ resolves (a
file of the repository, a heading of a Markdown page, as GitHub renders
them). The checker is shown to catch each kind of break on a scratch tree."""
import re
import unicodedata
from pathlib import Path

import pytest

from conftest import ROOT

README_MAX_LINES = 150
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
FENCE = re.compile(r"^\s*(```|~~~)")


def pages(root):
    """The Markdown pages whose links must resolve."""
    found = [root / "README.md", root / "CHANGELOG.md", *sorted((root / "docs").rglob("*.md"))]
    return [p for p in found if p.is_file()]


def prose_lines(text):
    """(line number, line) outside fenced and indented code blocks, inline
    code removed: what GitHub renders as text, links and headings."""
    in_fence, prev_blank_or_code = False, True
    for n, line in enumerate(text.splitlines(), 1):
        if FENCE.match(line):
            in_fence = not in_fence
            prev_blank_or_code = True
            continue
        if in_fence:
            continue
        # an indented code block starts after a blank line (list items here
        # continue with at most 3 spaces)
        if line.startswith(("    ", "\t")) and prev_blank_or_code:
            continue
        prev_blank_or_code = not line.strip()
        yield n, re.sub(r"`[^`]*`", "", line)


def slug(heading):
    """GitHub's anchor of a heading: the rendered text lower-cased, every
    character but letters, digits, '_', '-' and spaces dropped, spaces to '-'."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link: its text
    text = text.replace("`", "")
    text = re.sub(r"<[^>]+>", "", text).strip().lower()
    out = []
    for ch in text:
        cat = unicodedata.category(ch)
        if ch in "-_" or cat[0] in "LMN" or cat == "Pc":
            out.append(ch)
        elif ch == " ":
            out.append("-")
    return "".join(out)


def anchors(page):
    """Every anchor a page has: its headings' slugs, with GitHub's -1, -2
    suffixes for repeated ones."""
    seen = {}
    result = set()
    in_fence = False
    for line in page.read_text(encoding="utf-8").splitlines():
        if FENCE.match(line):
            in_fence = not in_fence
            continue
        m = None if in_fence else re.match(r"^ {0,3}#{1,6}\s+(.*?)\s*#*\s*$", line)
        if m:
            s = slug(m.group(1))
            k = seen.get(s, 0)
            seen[s] = k + 1
            result.add(s if k == 0 else f"{s}-{k}")
    return result


def broken_links(root):
    """Every relative link or anchor of the pages that does not resolve, as
    'file:line: target: why'."""
    root = root.resolve()
    bad = []
    for page in pages(root):
        for n, line in prose_lines(page.read_text(encoding="utf-8")):
            for m in LINK.finditer(line):
                target = m.group(1)
                if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):  # http:, mailto:, ...
                    continue
                path, _, frag = target.partition("#")
                dest = (page.parent / path).resolve() if path else page
                where = f"{page.relative_to(root)}:{n}: {target}"
                if root not in dest.parents and dest != root:
                    bad.append(f"{where}: outside the repository")
                elif not dest.exists():
                    bad.append(f"{where}: no such file")
                elif frag:
                    if dest.suffix != ".md" or dest.is_dir():
                        bad.append(f"{where}: an anchor into a file that is not a Markdown page")
                    elif frag not in anchors(dest):
                        bad.append(f"{where}: no heading with that anchor in {dest.name}")
    return bad


def test_readme_is_short():
    n = len((ROOT / "README.md").read_text(encoding="utf-8").splitlines())
    assert n <= README_MAX_LINES, f"README.md has {n} lines, at most {README_MAX_LINES}"


def test_every_link_and_anchor_resolves():
    assert len(pages(ROOT)) >= 10  # README, CHANGELOG and the docs pages
    bad = broken_links(ROOT)
    assert not bad, "broken links:\n" + "\n".join(bad)


def test_every_docs_page_is_reachable_from_the_readme():
    """A page nobody links to is a page nobody finds."""
    linked = set()
    for page in pages(ROOT):
        for _, line in prose_lines(page.read_text(encoding="utf-8")):
            for m in LINK.finditer(line):
                path = m.group(1).partition("#")[0]
                if path and not re.match(r"^[a-z][a-z0-9+.-]*:", path, re.I):
                    linked.add((page.parent / path).resolve())
    orphans = [p.relative_to(ROOT) for p in pages(ROOT)
               if p.parent.name == "docs" and p.resolve() not in linked]
    assert not orphans, f"docs pages no page links to: {orphans}"


@pytest.mark.parametrize("page,link,why", [
    ("README.md", "[x](docs/nowhere.md)", "no such file"),
    ("README.md", "[x](docs/a.md#no-such-heading)", "no heading with that anchor"),
    ("docs/a.md", "[x](#no-such-heading)", "no heading with that anchor"),
    ("docs/a.md", "[x](../../outside.md)", "outside the repository"),
    ("docs/a.md", "![plot](img/missing.png)", "no such file"),
    ("docs/a.md", "[x](a.md#the-codes-section-2)", "no heading with that anchor"),
])
def test_the_checker_finds_each_kind_of_break(tmp_path, page, link, why):
    """The checker itself, on a scratch tree: clean, then with one break."""
    (tmp_path / "docs").mkdir()
    (tmp_path / "README.md").write_text("# t\n\n[a](docs/a.md#the-codes-section)\n")
    (tmp_path / "docs" / "a.md").write_text(
        "# A\n\n## The `[CODES]` section\n\n## The `[CODES]` section\n\n"
        "[again](#the-codes-section-1) [top](../README.md#t)\n\n"
        "    [in code](nowhere.md)\n\n```\n[fenced](nowhere.md)\n```\n"
        "`[inline](nowhere.md)` [web](https://example.com/x.md)\n")
    assert broken_links(tmp_path) == []
    with open(tmp_path / page, "a") as f:
        f.write(f"\n{link}\n")
    bad = broken_links(tmp_path)
    assert len(bad) == 1 and why in bad[0], bad


@pytest.mark.parametrize("heading,anchor", [
    ("The `[DRIVES]` section", "the-drives-section"),
    ("`--can` without CAN hardware", "--can-without-can-hardware"),
    ("Beyond the paper: `smooth` uses the whole tolerance band",
     "beyond-the-paper-smooth-uses-the-whole-tolerance-band"),
    ("From the drive's EDS to a running machine", "from-the-drives-eds-to-a-running-machine"),
    ("After a program, a stop, a fault; the next program",
     "after-a-program-a-stop-a-fault-the-next-program"),
    ("mlip-rt: the controller", "mlip-rt-the-controller"),
])
def test_slugs_as_github_makes_them(heading, anchor):
    assert slug(heading) == anchor
