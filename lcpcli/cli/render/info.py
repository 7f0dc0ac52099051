"""Rich rendering of ``lcpcli info``: the class report and the methods that apply."""

from __future__ import annotations

from typing import Any

from rich.console import Group
from rich.padding import Padding
from rich.table import Table
from rich.text import Text

from lcpcli.cli.render.common import fit

APPLIES_STYLE = {"yes": "bold green", "maybe": "yellow", "no": "red"}

#: Class-report keys shown, with their labels.
FIELDS = [
    ("kind", "problem kind"), ("n", "n"), ("n_eq", "equality rows (MLCP)"),
    ("sparse", "sparse storage"), ("nnz", "nonzeros"), ("density", "density"),
    ("q_nonnegative", "q >= 0 (z = 0 solves)"), ("symmetric", "symmetric"),
    ("definiteness", "definiteness of (M + M^T)/2"),
    ("definiteness_test", "definiteness test"), ("factor_fill", "sparse LU fill ratio"),
    ("positive_diagonal", "positive diagonal"),
    ("zero_diagonal", "zero diagonal entries"), ("z_matrix", "Z-matrix (off-diagonal <= 0)"),
    ("nonnegative", "nonnegative matrix"),
    ("diagonally_dominant", "strictly diagonally dominant"),
    ("h_matrix_positive_diagonal", "H-matrix with positive diagonal"),
    ("p_matrix", "P-matrix"), ("p_matrix_reason", "P-matrix test"),
]


def _fmt(v: Any) -> str:
    if v is None:
        return "not tested"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def render_info(report: dict[str, Any]) -> Group:
    """The classification grid and the method table of an ``info`` report."""
    head = Table.grid(padding=(0, 2))
    head.add_column(style="bold")
    head.add_column()
    head.add_row("file", Text(str(report.get("file") or "")))  # a name, never markup
    head.add_row("problem", report["summary"])
    head.add_row("regime", report["regime"])
    c = report["classification"]
    for key, label in FIELDS:
        if key in c and not (key == "n_eq" and not c[key]):
            head.add_row(label, _fmt(c[key]))
    table = Table(title="methods", title_justify="left")
    for col in ("method", "applies", "why", "auto order"):
        table.add_column(col)
    for row in report["methods"]:
        table.add_row(row["method"], Text(row["applies"], style=APPLIES_STYLE[row["applies"]]),
                      row["why"], str(row["auto_rank"] or "-"))
    first = report.get("auto_first")
    plan = report["auto_plan"]
    parts = [fit(head), Text(""), fit(table), Text("")]
    if first:
        parts.append(Text(f"auto's first attempt (before the O(n^3) tests): {first[0]}: "
                          f"{first[1]}"))
    parts.append(Text("auto would try:" + ("" if plan else " nothing")))
    if plan:  # numbered, each entry's wrapped lines under its own text
        steps = Table.grid(padding=(0, 1))
        steps.add_column(justify="right")
        steps.add_column()
        for i, (name, why) in enumerate(plan):
            steps.add_row(f"{i + 1}.", f"{name}: {why}")
        parts.append(Padding(fit(steps), (0, 0, 0, 2), expand=False))
    return Group(*parts)
