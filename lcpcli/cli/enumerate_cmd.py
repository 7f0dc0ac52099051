"""``lcpcli enumerate``: the complementary cones of an LCP, all its solutions, the verdict."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import typer

from lcpcli.cli.common import (
    duration,
    pending_exit,
    progress_allowed,
    say_stopped,
    stderr_console,
    stdout_console,
    stopped_word,
    write_json_line,
)
from lcpcli.cli.export import EXACT_HELP, check_export_options, check_format, exact_cones
from lcpcli.core.errors import (
    EXIT_INTERRUPTED,
    EXIT_NOT_SOLVED,
    EXIT_SOLVED,
    OptionError,
    ProblemError,
)

#: Above this n, ``--all-cones`` is refused for the terminal table.
ALL_CONES_TABLE_MAX_N = 12
#: Above this n, ``--all-cones`` is refused even with ``--json``.
ALL_CONES_JSON_MAX_N = 16
#: From this many cones on (2^24), the run says up front how many and how long (stderr).
ESTIMATE_FROM_CONES = 1 << 24


def enumerate_command(
    file: str = typer.Argument(..., metavar="FILE",
                               help="Problem file (.json, .npz, .h5, .dat); '-' reads JSON "
                                    "from stdin."),
    as_json: bool = typer.Option(False, "--json",
                                 help="Print one JSON object on stdout and nothing else."),
    all_cones: bool = typer.Option(False, "--all-cones",
                                   help="List all 2^n cones, not only those containing q "
                                        f"(table: n <= {ALL_CONES_TABLE_MAX_N}; JSON: "
                                        f"n <= {ALL_CONES_JSON_MAX_N})."),
    max_n: int = typer.Option(24, "--max-n", metavar="N",
                              help="Refuse problems with more than N variables (2^N cones)."),
    plot: str = typer.Option(None, "--plot", metavar="FILE.png",
                              help="n = 2: draw the complementary cones and q with matplotlib "
                                   "(optional extra 'plot')."),
    problem: str = typer.Option(None, "--problem", "-p",
                                help="Problem (group) name inside an HDF5 file."),
    output: str = typer.Option(None, "--output", "-o",
                                help="Also write the JSON result to this file (atomically); "
                                     "with --format markdown/latex, the export instead."),
    lemke_path: bool = typer.Option(False, "--lemke-path",
                                    help="n = 2: draw Lemke's path q + z0 d (covering vector "
                                         "d = 1) in the cone pictures."),
    fmt: str = typer.Option("text", "--format",
                            help="text, markdown or latex: the cone table and solutions for "
                                 "lecture notes (stdout, or -o FILE)."),
    exact: bool = typer.Option(None, "--exact/--no-exact", show_default=False,
                               help=EXACT_HELP),
) -> int:
    """Enumerate the 2^n complementary cones of an LCP (Murty) and find ALL its solutions.

    Each choice of basic variables y_j in {w_j, z_j} gives the complementary matrix A_r
    (column I_j for w_j, -M_j for z_j); q lies in the cone Pos(A_r) when A_r y = q has a
    solution y >= 0, and that y is a solution of the LCP (w = M z + q). The verdict is: unique
    solution, finitely many, a continuum (a singular cone holding more than one point), or
    none, which is then a proof that the LCP has no solution. For n = 2 it also says whether
    the cones cover the plane (K(M) = R^2) and draws them. Exit codes: 0 a solution exists;
    1 no solution; 2 bad usage or bad input; 3 internal error.
    """
    from lcpcli.analysis.enumeration import check_problem, covers_plane, enumerate_cones
    from lcpcli.core.numeric import json_text
    from lcpcli.io import check_output, load, write_atomic_text
    from lcpcli.io.writing import check_distinct

    fmt = check_format(fmt)
    plot_path = Path(plot) if plot is not None else None
    output_path = Path(output) if output is not None else None
    check_export_options(fmt, output_path, [file], as_json)
    for option, target in (("--output", output), ("--plot", plot)):  # as typed: 'x.json/'
        if target is not None:  # before any work: never the input or a device
            check_output(target, inputs=[file], stdout=False, option=option)
    check_distinct([("--output", output_path), ("--plot", plot_path)])
    prob = load(file, problem)
    try:
        M = check_problem(prob, max_n)
    except ProblemError as exc:  # a problem enumeration does not take: the message names it
        raise exc.with_source(file) from None
    n = prob.n
    if lemke_path and n != 2:
        raise OptionError(f"--lemke-path draws in the 2 x 2 cone picture only (n = {n})")
    if all_cones:
        if n > ALL_CONES_JSON_MAX_N:
            raise OptionError(f"--all-cones lists 2^n = {2**n:,} cones, too many for n = {n} "
                              f"(limit n = {ALL_CONES_JSON_MAX_N}); leave it out to list the "
                              f"cones that contain q")
        if n > ALL_CONES_TABLE_MAX_N and not as_json:
            raise OptionError(f"--all-cones would print 2^{n} = {2**n:,} table rows (limit "
                              f"n = {ALL_CONES_TABLE_MAX_N}); use --json for the full list")
    if plot_path is not None:
        if n != 2:
            raise OptionError(f"--plot draws the cones of 2 x 2 problems only (n = {n})")
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise OptionError("--plot needs matplotlib: pip install matplotlib "
                              "(or the 'plot' extra of lcpcli)") from None
        if not plot_path.parent.is_dir():
            raise OptionError(f"--plot: folder {plot_path.parent} does not exist")

    tracker = _Progress(1 << n)
    try:
        with tracker:
            res = enumerate_cones(prob, all_cones=all_cones, max_n=max_n, progress=tracker.update)
    except KeyboardInterrupt as exc:
        say_stopped(f"lcpcli: {stopped_word(exc)} after {tracker.done:,} of {1 << n:,} cones "
                    f"({100 * tracker.done / (1 << n):.2g} %); no verdict: every cone must be "
                    f"visited to list all solutions or prove there is none (for one solution "
                    f"use 'lcpcli solve')")
        return EXIT_INTERRUPTED
    code = pending_exit(EXIT_SOLVED if res.solutions else EXIT_NOT_SOLVED)
    covers = covers_plane(M) if n == 2 else None
    path = _lemke_path(prob) if lemke_path else None
    if plot_path is not None:
        from lcpcli.cli.render.enumerate import plot_cones

        plot_cones(M, prob.q, plot_path, title=prob.name or "", path=path)
    payload = res.to_dict()
    payload = {"file": file, **payload}
    if covers is not None:
        payload["covers_plane"] = covers
    if path is not None:
        payload["lemke_path"] = path
    if output_path is not None and fmt == "text":
        write_atomic_text(output_path, json_text(payload) + "\n")
    if not as_json or fmt != "text":  # the tables in fractions; the JSON above keeps floats

        res, M = exact_cones(prob, exact, res, M)
    if fmt != "text":
        from lcpcli.cli.render.doc import write
        from lcpcli.cli.render.enumerate import enumeration_pages

        text = write(enumeration_pages(res, prob, file, all_cones=all_cones, covers=covers),
                     fmt, title=f"lcpcli enumerate {file}")
        if output_path is not None:
            write_atomic_text(output_path, text)
            sys.stderr.write(f"lcpcli: wrote {output_path}\n")
        else:
            sys.stdout.write(text)
    if as_json:
        write_json_line(payload)
    elif fmt == "text":
        from lcpcli.cli.render.enumerate import draw_cones_text, render_enumeration

        # (a stream without the box characters gets ASCII stand-ins: common.StdoutGuard)
        drawing = draw_cones_text(M, prob.q, path=path) if n == 2 else None
        stdout_console().print(render_enumeration(res, prob, file, all_cones=all_cones,
                                                  covers=covers, drawing=drawing))
    if plot_path is not None and not as_json:
        sys.stderr.write(f"lcpcli: wrote {plot_path}\n")
    return code


def _lemke_path(prob: object) -> list[dict[str, object]]:
    """Lemke's path q + z0 d of a 2 x 2 problem (covering vector d = 1), from the trace."""
    from lcpcli.api import solve
    from lcpcli.solvers.trace.lemke import path_points

    result = solve(prob, "lemke-tableau", trace=True)
    return path_points(result.trace or [], prob.q)  # type: ignore[attr-defined]


