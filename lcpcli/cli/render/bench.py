"""Rendering of ``lcpcli bench`` results: rich tables, a Markdown report and the PNG plot.

No computing here beyond formatting: the figures come from :mod:`lcpcli.bench.runner`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from rich.console import Group
from rich.table import Table
from rich.text import Text

from lcpcli.bench.runner import (
    PENALTY,
    SHIFT,
    BenchReport,
    MethodSummary,
    peer_ratios,
    performance_profile,
    summarize,
    work_precision,
)
from lcpcli.core.result import Status

#: Profile values shown in the terminal table.
PROFILE_TAUS = (1.0, 2.0, 4.0, 10.0, 100.0)


def ms(seconds: float | None) -> str:
    """Seconds as milliseconds, 3 significant digits ('-' for none)."""
    if seconds is None or not math.isfinite(seconds):
        return "-"
    return f"{seconds * 1e3:.3g}"


def sci(x: float | None) -> str:
    if x is None or not math.isfinite(x):
        return "-"
    return f"{x:.1e}"


def mark(r: Any) -> str:
    """Short verdict: ok (right outcome), fail (unsolved), wrong (a verdict that is not the
    expected one, e.g. a huge-z 'solution' of an infeasible problem), error, DEFECT."""
    if r.defect:
        return "DEFECT"
    if r.success:
        return "ok"
    return {Status.SOLVED: "wrong", Status.NO_SOLUTION: "wrong", Status.UNSOLVED: "fail",
            Status.ERROR: "error"}.get(r.status, r.status)


def header(report: BenchReport, title: str) -> Table:
    grid = Table.grid(padding=(0, 2))
    grid.add_column(style="bold")
    grid.add_column()
    kinds = sorted({k for _, _, k, _ in report.problems})
    grid.add_row("benchmark", title)
    grid.add_row("problems", f"{len(report.problems)} ({', '.join(k.upper() for k in kinds)})")
    grid.add_row("methods", ", ".join(report.methods))
    peers = ", ".join(f"{k} {v}" for k, v in report.peers.items()) or "none"
    grid.add_row("peers", peers)
    for fam, why in report.missing_peers.items():
        grid.add_row("peer not used", f"{fam}: {why}")
    grid.add_row("tolerances", ", ".join(f"{t:g}" for t in report.tols))
    grid.add_row("timing", "median of repeats after one untimed warm-up; our methods' time "
                           "includes the certificate of the answer, a peer's is its solver "
                           "call alone (no loading, no JIT for either)")
    return grid


#: Width assumed when none is given (rich's own default off a terminal).
DEFAULT_WIDTH = 80
Cell = str | Text


def _plain(cell: Cell) -> str:
    return cell.plain if isinstance(cell, Text) else str(cell)


def fit_tables(title: str, keys: list[tuple[str, str]], columns: list[tuple[str, str]],
               rows: list[list[Cell]], width: int | None, **table_args: Any) -> list[Table]:
    """``rows`` as one table, or as several that each fit ``width`` (narrow terminals).

    ``keys`` (name, justify) start every table (e.g. the method); the other ``columns`` are
    dealt out so that no number or name is cut: a table holds as many whole columns as fit,
    the next table the rest (titled "1/2", "2/2").  A column wider than the terminal alone
    is folded onto several lines, never truncated with an ellipsis.
    """
    width = width or DEFAULT_WIDTH
    nk = len(keys)

    def col_width(i: int, name: str) -> int:
        return max([len(name), *(len(_plain(r[i])) for r in rows)]) + 3  # padding and rule

    key_w = 1 + sum(col_width(i, name) for i, (name, _) in enumerate(keys))
    groups: list[list[int]] = []
    used = key_w
    for j, (name, _) in enumerate(columns):
        w = col_width(nk + j, name)
        if groups and groups[-1] and used + w <= width:
            groups[-1].append(j)
            used += w
        else:
            groups.append([j])
            used = key_w + w
    groups = groups or [[]]
    tables = []
    for g, group in enumerate(groups):
        part = f" ({g + 1}/{len(groups)})" if len(groups) > 1 else ""
        table = Table(title=title + part, title_justify="left", **table_args)
        for name, just in keys + [columns[j] for j in group]:
            table.add_column(name, justify=just, overflow="fold")  # type: ignore[arg-type]
        for r in rows:
            table.add_row(*r[:nk], *(r[nk + j] for j in group))
        tables.append(table)
    return tables


def summary_table(rows: list[MethodSummary], width: int | None = None) -> list[Table]:
    title = (f"per method (shifted geometric mean: shift {SHIFT * 1e3:g} ms, a failure "
             f"counts {PENALTY:g}x the slowest time on its problem)")
    columns = [(name, "right") for name in ("tol", "success", "sgm ms", "median ms",
                                            "median error", "worst error", "median fwd",
                                            "worst fwd", "defects")]
    cells: list[list[Cell]] = []
    for s in rows:
        name = s.method + (" (peer)" if s.peer else "")
        defects = Text(str(s.defects), style="bold red" if s.defects else "")
        cells.append([name, f"{s.tol:g}", f"{s.successes}/{s.runs}", ms(s.sgm_seconds),
                      ms(s.median_seconds), sci(s.median_error), sci(s.worst_error),
                      sci(s.median_z_error), sci(s.worst_z_error), defects])
    return fit_tables(title, [("method", "left")], columns, cells, width)


def problem_table(report: BenchReport, tol: float | None = None,
                  width: int | None = None) -> list[Table]:
    """Per problem: for each method, time (ms), error and verdict at ``tol``."""
    tol = report.tols[0] if tol is None else tol
    methods = report.all_methods()
    by = {(r.problem, r.method): r for r in report.records if r.tol == tol}
    cells: list[list[Cell]] = []
    for name, n, _kind, expected in report.problems:
        row: list[Cell] = [name, str(n), expected]
        for m in methods:
            r = by.get((name, m))
            if r is None:
                row.append(Text("n/a", style="dim"))
                continue
            style = "bold red" if r.defect else ("green" if r.success else "yellow")
            row.append(Text(f"{ms(r.seconds)} {sci(r.error)} {mark(r)}", style=style))
        cells.append(row)
    return fit_tables(f"per problem at tol {tol:g}: time ms, error, verdict",
                      [("problem", "left"), ("n", "right"), ("expected", "left")],
                      [(m, "right") for m in methods], cells, width)


def tolerance_table(rows: list[MethodSummary], width: int | None = None) -> list[Table]:
    """Time to reach each tolerance: success count and median time of successes per tol."""
    tols = sorted({s.tol for s in rows}, reverse=True)
    cells: list[list[Cell]] = []
    for m in dict.fromkeys(s.method for s in rows):
        row: list[Cell] = [m]
        for t in tols:
            s = next((x for x in rows if x.method == m and x.tol == t), None)
            row.append("-" if s is None else f"{s.successes}/{s.runs}, {ms(s.median_seconds)}")
        cells.append(row)
    return fit_tables("time to reach each tolerance (successes, median ms of successes)",
                      [("method", "left")], [(f"tol {t:g}", "right") for t in tols], cells,
                      width)


def peer_table(report: BenchReport, width: int | None = None) -> list[Table]:
    ratios = peer_ratios(report)
    if not ratios:
        return []
    claims: dict[str, int] = {}
    for r in report.records:
        if r.peer and r.tol == report.tols[0] and r.claimed and r.status != Status.SOLVED:
            claims[r.method] = claims.get(r.method, 0) + 1
    cells: list[list[Cell]] = [
        [d["method"], d["peer"], str(d["problems"]), f"{d['geomean_ratio']:.3g}",
         f"{d['min_ratio']:.3g}", f"{d['max_ratio']:.3g}", str(claims.get(d["peer"], 0))]
        for d in ratios]
    return fit_tables("peer ratios: time(ours) / time(peer), geometric mean over problems both "
                      "solved (< 1: ours faster)", [("method", "left"), ("peer", "left")],
                      [(name, "right") for name in ("problems", "geomean ratio", "min", "max",
                                                    "peer claims failing our certificate")],
                      cells, width)


def profile_table(report: BenchReport, width: int | None = None) -> list[Table]:
    prof = performance_profile(report)
    cells: list[list[Cell]] = []
    for m, ratios in prof["ratios"].items():
        vals = list(ratios)
        cnt = len(vals) or 1
        row: list[Cell] = [m]
        row += [f"{sum(1 for x in vals if x is not None and x <= tau) / cnt:.2f}"
                for tau in PROFILE_TAUS]
        row.append(f"{sum(1 for x in vals if x is not None) / cnt:.2f}")
        cells.append(row)
    return fit_tables(f"performance profile (Dolan-More) at tol {prof['tol']:g} over "
                      f"{len(prof['problems'])} problems: fraction solved within tau x the "
                      "best time", [("method", "left")],
                      [(f"tau={tau:g}", "right") for tau in PROFILE_TAUS] + [("ever", "right")],
                      cells, width)


def defect_table(report: BenchReport, width: int | None = None) -> list[Table]:
    if not report.defects:
        return []
    cells: list[list[Cell]] = [[r.problem, r.method, f"{r.tol:g}", r.status, r.defect_reason]
                               for r in report.defects]
    return fit_tables("DEFECTS (a method claimed something false)",
                      [("problem", "left"), ("method", "left")],
                      [("tol", "left"), ("status", "left"), ("why", "left")], cells, width,
                      style="red")


def render_report(report: BenchReport, title: str, width: int | None = None) -> Group:
    """Everything the terminal shows for a benchmark run (tables split to fit ``width``)."""
    rows = summarize(report)
    parts: list[Any] = [header(report, title), Text("")]
    sections = [summary_table(rows, width), problem_table(report, width=width)]
    if len(report.tols) > 1:
        sections.append(tolerance_table(rows, width))
    sections += [profile_table(report, width), peer_table(report, width),
                 defect_table(report, width)]
    for tables in sections:
        for table in tables:
            parts += [table, Text("")]
    if report.skipped:
        skipped = sorted({f"{m} ({why})" for _, m, why in report.skipped})
        parts += [Text(f"skipped {len(report.skipped)} (problem, method) pairs: "
                       + "; ".join(skipped), style="dim")]
    return Group(*parts)


# ---------------------------------------------------------------------- plot
def plot_available() -> bool:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def write_plot(report: BenchReport, path: Path) -> None:
    """PNG with the performance profile (left), the certified error against time (middle) and
    the forward error ``||z - z*||_inf / max(1, ||z*||_inf)`` against time where z* is known
    (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from lcpcli.io import atomic_path

    prof = performance_profile(report)
    fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(19, 4.8))
    # one colour per method or peer in all three panels (up to 20 apart); peers dashed / x
    names = report.all_methods()
    peers = {r.method for r in report.records if r.peer is not None}
    colour = {m: plt.get_cmap("tab20")(i % 20) for i, m in enumerate(names)}
    taus = prof["tau"]
    top = max(taus[-1] * 1.5, 2.0)
    for m, rho in prof["rho"].items():
        ax1.step(taus + [top], rho + [rho[-1]], where="post", label=m, color=colour[m],
                 ls="--" if m in peers else "-")
    ax1.set_xscale("log")
    ax1.set_ylim(0, 1.02)
    ax1.set_xlabel("tau (time / best time)")
    ax1.set_ylabel("fraction of problems")
    ax1.set_title(f"performance profile, tol {prof['tol']:g}, {len(prof['problems'])} problems")
    pts = work_precision(report)
    floor = 1e-18
    for key, ax in (("error", ax2), ("z_error", ax3)):
        for m in report.all_methods():
            sel = [p for p in pts if p["method"] == m and p[key] is not None
                   and (key == "error" or p["success"])]
            if sel:
                ax.scatter([p["seconds"] for p in sel], [max(p[key], floor) for p in sel],
                           s=14, alpha=0.7, label=m, color=colour[m],
                           marker="x" if m in peers else "o")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("seconds (median; ours include the certificate)")
    for t in report.tols:
        ax2.axhline(t, color="grey", lw=0.6, ls="--")
    ax2.set_ylabel(f"certified error (floored at {floor:g})")
    ax2.set_title("work-precision (all runs; dashed: tolerances)")
    known = sum(1 for p in pts if p["z_error"] is not None and p["success"])
    ax3.set_ylabel(f"forward error ||z - z*|| / max(1, ||z*||) (floored at {floor:g})")
    ax3.set_title(f"speed against forward error (z* known: {known} solved runs)")
    handles = {h.get_label(): h for ax in (ax3, ax2, ax1)
               for h in ax.get_legend_handles_labels()[0]}
    fig.legend([handles[m] for m in names if m in handles],
               [m for m in names if m in handles], fontsize=8, loc="center right")
    fig.tight_layout(rect=(0, 0, 0.89, 1))
    with atomic_path(Path(path)) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------- markdown
