"""Rich renderables for batch runs: the progress bar (stderr) and the summary tables."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rich.console import Group
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    TextColumn,
    TimeRemainingColumn,
)
from rich.table import Table
from rich.text import Text

from lcpcli.cli.render.common import STATUS_STYLE as COMMON_STATUS_STYLE
from lcpcli.cli.render.common import shown_name
from lcpcli.core.result import Status
from lcpcli.core.text import plural

STATUS_STYLE = {**COMMON_STATUS_STYLE, Status.ERROR: "bold magenta"}


class RateColumn(ProgressColumn):
    """Problems per second."""

    def render(self, task: Any) -> Text:
        speed = task.finished_speed or task.speed
        return Text("-- /s" if speed is None else f"{speed:,.0f} /s", style="cyan")


def make_progress(console: Any) -> Progress:
    """Done/total, counts by outcome, rate and ETA (shown on stderr, on a terminal only)."""
    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TextColumn("{task.fields[counts]}"), RateColumn(), TextColumn("ETA"),
                    TimeRemainingColumn(), console=console, transient=False)


def _where(source: str, problem: str) -> str:
    """The file, and the problem's name when it is not the file's stem (:func:`shown_name`)."""
    return shown_name(source if Path(source).stem == problem else f"{source} : {problem}")


def problems_table(rows: list[dict[str, Any]]) -> Table:
    """One line per problem of a small batch: where, status, n, iterations, error, and for a
    problem not solved the reason (``--json`` has every field)."""
    table = Table(title="problems", title_justify="left")
    table.add_column("problem", overflow="fold", ratio=1)
    table.add_column("status", no_wrap=True)
    table.add_column("n", justify="right", no_wrap=True)
    table.add_column("iterations", justify="right", no_wrap=True)
    table.add_column("error", justify="right", no_wrap=True)
    table.add_column("why not solved", overflow="fold", ratio=2)
    for row in sorted(rows, key=lambda r: (str(r.get("source")), str(r.get("problem")))):
        status = str(row.get("status") or "")
        err = row.get("error")
        table.add_row(Text(_where(str(row.get("source") or ""), str(row.get("problem") or ""))),
                      Text(status, style=STATUS_STYLE.get(status, "")),
                      "" if row.get("n") is None else str(row["n"]),
                      "" if row.get("n") is None else str(row.get("iterations")),
                      "" if err is None else f"{err:.1e}",
                      Text("" if status == Status.SOLVED else str(row.get("message") or "")))
    return table


def render_summary(report: Any, rows: list[dict[str, Any]] | None = None) -> Group:
    """Counts by status, the slowest problems, the worst certificates and the first errors.

    ``rows`` (a small batch): one table line per problem instead of the extremes.
    """
    summary = report.tally.as_dict()
    total = max(1, summary["total"])
    counts = Table(title="batch summary", title_justify="left")
    counts.add_column("status")
    counts.add_column("problems", justify="right")
    counts.add_column("share", justify="right")
    for status, count in sorted(summary["counts"].items(), key=lambda kv: -kv[1]):
        counts.add_row(Text(status, style=STATUS_STYLE.get(status, "")), str(count),
                       f"{100 * count / total:.1f} %")
    counts.add_row("total", str(summary["total"]), "")
    parts: list[Any] = [counts]
    if rows:
        parts.append(problems_table(rows))
    if summary["slowest"] and not rows:
        slow = Table(title="slowest problems (method time)", title_justify="left")
        slow.add_column("problem")
        slow.add_column("seconds", justify="right")
        for item in summary["slowest"]:
            slow.add_row(_where(item["source"], item["problem"]), f"{item['seconds']:.3g}")
        parts.append(slow)
    if summary["worst"] and not rows:
        worst = Table(title="worst certificates (certified error)", title_justify="left")
        worst.add_column("problem")
        worst.add_column("error", justify="right")
        for item in summary["worst"]:
            e = item["error"]
            worst.add_row(_where(item["source"], item["problem"]),
                          "inf/nan" if e is None else f"{e:.3e}")
        parts.append(worst)
    if summary["errors"] and not rows:
        errs = Table(title="bad inputs (first few)", title_justify="left")
        errs.add_column("message")
        for item in summary["errors"]:
            errs.add_row(Text(item["message"]))
        parts.append(errs)
    wall = report.wall_seconds
    rate = report.new / wall if wall > 0 else 0.0
    line = (f"{plural(report.new, 'problem')} done in this run in {wall:.2f} s "
            f"({plural(round(rate), 'problem')}/s)")
    if report.skipped:
        line += f"; {report.skipped:,} already in the output (--resume)"
    if report.output:
        line += f"; results in {report.output}"
    parts.append(Text(line))
    return Group(*parts)
