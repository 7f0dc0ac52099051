"""``lcpcli bench``: speed against error for every registered method, with peers side by side."""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from typing import Any

import typer

from lcpcli.cli.common import (
    MethodListCommand,
    duration,
    pending_exit,
    plural,
    progress_allowed,
    say_stopped,
    stderr_console,
    stdout_console,
    stopped_word,
    write_json_line,
)
from lcpcli.core.errors import (
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_NOT_SOLVED,
    EXIT_OK,
    OptionError,
)

#: Largest ``--n`` of each built-in suite (hard: dense 4n x 4n families, Murty's needs 2^n
#: pivots; random: its largest size; siconos: any, it only skips larger files).
SUITE_MAX_N = {"hard": 250, "random": 2000}
#: Largest ``--repeat`` (the budget stops repeats anyway).
MAX_REPEAT = 10_000
#: A run expected to take longer than this (seconds) prints an estimate on stderr.
ESTIMATE_AFTER_SECONDS = 10.0


def _floats(text: str, label: str) -> list[float]:

    try:
        vals = [float(x) for x in text.replace(";", ",").split(",") if x.strip()]
    except ValueError:
        raise OptionError(f"{label} must be a comma-separated list of numbers, got {text!r}") \
            from None
    if not vals:
        raise OptionError(f"{label} is empty")
    return vals


def bench(
    problems: list[str] = typer.Argument(None, metavar="PROBLEMS",  # noqa: B008
                                         help="Problem files, folders (searched recursively) "
                                              "or HDF5 files holding many problems."),
    methods: str = typer.Option(None, "--methods", "-m",
                                help="Comma-separated methods [default: every registered "
                                     "method]."),
    suite: str = typer.Option(None, "--suite", "-s",
                              help="Built-in suite: hard, random or siconos."),
    n: int = typer.Option(None, "--n",
                          help="Suite size parameter (hard: family size, default 8; random: "
                               "largest size, default 2000; siconos: skip larger problems)."),
    seed: int = typer.Option(0, "--seed", help="Seed of the generated suites."),
    tol: str = typer.Option("1e-8", "--tol",
                            help="Comma-separated tolerances on the certified error; each method "
                                 "runs once per tolerance."),
    repeat: int = typer.Option(5, "--repeat", "-r",
                               help="Timed repeats after the untimed warm-up (median reported)."),
    budget: float = typer.Option(1.0, "--budget",
                                 help="Stop repeating once the timed runs of a (problem, method) "
                                      "add up to this many seconds."),
    timeout: float = typer.Option(60.0, "--timeout",
                                  help="Wall-clock limit in seconds of one (problem, method, "
                                       "tol), warm-up and repeats included; each runs in a "
                                       "forked child process. 0 = no limit, in process."),
    peers: bool = typer.Option(True, "--peers/--no-peers",
                               help="Run the peers found (Siconos via /usr/bin/python3, "
                                    "lemkelcp) side by side."),
    as_json: bool = typer.Option(False, "--json",
                                 help="One JSON object per line per (problem, method, tol) on "
                                      "stdout, nothing else."),
    plot: str = typer.Option(None, "--plot", metavar="PATH",
                              help="Write a PNG with the performance profile, the "
                                   "work-precision scatter and time against forward error "
                                   "where z* is known (needs matplotlib: extra 'plot')."),
    markdown: str = typer.Option(None, "--markdown", metavar="PATH",
                                  help="Also write the report as Markdown tables to this file."),
) -> int:
    """Benchmark solver methods: time, achieved error and verdict on each problem.

    Every answer is re-certified; a method that claims 'solved' with a failing certificate, or
    'no_solution' on a problem known to be solvable or without a Farkas vector that passes the
    proof check, is a DEFECT. Exit codes: 0 no defect and
    no error; 1 at least one defect; 2 bad usage or bad input; 3 a method raised or its
    process died (an internal error; the rows say which).
    """
    from lcpcli.bench import runner as B
    from lcpcli.core.certificate import validate_tol

    tols = [validate_tol(t) for t in _floats(tol, "--tol")]  # the one rule, as for a solve
    if not 0 <= repeat <= MAX_REPEAT:
        raise OptionError(f"--repeat must be between 0 and {MAX_REPEAT:,}, got {repeat}")
    if not (math.isfinite(budget) and budget > 0):
        raise OptionError(f"--budget must be a positive number of seconds, got {budget}")
    if not (math.isfinite(timeout) and timeout >= 0):
        raise OptionError(f"--timeout must be a finite number of seconds >= 0, got {timeout}")
    if seed < 0:
        raise OptionError(f"--seed must be >= 0, got {seed}")
    if suite is not None and n is not None:
        limit = SUITE_MAX_N.get(suite.strip().lower())
        if limit is not None and n > limit:
            raise OptionError(f"--n {n} is too large for the {suite} suite (limit {limit})")
    method_list = B.resolve_methods(None if methods is None else methods.split(","))
    inputs = list(problems or [])
    # before any work: never an input, a link or a device, never stdout (a file named '-'
    # was written), and two outputs are two files (lcpcli.io.writing's rule 1)
    for option, target in (("--plot", plot), ("--markdown", markdown)):
        if target is not None:
            from lcpcli.io import check_output

            check_output(target, inputs=inputs, stdout=False, option=option)
    if plot is not None and markdown is not None:
        from lcpcli.io.writing import check_distinct

        check_distinct([("--markdown", markdown), ("--plot", plot)])
    if plot is not None:
        from lcpcli.cli.render.bench import plot_available

        if not plot_available():
            raise OptionError("--plot needs matplotlib (pip install 'lcpcli[plot]')")
    if not problems and suite is None:
        raise OptionError("give problem files or folders, or --suite hard|random|siconos")
    cases = []
    titles = []
    if suite is not None:
        from lcpcli.bench.suites import suite as make_suite

        cases += make_suite(suite, n, seed)
        titles.append(f"suite {suite}" + (f" (n={n})" if n else ""))
    if problems:
        cases += B.cases_from_paths(problems)
        titles.append(f"{len(problems)} path(s)")
    if not cases:
        raise OptionError("no problems to run")

    found, missing = [], {}
    if peers:
        from lcpcli.bench.peers import discover

        found, missing = discover()
    err = stderr_console()
    for fam, why in missing.items():
        err.print(f"lcpcli: note: peer {fam} not used: {why}")

    tracker = _Tracker(cases, method_list, tols, found, err)
    records: list[Any] = []

    def on_record(rec: B.Record) -> None:
        records.append(rec)
        if as_json:
            write_json_line(rec.to_json())
        tracker.record(rec)

    title = ", ".join(titles)
    interrupted = False
    try:
        with tracker:
            report = B.run_bench(cases, method_list, tols, repeat=repeat, budget=budget,
                                 peers=found, missing_peers=missing, timeout=timeout or None,
                                 on_record=on_record)
    except KeyboardInterrupt as exc:
        interrupted, word = True, stopped_word(exc)
        report = B.BenchReport(records=records, methods=list(method_list), tols=tols,
                               problems=[(c.name, c.n, c.problem.kind, c.expected)
                                         for c in cases],
                               peers={p.family: p.version for p in found},
                               missing_peers=dict(missing))
        title += f" ({word} after {tracker.done:,} of {tracker.total:,} runs)"
        say_stopped(f"lcpcli: {word} after {tracker.done:,} of {tracker.total:,} runs; "
                    f"the report below covers those")

    code = pending_exit(EXIT_INTERRUPTED if interrupted else EXIT_NOT_SOLVED if report.defects
                        else EXIT_INTERNAL if report.errors else EXIT_OK)
    if not as_json and report.records:
        from lcpcli.cli.render.bench import render_report

        console = stdout_console()
        console.print(render_report(report, title, width=console.width))
    if markdown is not None and report.records:
        from lcpcli.cli.render.bench import markdown_report
        from lcpcli.io import write_atomic_text

        write_atomic_text(markdown, markdown_report(report, title))
    if plot is not None and report.records:
        from lcpcli.cli.render.bench import write_plot

        write_plot(report, Path(plot))
    for rec in report.defects:
        err.print(f"lcpcli: DEFECT: {rec.method} on {rec.problem}: {rec.defect_reason}")
    for rec in report.errors:
        err.print(f"lcpcli: ERROR: {rec.method} on {rec.problem}: {rec.message}")
    return code


