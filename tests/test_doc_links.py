"""The relative links of README.md and docs/*.md lead somewhere: the file exists and, for a
``#fragment`` into a Markdown file, a heading there has that slug (GitHub's rule: lower case,
punctuation other than ``-`` and ``_`` dropped, spaces to hyphens, ``-1``, ``-2`` for repeats)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _prose(text: str) -> str:
    """``text`` without fenced blocks and inline code (``N_[l,u](lambda)`` is no link)."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.M | re.S)
    return re.sub(r"`[^`\n]*`", "", text)


def slug(heading: str) -> str:
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(page: Path) -> set[str]:
    seen: dict[str, int] = {}
    found = set()
    for heading in re.findall(r"^#+\s+(.*)$", re.sub(r"^```.*?^```", "", page.read_text(),
                                                        flags=re.M | re.S), re.M):
        s = slug(heading)
        count = seen.get(s, 0)
        seen[s] = count + 1
        found.add(s if count == 0 else f"{s}-{count}")
    return found


def test_slug_follows_github():
    heading = "Start-up (`python benchmarks/bench_startup.py --first-run`)"
    assert slug(heading) == "start-up-python-benchmarksbench_startuppy---first-run"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_resolve(page):
    bad = []
    for target in re.findall(r"\]\(([^)\s]+)\)", _prose(page.read_text())):
        if re.match(r"[a-z]+:", target):
            continue
        path, _, fragment = target.partition("#")
        file = (page.parent / path) if path else page
        if not file.exists():
            bad.append(f"{target}: no such file")
        elif fragment and file.suffix == ".md" and fragment not in anchors(file):
            bad.append(f"{target}: no heading with this slug")
    assert not bad, bad
