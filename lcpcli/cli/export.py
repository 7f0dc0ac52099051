"""Where teaching output goes: the terminal (one step or all, ``--step``), Markdown or LaTeX
on stdout or in a file (``-o``, written atomically, never over an input file)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from lcpcli.core.errors import OptionError

if TYPE_CHECKING:
    from lcpcli.cli.render.doc import Page



def check_format(fmt: str) -> str:
    """``text``, ``markdown`` (``md``) or ``latex`` (``tex``)."""
    value = {"md": "markdown", "tex": "latex"}.get(str(fmt).lower(), str(fmt).lower())
    if value == "text":  # the default: no renderer to load
        return value
    from lcpcli.cli.render.doc import FORMATS  # the renderer knows what it can write

    if value not in FORMATS:
        raise OptionError(f"--format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    return value


def check_target(output: str | Path, inputs: list[str]) -> None:
    """Refuse to write the export over an input, a device, a link or a directory
    (:func:`lcpcli.io.check_output`, the one definition of what an output may be)."""
    from lcpcli.io import check_output  # io (numpy) only when an export file is named

    check_output(output, inputs=[name for name in inputs if name and name != "-"],
                 stdout=False)


def emit(pages: list[Page], *, fmt: str, output: str | Path | None, inputs: list[str],
         pivot: int | None, numbers: list[int], labels: list[str], step: bool, what: str,
         console: Any, title: str = "") -> bool:
    """Show or write ``pages``; return True when the export went to stdout.

    ``numbers`` are the step numbers of the pages (``--pivot K`` picks number K), ``labels``
    their names on the step screen.
    """
    # the renderer and the stepper only here: a plain solve never loads them (start-up budget)
    from lcpcli.cli.render.doc import to_rich, write
    from lcpcli.cli.stepper import interactive, pick, print_all, step_through

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


def check_export_options(fmt: str, output: str | Path | None, inputs: list[str],
                         as_json: bool) -> None:
    """Before any work: an export and ``--json`` cannot share stdout; ``-o`` is no input."""
    if fmt != "text":
        if as_json and output is None:
            raise OptionError(f"--json and --format {fmt} both write to stdout; send the "
                              f"export to a file with -o FILE")
        if output is not None:
            check_target(output, inputs)


#: The help of ``--exact/--no-exact`` (solve --trace, pivot, enumerate).
EXACT_HELP = ("Fractions (4/3) instead of decimals: the steps computed in exact rational "
              "arithmetic [default: on when n <= 8 and every entry is a fraction with a "
              "denominator and magnitude up to 1000]. The verdict and certificate still come "
              "from the floating-point solve; --json keeps floats.")


def note(text: str) -> None:
    """A one-line note on stderr."""
    sys.stderr.write(f"lcpcli: {text}\n")


def exact_view(problem: Any, method: str, flag: bool | None, opts: dict[str, Any],
               trace: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The trace to show: ``trace`` recomputed in fractions when ``--exact`` asks for it (or
    by default on small rational data), else ``trace`` itself.  A note on stderr when
    ``--exact`` cannot be honoured, or when the exact run pivots differently."""
    from lcpcli.solvers.trace.exact import EXACT_METHODS, exact_trace, same_pivots, wants_exact

    if flag is False:
        return trace
    if method not in EXACT_METHODS:
        if flag:
            note(f"--exact: {method} iterates (sweeps), its trace stays in decimals (exact "
                 f"traces: {', '.join(EXACT_METHODS)})")
        return trace
    data = wants_exact(problem, flag)
    if data is None:
        if flag:
            note("--exact: the data are not fractions with small denominators; the trace "
                 "stays in decimals")
        return trace
    try:
        exact = exact_trace(problem, method, data, covering=opts.get("covering"),
                            max_iter=opts.get("max_iter"), z0=opts.get("z0"))
    except (ValueError, ZeroDivisionError) as exc:
        if flag:
            note(f"--exact: {exc}; the trace stays in decimals")
        return trace
    if not same_pivots(trace, exact):
        note("--exact: in exact arithmetic the method pivots differently from its "
             "floating-point run (ties decided by rounding); the exact steps are shown, the "
             "answer is the floating-point run's")
    return exact


def exact_cones(problem: Any, flag: bool | None, res: Any, M: Any) -> tuple[Any, Any]:
    """``enumerate``'s tables in fractions (``--exact``, or by default on small rational
    data): the enumeration with exact ``det A_r``, ``y``, ``z``, ``w``, and ``M`` as
    fractions; ``(res, M)`` unchanged otherwise (with a note when ``--exact`` was asked)."""
    from lcpcli.solvers.trace.exact import exact_enumeration, wants_exact

    data = wants_exact(problem, flag)
    if data is None:
        if flag:
            note("--exact: the data are not fractions with small denominators; the tables "
                 "stay in decimals")
        return res, M
    return exact_enumeration(res, data), data.M

