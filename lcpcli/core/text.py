"""Wording shared by every layer (messages of solvers, batch summaries, CLI lines)."""

from __future__ import annotations


def plural(count: int, word: str, many: str | None = None) -> str:
    """``"1 pivot"``, ``"2 pivots"``, ``"1,000 problems"`` (``many`` for irregular plurals)."""
    return f"{count:,} {word if count == 1 else (many or word + 's')}"
