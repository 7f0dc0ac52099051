"""Rich renderables for the terminal (no computing here: results come in, tables go out).

Variable names are shown 1-based (``z1``, ``w1``) as in the papers and textbooks.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Iterator
from fractions import Fraction
from typing import Any

from rich.console import Console, ConsoleOptions, Group, RenderableType
from rich.measure import Measurement
from rich.table import Column, Table
from rich.text import Text

from lcpcli.core.result import Status

STATUS_STYLE = {Status.SOLVED: "bold green", Status.NO_SOLUTION: "bold yellow",
                Status.UNSOLVED: "bold red"}

#: Above this many variables the z/w table shows the head and tail only.
MAX_ROWS = 40


def shown_name(text: str) -> str:
    """A file or problem name as a table shows it: characters that are not printable (a
    newline in a file name, a tab, an escape) written as Python escapes (``a\\nb.json``), so
    that a name never splits a row or sends a terminal control sequence."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def fmt(x: Any) -> str:
    """Compact number: 6 significant digits; an exact trace's fraction as ``p/q`` (``4/3``)."""
    if isinstance(x, Fraction):
        return str(x)
    return f"{x + 0.0:.6g}"


# ------------------------------------------------------------------------------- layout rule
def _content_ranges(table: Table, console: Console,
                    options: ConsoleOptions) -> tuple[list[int], list[int]]:
    """Per column: the narrowest width that cuts no word (its longest word) and the natural
    width (its longest line), over the header and every cell; padding excluded."""
    wide = options.update(width=10**6)
    mins, maxs = [], []
    for col in table.columns:
        lo, hi = 1, 1
        for cell in col._cells:
            m = Measurement.get(console, wide, cell)
            # a no_wrap column (a matrix drawn line by line) keeps its lines whole
            lo, hi = max(lo, m.maximum if col.no_wrap else m.minimum), max(hi, m.maximum)
        if table.show_header:
            m = Measurement.get(console, wide, col.header)  # a header may wrap at spaces
            lo, hi = max(lo, m.minimum), max(hi, m.maximum)
        mins.append(lo)
        maxs.append(hi)
    return mins, maxs


def _allocate(mins: list[int], maxs: list[int], budget: int) -> list[int] | None:
    """Column widths summing to at most ``budget``: the natural ones if they fit, else the
    widest columns narrowed one cell at a time down to their longest word; None when even
    the longest words do not fit."""
    widths = list(maxs)
    excess = sum(widths) - budget
    if excess <= 0:
        return widths
    if sum(mins) > budget:
        return None
    while excess > 0:
        j = max((k for k in range(len(widths)) if widths[k] > mins[k]),
                key=lambda k: widths[k])
        widths[j] -= 1
        excess -= 1
    return widths


def _with_columns(table: Table, picks: list[int], widths: list[int], title: str | None,
                  fold: bool) -> Table:
    """A copy of ``table`` holding the columns ``picks`` at the given content widths."""
    out = copy.copy(table)
    out.title = title
    cols: list[Column] = []
    for k, (j, w) in enumerate(zip(picks, widths, strict=True)):
        col = table.columns[j]
        cols.append(dataclasses.replace(col, width=w, min_width=None, max_width=None,
                                        _index=k, _cells=col._cells, no_wrap=False,
                                        overflow="fold" if fold else col.overflow))
    out.columns = cols
    return out


def fit_table(table: Table, console: Console,
              options: ConsoleOptions) -> list[RenderableType]:
    """The layout rule of every table on the terminal: no number or word is ever cut.

    A table that fits ``options.max_width`` is kept; otherwise its wrappable columns (text
    with spaces) are narrowed down to their longest word; if even that does not fit, the
    table is split into column blocks, as printed books do with wide tableaux: each block
    repeats the first column (the row names), a note above them says so and each block's
    title names its columns.
    Only a single word wider than the whole screen is folded (broken, never elided).  A title
    wider than its table is printed above it, wrapped at the screen's width only (rich wraps
    a title at the table's: "... (n =" over "1)").
    """
    width = options.max_width
    n = len(table.columns)
    if n == 0:
        return [table]
    mins, maxs = _content_ranges(table, console, options)
    pads = [table._get_padding_width(j) for j in range(n)]
    budget = width - table._extra_width - sum(pads)
    widths = _allocate(mins, maxs, budget)
    if widths is not None:
        fitted = table if widths == maxs else \
            _with_columns(table, list(range(n)), widths, table.title, fold=True)
        title = table.title
        if isinstance(title, str) and len(title) > sum(widths) + table._extra_width + sum(pads):
            untitled = copy.copy(fitted)
            untitled.title = None
            return [Text(title, style="table.title", justify=table.title_justify), untitled]
        return [fitted]
    edge = 2 if table.box and table.show_edge else 0
    sep = 1 if table.box else 0
    pad = max(pads) if pads else 0
    if not table.show_header or n < 3:  # nothing to repeat: narrow to the screen, fold
        return [_with_columns(table, list(range(n)),
                              _squeeze(mins, max(n, budget)), table.title, fold=True)]
    blocks: list[list[int]] = []
    used = edge + mins[0] + pad
    current: list[int] = []
    for j in range(1, n):
        need = sep + mins[j] + pad
        if current and used + need > width:
            blocks.append(current)
            current, used = [], edge + mins[0] + pad
        current.append(j)
        used += need
    blocks.append(current)
    names = [str(c.header) for c in table.columns]
    note = (f"{table.title}: " if table.title else "") + (
        f"{n - 1} columns in {len(blocks)} blocks to fit {width} columns (each block repeats "
        f"the column {names[0]})")
    out: list[RenderableType] = [Text(note, style="italic")]
    for block in blocks:
        picks = [0, *block]
        inner = width - edge - sep * (len(picks) - 1) - pad * len(picks)
        ws = _allocate([mins[j] for j in picks], [maxs[j] for j in picks], inner)
        if ws is None:
            ws = _squeeze([mins[j] for j in picks], max(len(picks), inner))
        label = (f"columns {names[block[0]]} to {names[block[-1]]}" if len(block) > 1
                 else f"column {names[block[0]]}")
        out.append(_with_columns(table, picks, ws, label, fold=True))
    return out