class _Tracker:
    """Runs done out of the total: an estimate on stderr once the first runs are timed, and a
    progress bar on stderr when it is a terminal.  A run is one (problem, tolerance, method)
    or one (problem, tolerance, peer family)."""

    def __init__(self, cases: list[Any], methods: list[str], tols: list[float],
                 peers: list[Any], console: Any) -> None:
        from lcpcli.bench.runner import skip_reason

        # the runs run_bench makes: its own skip rule (kind, max_n), peers by kind
        self.total = len(tols) * sum(
            sum(not skip_reason(c, m) for m in methods)
            + sum(c.problem.kind in p.kinds for p in peers) for c in cases)
        self.done = 0
        self.console = console
        self._seen_peer: set[tuple[str, float, str]] = set()
        self._start = 0.0
        self._estimated = False
        self._bar: Any = None
        self._task: Any = None

    def __enter__(self) -> _Tracker:

        self._start = time.perf_counter()

        if progress_allowed():
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

            self._bar = Progress(TextColumn("bench"), BarColumn(), MofNCompleteColumn(),
                                 TextColumn("{task.fields[what]}"), console=self.console,
                                 transient=True)
            self._task = self._bar.add_task("bench", total=self.total, what="")
            self._bar.start()
        if self.total > 1:
            sys.stderr.write(f"lcpcli: bench: {plural(self.total, 'run')} (problem x "
                             f"tolerance x method or peer); Ctrl-C stops and reports the "
                             f"finished ones\n")
        return self

    def record(self, rec: Any) -> None:

        if rec.peer:
            key = (rec.problem, rec.tol, rec.peer)
            if key in self._seen_peer:
                return
            self._seen_peer.add(key)
        self.done += 1
        if self._bar is not None:
            self._bar.update(self._task, completed=self.done,
                             what=f"{rec.problem} {rec.method}"[:40])
        elapsed = time.perf_counter() - self._start
        if not self._estimated and elapsed >= 2.0 and self.done < self.total:
            self._estimated = True
            left = elapsed / self.done * (self.total - self.done)
            if left > ESTIMATE_AFTER_SECONDS:
                sys.stderr.write(f"lcpcli: bench: about {duration(left)} to go\n")

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()


def register(app: typer.Typer) -> None:
    app.command("bench", cls=MethodListCommand)(bench)
