"""``lcpcli info``: classify a problem's matrix and say which methods apply, and why."""

from __future__ import annotations

import typer

from lcpcli.cli.common import stdout_console, write_json_line
from lcpcli.core.errors import EXIT_OK


def info(
    file: str = typer.Argument(..., metavar="FILE",
                               help="Problem file (.json, .npz, .h5, .dat); '-' reads JSON "
                                    "from stdin."),
    problem: str = typer.Option(None, "--problem", "-p",
                                help="Problem (group) name inside an HDF5 file."),
    as_json: bool = typer.Option(False, "--json",
                                 help="Print one JSON object on stdout and nothing else."),
) -> int:
    """Classify M (symmetric? PD/PSD? Z? H? P-matrix? sparse? size?), every test run, and
    list each solver method with whether it applies and why, and the order 'auto' would try
    once its first, optimistic attempt has failed.
    Exit codes: 0 done; 2 bad usage or bad input; 3 internal error.
    """
    from lcpcli.core.limits import check_dense_work
    from lcpcli.io import load
    from lcpcli.solvers.policy import info_report

    def budget(n: int) -> None:  # the work budget (docs/files.md): the tests copy a dense M
        check_dense_work(n, "the classification works on dense copies of M", cubic=False)

    prob = load(file, problem, check_dense=budget)  # from the header, before M is read
    report = info_report(prob, file)
    if as_json:

        write_json_line(report)
    else:
        from lcpcli.cli.render.info import render_info

        stdout_console().print(render_info(report))
    return EXIT_OK


def register(app: typer.Typer) -> None:
    app.command("info")(info)
