"""Wording shared by every layer (messages of solvers, batch summaries, CLI lines)."""

from __future__ import annotations

import sys
import warnings


def plural(count: int, word: str, many: str | None = None) -> str:
    """``"1 pivot"``, ``"2 pivots"``, ``"1,000 problems"`` (``many`` for irregular plurals)."""
    if count == 1:
        return "1 " + word
    # the thousands separator only where there are thousands (formatting it costs a third of a
    # microsecond, on the small-solve path)
    return f"{count if -1000 < count < 1000 else format(count, ',')} {many or word + 's'}"


def option_name(key: str) -> str:
    """The registered spelling of a method option's name: hyphens as underscores, so that
    ``-O max-iter=50`` and ``max_iter=50`` name the same option (the one normalisation of the
    registry, the command line and ``solve_many``)."""
    return key.replace("-", "_")


def show_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                 file: object = None, line: str | None = None) -> None:
    """Warnings as one ``lcpcli: warning:`` line on stderr (no source path, no code line); a
    category with a ``label`` (:class:`lcpcli.core.limits.CostNote`: ``note``) names itself."""
    text = " ".join(str(message).split())
    sys.stderr.write(f"lcpcli: {getattr(category, 'label', 'warning')}: {text}\n")


def one_line_warnings() -> None:
    """Print every Python warning of this process as one ``lcpcli: warning:`` line (the CLI
    and the batch worker processes call it at start)."""
    warnings.showwarning = show_warning