def _squeeze(mins: list[int], budget: int) -> list[int]:
    """Last resort (a single word wider than the screen): widths cut down to ``budget``."""
    widths = list(mins)
    while sum(widths) > budget and max(widths) > 1:
        j = widths.index(max(widths))
        widths[j] -= 1
    return widths


class Fitted:
    """A rich table laid out by :func:`fit_table` at whatever width it is rendered."""

    def __init__(self, table: Table) -> None:
        self.table = table

    def __rich_console__(self, console: Console,
                         options: ConsoleOptions) -> Iterator[RenderableType]:
        parts = fit_table(self.table, console, options)
        for k, part in enumerate(parts):
            if k > 1:
                yield Text("")
            yield part

    def __rich_measure__(self, console: Console, options: ConsoleOptions) -> Measurement:
        return Measurement.get(console, options, self.table)


def fit(table: Table) -> Fitted:
    """``table`` under the layout rule (:func:`fit_table`)."""
    return Fitted(table)


def render_result(result: Any, problem: Any, file: str | None = None,
                  forward: Any = None) -> Group:
    """Verdict, certificate and the solution table of a :class:`~lcpcli.core.result.Result`
    (``forward``: a :class:`~lcpcli.analysis.bounds.ForwardBound`, when one was computed)."""
    head = Table.grid(padding=(0, 2))
    head.add_column(style="bold")
    head.add_column()
    # user text (file names, messages) is never read as rich markup
    head.add_row("problem", Text(shown_name(f"{file or ''}"
                                            f"{' : ' + problem.name if problem.name else ''}")))
    head.add_row("size", problem.summary())
    head.add_row("method", result.method)
    head.add_row("status", Text(result.status, style=STATUS_STYLE.get(result.status, "")))
    head.add_row("message", Text(result.message))
    cert = result.certificate
    head.add_row("pivots/iterations", str(result.iterations))
    head.add_row("time", f"{result.seconds * 1e3:.3f} ms (method only)")
    natural = "||min(z, w)||_inf" if problem.kind == "lcp" else "||mid(z-l, z-u, w)||_inf"
    head.add_row("residual", f"{cert.residual:.3e}  {natural}")
    head.add_row("error", f"{cert.error:.3e}  componentwise (tol {cert.tol:.1e}): backward error "
                          f"{cert.backward_error:.2e} x growth {cert.growth:.3g}")
    if forward is not None and math.isfinite(forward.bound):
        relative = (f"relative {forward.relative:.2e}" if math.isfinite(forward.relative)
                    else "relative: n/a (z = 0)")
        head.add_row("forward error", f"||z - z*||_inf <= {forward.bound:.2e} "
                                      f"({relative}; {forward.how})")
    if problem.kind != "lcp":
        head.add_row("bounds / equalities",
                     f"bound violation {cert.bound_violation:.2e}, "
                     f"equality residual {cert.equality_residual:.2e}")
    if result.status == Status.NO_SOLUTION:  # no table of values that are not a solution
        return Group(fit(head), Text(""), Text.assemble(
            ("no solution", STATUS_STYLE[Status.NO_SOLUTION]),
            f" (n = {problem.n}): " + ("no z >= 0 gives w = Mz + q >= 0 with z^T w = 0; "
                                       if problem.kind == "lcp" else "") +
            "the message above says how that was proved"))
    title = None if result.solved else "last point, not a solution (the certificate fails)"
    return Group(fit(head), Text(""), fit(solution_table(result.z, result.w, title)))


def solution_table(z: Any, w: Any, title: str | None = None) -> Table:
    """``i, z_i, w_i, z_i w_i`` rows (head and tail only for large n)."""
    n = len(z)
    table = Table(title=f"{title or 'solution'} (n = {n})", title_justify="left")
    for name in ("i", "z", "w = Mz + q", "z*w"):
        table.add_column(name, justify="right")
    rows = list(range(n))
    if n > MAX_ROWS:
        rows = rows[: MAX_ROWS // 2] + [-1] + rows[-MAX_ROWS // 2:]
    for i in rows:
        if i < 0:
            table.add_row("...", f"({n - MAX_ROWS} rows not shown: use --json)", "", "")
            continue
        # Python floats: a product past the float64 range is inf (or nan), with no warning
        table.add_row(str(i + 1), fmt(z[i]), fmt(w[i]), fmt(float(z[i]) * float(w[i])))
    return table


def render_methods(registry: dict[str, Any]) -> Fitted:
    """The solver registry as a table."""
    table = Table(title="solver methods", title_justify="left")
    for name in ("method", "problems", "matrix classes", "options"):
        table.add_column(name)
    for name, m in registry.items():
        label = name + (f" ({', '.join(m.aliases)})" if m.aliases else "")
        kinds = "/".join(k.upper() for k in m.kinds)
        if m.batch is not None:  # stacks of problems: one compiled call (lcpcli.solve_many)
            kinds += f"; stacks: batched ({'/'.join(k.upper() for k in m.batch.kinds)})"
        table.add_row(label, kinds, m.matrix_classes, ", ".join(m.options) or "-")
    return fit(table)