def markdown_report(report: BenchReport, title: str) -> str:
    """The same figures as Markdown tables (for benchmarks/README.md)."""
    rows = summarize(report)
    out = [f"### {title}", ""]
    out.append(f"Problems: {len(report.problems)}; methods: {', '.join(report.methods)}; "
               f"peers: {', '.join(f'{k} {v}' for k, v in report.peers.items()) or 'none'}"
               + "".join(f"; not used: {k} ({v})" for k, v in report.missing_peers.items()))
    out += ["", "| method | tol | success | sgm ms | median ms | median error | worst error "
                "| median fwd error | worst fwd error | defects |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for s in rows:
        out.append(f"| {s.method}{' (peer)' if s.peer else ''} | {s.tol:g} | "
                   f"{s.successes}/{s.runs} | {ms(s.sgm_seconds)} | {ms(s.median_seconds)} | "
                   f"{sci(s.median_error)} | {sci(s.worst_error)} | {sci(s.median_z_error)} | "
                   f"{sci(s.worst_z_error)} | {s.defects} |")
    out += ["", "fwd error: ||z - z*||_inf / max(1, ||z*||_inf) over the solved runs on problems "
                "with a unique known z* (the certified error bounds the backward error only). "
                "sgm ms is over the runs counted in `success`: rows with different counts are "
                "over different problems (a peer runs LCPs only; a method skips the kinds and "
                "sizes it does not handle); the performance profile counts a problem a method "
                "did not run as one it did not solve (methods that ran on none are left out)."]
    ratios = peer_ratios(report)
    if ratios:
        out += ["", "| method | peer | problems both solved | geomean time ratio ours/peer "
                    "| min | max |", "|---|---|---|---|---|---|"]
        for d in ratios:
            out.append(f"| {d['method']} | {d['peer']} | {d['problems']} | "
                       f"{d['geomean_ratio']:.3g} | {d['min_ratio']:.3g} | "
                       f"{d['max_ratio']:.3g} |")
    methods = report.all_methods()
    tol = report.tols[0]
    by = {(r.problem, r.method): r for r in report.records if r.tol == tol}
    out += ["", f"Per problem at tol {tol:g} (time ms / certified error / verdict: ok = right "
                "outcome, fail = unsolved, wrong = a verdict that is not the expected one):", "",
            "| problem | n | expected | " + " | ".join(methods) + " |",
            "|---|---|---|" + "---|" * len(methods)]
    for name, n, _k, expected in report.problems:
        cells = []
        for m in methods:
            r = by.get((name, m))
            cells.append("n/a" if r is None else f"{ms(r.seconds)} / {sci(r.error)} / {mark(r)}")
        out.append(f"| {name} | {n} | {expected} | " + " | ".join(cells) + " |")
    if report.defects:
        out += ["", "**Defects:**", ""]
        out += [f"- {r.problem} / {r.method}: {r.defect_reason}" for r in report.defects]
    return "\n".join(out) + "\n"
