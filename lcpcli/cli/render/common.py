"""Rich renderables for the terminal (no computing here: results come in, tables go out).

Variable names are shown 1-based (``z1``, ``w1``) as in the seeds and textbooks.
"""

from __future__ import annotations

import math
from typing import Any

from rich.console import Group
from rich.table import Table
from rich.text import Text

from lcpcli.core.result import Status

STATUS_STYLE = {Status.SOLVED: "bold green", Status.NO_SOLUTION: "bold yellow",
                Status.UNSOLVED: "bold red"}

#: Above this many variables the z/w table shows the head and tail only.
MAX_ROWS = 40


def fmt(x: float) -> str:
    """Compact number: 6 significant digits."""
    return f"{x + 0.0:.6g}"


def render_result(result: Any, problem: Any, file: str | None = None,
                  forward: Any = None) -> Group:
    """Verdict, certificate and the solution table of a :class:`~lcpcli.core.result.Result`
    (``forward``: a :class:`~lcpcli.analysis.bounds.ForwardBound`, when one was computed)."""
    head = Table.grid(padding=(0, 2))
    head.add_column(style="bold")
    head.add_column()
    # user text (file names, messages) is never read as rich markup
    head.add_row("problem", Text(f"{file or ''}{' : ' + problem.name if problem.name else ''}"))
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
    return Group(head, Text(""), solution_table(result.z, result.w))


def solution_table(z: Any, w: Any) -> Table:
    """``i, z_i, w_i, z_i w_i`` rows (head and tail only for large n)."""
    n = len(z)
    table = Table(title=f"solution (n = {n})", title_justify="left")
    for name in ("i", "z", "w = Mz + q", "z*w"):
        table.add_column(name, justify="right")
    rows = list(range(n))
    if n > MAX_ROWS:
        rows = rows[: MAX_ROWS // 2] + [-1] + rows[-MAX_ROWS // 2:]
    for i in rows:
        if i < 0:
            table.add_row("...", f"({n - MAX_ROWS} rows not shown: use --json)", "", "")
            continue
        table.add_row(str(i + 1), fmt(z[i]), fmt(w[i]), fmt(z[i] * w[i]))
    return table


def render_methods(registry: dict[str, Any]) -> Table:
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
    return table
