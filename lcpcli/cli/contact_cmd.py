"""``lcpcli contact-matrix``: the impulse LCP of a rigid-body scene (seed 004)."""

from __future__ import annotations

from pathlib import Path

import typer

from lcpcli.cli.common import MethodListCommand


def contact_matrix(
    scene_file: str = typer.Argument(..., metavar="SCENE",
                                     help="Scene file (.json or .h5/.hdf5), see docs/contact.md."),
    output: Path = typer.Option(None, "--output", "-o", metavar="OUT",  # noqa: B008
                                help="Write the LCP (M, q, contact metadata) to OUT "
                                     "(.json, .npz, .h5, .dat; atomically)."),
    do_solve: bool = typer.Option(False, "--solve",
                                  help="Solve the LCP and report impulses, post-impact "
                                       "velocities and kinetic energies."),
    friction: int = typer.Option(0, "--friction", metavar="K",
                                 help="Polyhedral friction with K tangent directions per contact "
                                      "with mu > 0 (3-D: K >= 3; 2-D: 2) [default: 0, "
                                      "frictionless]."),
    method: str = typer.Option("lemke", "--method", "-m",
                               help="Solver method for --solve (listed below)."),
    tol: float = typer.Option(None, "--tol", help="Tolerance on the certificate's scaled error."),
    storage: str = typer.Option("auto", "--storage",
                                help="M storage: auto (dense when small, sparse when large and "
                                     "sparse), dense or sparse."),
    as_json: bool = typer.Option(False, "--json",
                                 help="Print one JSON object on stdout and nothing else."),
) -> int:
    """Build the contact LCP w = M j + q of a rigid-body scene (M = J W J^T, q = (1+eps) J v^-).

    Normals point from body B to body A; approaching contacts have q < 0. Only moving bodies
    that touch a contact get unknowns. Exit codes: 0 built (and solved with --solve); 1 not
    solved; 2 bad scene or options; 3 internal error.
    """
    import sys

    from lcpcli.cli.common import exit_code_for, write_json_line
    from lcpcli.contact import build, load_scene, solve, to_json
    from lcpcli.contact.model import check_method
    from lcpcli.core.errors import OptionError

    if friction < 0:
        raise OptionError(f"--friction K must be >= 0, got {friction}")
    scene = load_scene(scene_file)
    for w in scene.warnings:
        sys.stderr.write(f"lcpcli: warning: {scene_file}: {w}\n")
    clcp = build(scene, friction=friction, storage=storage)
    for note in clcp.notes:
        sys.stderr.write(f"lcpcli: note: {note}\n")
    if do_solve:
        check_method(clcp, method)  # before anything is written
    if output is not None:
        from lcpcli.io import save

        save(clcp.problem, output)
    impact = None
    if do_solve:
        impact = solve(clcp, method, tol=tol)
    if as_json:
        write_json_line(to_json(clcp, impact))
    else:
        from lcpcli.cli.common import stdout_console
        from lcpcli.cli.render.contact import render_impact, render_scene

        console = stdout_console()
        console.print(render_scene(clcp, scene_file, str(output) if output else None))
        if impact is not None:
            console.print(render_impact(clcp, impact))
    if impact is not None and impact.energy_increase:
        sys.stderr.write("lcpcli: warning: kinetic energy increased in the impact "
                         f"({impact.energy_before:.6g} -> {impact.energy_after:.6g})\n")
    return exit_code_for([impact.result.status]) if impact is not None else 0


def register(app: typer.Typer) -> None:
    app.command("contact-matrix", cls=MethodListCommand)(contact_matrix)