class _Progress:
    """What a long enumeration shows: an estimate on stderr up front (from 2^24 cones on),
    and a progress bar on stderr when it is a terminal, after about a second."""

    def __init__(self, total: int) -> None:
        self.total = total
        self.done = 0
        self._bar: Any = None
        self._task: Any = None
        self._start = 0.0
        self._estimated = False

    def __enter__(self) -> _Progress:
        self._start = time.perf_counter()
        if self.total >= ESTIMATE_FROM_CONES:
            sys.stderr.write(f"lcpcli: enumerating 2^{self.total.bit_length() - 1} = "
                             f"{self.total:,} complementary cones (Ctrl-C stops)\n")
        return self

    def update(self, done: int, total: int) -> None:
        self.done = done
        elapsed = time.perf_counter() - self._start
        if not self._estimated and self.total >= ESTIMATE_FROM_CONES and 0 < done < total:

            self._estimated = True
            rate = done / max(elapsed, 1e-9)
            sys.stderr.write(f"lcpcli: about {duration((total - done) / rate)} to go at "
                             f"{rate:,.0f} cones/s\n")
        if self._bar is None:

            if elapsed < 1.0 or done >= total or not progress_allowed():
                return
            from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn


            self._bar = Progress(TextColumn("cones"), BarColumn(),
                                 TextColumn("{task.completed:,}/{task.total:,}"),
                                 TimeRemainingColumn(), console=stderr_console(),
                                 transient=True)
            self._bar.start()
            self._task = self._bar.add_task("cones", total=total)
        self._bar.update(self._task, completed=done)

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()


def register(app: typer.Typer) -> None:
    app.command("enumerate")(enumerate_command)
