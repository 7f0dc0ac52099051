"""``lcpcli bench``: speed against error for every registered method, with peers side by side."""

from __future__ import annotations

from pathlib import Path

import typer

from lcpcli.cli.common import MethodListCommand
from lcpcli.core.errors import EXIT_INTERNAL, EXIT_NOT_SOLVED, EXIT_OK


def _floats(text: str, label: str) -> list[float]:
    from lcpcli.core.errors import OptionError

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
                            help="Comma-separated tolerances on the scaled error; each method "
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
    plot: Path = typer.Option(None, "--plot",  # noqa: B008
                              help="Write a PNG with the performance profile and the "
                                   "work-precision scatter (needs matplotlib: extra 'plot')."),
    markdown: Path = typer.Option(None, "--markdown",  # noqa: B008
                                  help="Also write the report as Markdown tables to this file."),
) -> int:
    """Benchmark solver methods: time, achieved error and verdict on each problem.

    Every answer is re-certified; a method that claims 'solved' with a failing certificate, or
    'no_solution' on a problem known to be solvable, is a DEFECT. Exit codes: 0 no defect and
    no error; 1 at least one defect; 2 bad usage or bad input; 3 a method raised or its
    process died (an internal error; the rows say which).
    """
    from lcpcli.bench import runner as B
    from lcpcli.cli.common import stderr_console, stdout_console, write_json_line
    from lcpcli.core.errors import OptionError

    tols = _floats(tol, "--tol")
    if any(t <= 0 for t in tols):
        raise OptionError("--tol values must be positive")
    if repeat < 0:
        raise OptionError("--repeat must be >= 0")
    if budget <= 0:
        raise OptionError("--budget must be positive")
    if timeout < 0:
        raise OptionError("--timeout must be >= 0")
    method_list = B.resolve_methods(None if methods is None else methods.split(","))
    if plot is not None:
        from lcpcli.cli.render.bench import plot_available

        if not plot_available():
            raise OptionError("--plot needs matplotlib (pip install 'lcpcli[plot]')")
        if not plot.parent.is_dir() and str(plot.parent):
            raise OptionError(f"--plot: folder {plot.parent} does not exist")
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

    def on_record(rec: B.Record) -> None:
        if as_json:
            write_json_line(rec.to_json())

    report = B.run_bench(cases, method_list, tols, repeat=repeat, budget=budget, peers=found,
                         missing_peers=missing, timeout=timeout or None, on_record=on_record)
    title = ", ".join(titles)
    if not as_json:
        from lcpcli.cli.render.bench import render_report

        stdout_console().print(render_report(report, title))
    if markdown is not None:
        from lcpcli.cli.render.bench import markdown_report
        from lcpcli.io import write_atomic_text

        write_atomic_text(markdown, markdown_report(report, title))
    if plot is not None:
        from lcpcli.cli.render.bench import write_plot

        write_plot(report, plot)
    for rec in report.defects:
        err.print(f"lcpcli: DEFECT: {rec.method} on {rec.problem}: {rec.defect_reason}")
    for rec in report.errors:
        err.print(f"lcpcli: ERROR: {rec.method} on {rec.problem}: {rec.message}")
    if report.defects:
        return EXIT_NOT_SOLVED
    return EXIT_INTERNAL if report.errors else EXIT_OK


def register(app: typer.Typer) -> None:
    app.command("bench", cls=MethodListCommand)(bench)
