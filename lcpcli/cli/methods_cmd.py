"""``lcpcli methods``: list the registered solver methods."""

from __future__ import annotations

import typer

from lcpcli.cli.common import stdout_console, write_json_line
from lcpcli.core.errors import EXIT_OK


def methods_command(
    as_json: bool = typer.Option(False, "--json", help="Machine-readable list on stdout."),
) -> int:
    """List the solver methods, the matrix classes they handle and their options.

    With --json: one list of objects with the declared policy data too (guarantees: the
    properties of the class report that must hold and the claim; needs; max_n; cost; fallback;
    batch: the batched kernel that solves stacks, see docs/batch.md).
    """
    from lcpcli.solvers.registry import methods

    registry = methods()
    if as_json:

        write_json_line([{"name": m.name, "aliases": list(m.aliases), "summary": m.summary,
                          "classes": m.matrix_classes, "kinds": list(m.kinds),
                          "default_tol": m.default_tol,
                          "options": {k: o.help for k, o in m.options.items()},
                          "guarantees": [{"when": list(g.when.props), "claim": g.claim,
                                          "kinds": list(g.kinds or m.kinds), "slow": g.slow}
                                         for g in m.guarantees],
                          "needs": [{"when": list(r.when.props), "why": r.why}
                                    for r in m.needs],
                          "max_n": m.max_n, "cost": m.cost.value, "fallback": m.fallback,
                          "batch": None if m.batch is None else {
                              "kernel": m.batch.kernel, "options": list(m.batch.options),
                              "kinds": list(m.batch.kinds),
                              "runs_as": m.batch.runs_as or m.name}}
                         for m in registry.values()])
        return EXIT_OK
    from lcpcli.cli.render.common import render_methods

    stdout_console().print(render_methods(registry))
    return EXIT_OK


def register(app: typer.Typer) -> None:
    app.command("methods")(methods_command)
