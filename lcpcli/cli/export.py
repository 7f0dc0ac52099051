"""Where teaching output goes: the terminal (one step or all, ``--step``), Markdown or LaTeX
on stdout or in a file (``-o``, written atomically, never over an input file)."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

from lcpcli.cli.render.doc import FORMATS, Page, to_rich, write
from lcpcli.cli.stepper import interactive, pick, print_all, step_through
from lcpcli.core.errors import OptionError


def check_format(fmt: str) -> str:
    """``text``, ``markdown`` (``md``) or ``latex`` (``tex``)."""
    value = {"md": "markdown", "tex": "latex"}.get(str(fmt).lower(), str(fmt).lower())
    if value not in FORMATS:
        raise OptionError(f"--format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    return value


def check_target(output: Path, inputs: list[str]) -> None:
    """Refuse to write the export over one of the input files."""
    for name in inputs:
        if name == "-" or not name:
            continue
        src = Path(name)
        same = False
        try:
            same = output.exists() and src.exists() and os.path.samefile(output, src)
        except OSError:
            same = False
        if same or output.resolve() == src.resolve():
            raise OptionError(f"-o {output}: that is the input file; choose another name")


def emit(pages: list[Page], *, fmt: str, output: Path | None, inputs: list[str],
         pivot: int | None, numbers: list[int], labels: list[str], step: bool, what: str,
         console: Any, title: str = "") -> bool:
    """Show or write ``pages``; return True when the export went to stdout.

    ``numbers`` are the step numbers of the pages (``--pivot K`` picks number K), ``labels``
    their names on the step screen.
    """
    if pivot is not None:
        pages = pick(pages, pivot, numbers, what)
    if fmt == "text":
        if step and pivot is None:
            if interactive():
                step_through(console, pages, labels)
            else:
                print_all(console, pages)
        else:
            console.print(to_rich(pages))
        return False
    if step:
        raise OptionError(f"--step pages through the steps on a terminal; it does not combine "
                          f"with --format {fmt} (use --pivot K for one step)")
    text = write(pages, fmt, title)
    if output is None:
        sys.stdout.write(text)
        sys.stdout.flush()
        return True
    from lcpcli.io import write_atomic_text

    write_atomic_text(output, text)
    return False


def check_export_options(fmt: str, output: Path | None, inputs: list[str],
                         as_json: bool) -> None:
    """Before any work: an export and ``--json`` cannot share stdout; ``-o`` is no input."""
    if fmt != "text":
        if as_json and output is None:
            raise OptionError(f"--json and --format {fmt} both write to stdout; send the "
                              f"export to a file with -o FILE")
        if output is not None:
            check_target(output, inputs)
