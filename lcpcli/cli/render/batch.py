"""Rich renderables for batch runs: the progress bar (stderr) and the summary tables."""

from __future__ import annotations

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
from lcpcli.core.result import Status

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
    from pathlib import Path

    return source if Path(source).stem == problem else f"{source} : {problem}"


def render_summary(report: Any) -> Group:
    """Counts by status, the slowest problems, the worst certificates and the first errors."""
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
    if summary["slowest"]:
        slow = Table(title="slowest problems (method time)", title_justify="left")
        slow.add_column("problem")
        slow.add_column("seconds", justify="right")
        for item in summary["slowest"]:
            slow.add_row(_where(item["source"], item["problem"]), f"{item['seconds']:.3g}")
        parts.append(slow)
    if summary["worst"]:
        worst = Table(title="worst certificates (scaled error)", title_justify="left")
        worst.add_column("problem")
        worst.add_column("error", justify="right")
        for item in summary["worst"]:
            e = item["error"]
            worst.add_row(_where(item["source"], item["problem"]),
                          "inf/nan" if e is None else f"{e:.3e}")
        parts.append(worst)
    if summary["errors"]:
        errs = Table(title="bad inputs (first few)", title_justify="left")
        errs.add_column("message")
        for item in summary["errors"]:
            errs.add_row(item["message"])
        parts.append(errs)
    wall = report.wall_seconds
    rate = report.new / wall if wall > 0 else 0.0
    line = f"{report.new} problems done in this run in {wall:.2f} s ({rate:,.0f} problems/s)"
    if report.skipped:
        line += f"; {report.skipped} already in the output (--resume)"
    if report.output:
        line += f"; results in {report.output}"
    parts.append(Text(line))
    return Group(*parts)
