"""``lcpcli contact-matrix``: the impulse LCP of a rigid-body scene (effective masses,
multi-contact ``M = J W J^T``)."""

from __future__ import annotations

import sys

import typer

from lcpcli.cli.common import MethodListCommand, exit_code_for, stdout_console, write_json_line
from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.solvers import DEFAULT_METHOD


def contact_matrix(
    scene_file: str = typer.Argument(..., metavar="SCENE",
                                     help="Scene file (.json or .h5/.hdf5), see docs/contact.md."),
    output: str = typer.Option(None, "--output", "-o", metavar="OUT",
                                help="Write the whole-scene LCP (M, q, contact metadata) to OUT "
                                     "(.json, .npz, .h5, .dat; atomically)."),
    do_solve: bool = typer.Option(False, "--solve",
                                  help="Solve the LCP and report impulses, post-impact "
                                       "velocities and kinetic energies."),
    friction: int = typer.Option(0, "--friction", metavar="K", show_default=False,
                                 help="Polyhedral friction with K tangent directions per contact "
                                      "with mu > 0: in 3-D K >= 3 (a scene whose motion is "
                                      "planar then uses its 2 in-plane directions, see "
                                      "--no-planar); in 2-D K >= 2 gives the 2 directions +-t "
                                      "[default: 0, frictionless]."),
    method: str = typer.Option(DEFAULT_METHOD, "--method", "-m",
                               help="Solver method for --solve, per island (listed below)."),
    tol: float = typer.Option(None, "--tol",
                              help="Tolerance on the certified error (see the README)."),
    storage: str = typer.Option("auto", "--storage",
                                help="M storage: auto (dense when small, sparse when large and "
                                     "sparse), dense or sparse."),
    no_islands: bool = typer.Option(False, "--no-islands",
                                    help="Solve the whole-scene LCP at once instead of one LCP "
                                         "per island."),
    jobs: int = typer.Option(1, "--jobs", "-j", metavar="N",
                             help="Processes for the islands (used when the islands hold at "
                                  "least 20,000 unknowns)."),
    threshold: float = typer.Option(None, "--restitution-threshold", metavar="V",
                                    help="Restitution only for contacts approaching faster than "
                                         "V (replaces the scene's value; contacts with their own "
                                         "keep it) [default: scene's, else 0]."),
    softness: float = typer.Option(None, "--softness", metavar="S",
                                   help="Soft contacts: add S * M_ii to each impulse row's "
                                        "diagonal (replaces the scene's value) [default: "
                                        "scene's, else 0 = rigid]."),
    kinematic: list[str] = typer.Option(None, "--kinematic", metavar="NAME",  # noqa: B008
                                        help="Make body NAME kinematic (prescribed velocity, "
                                             "infinite mass); repeatable or comma-separated."),
    no_planar: bool = typer.Option(False, "--no-planar",
                                   help="Keep K friction directions even when the motion of a "
                                        "3-D scene is planar."),
    z0: str = typer.Option(None, "--z0", metavar="FILE",
                           help="Warm start from previous impulses (--impulses file, "
                                "contact-matrix --json or lcpcli solve --json output)."),
    impulses: str = typer.Option(None, "--impulses", metavar="FILE",
                                  help="With --solve, write the impulses with their unknown "
                                       "names to FILE (.json or .npz) for a later --z0."),
    as_json: bool = typer.Option(False, "--json",
                                 help="Print one JSON object on stdout and nothing else."),
) -> int:
    """Build the contact LCP w = M j + q of a rigid-body scene (M = J W J^T, q = (1+e) J v^-).

    Normals point from body B to body A; approaching contacts have q < 0; restitution e applies
    only to contacts approaching faster than their threshold. Only dynamic bodies that touch a
    contact get unknowns; --solve solves one LCP per island. Exit codes: 0 built (and solved
    with --solve); 1 not solved; 2 bad scene or options; 3 internal error.
    """

    from lcpcli.contact import build, load_scene, solve, to_json
    from lcpcli.contact.model import check_method
    from lcpcli.contact.scene import with_kinematic
    from lcpcli.contact.warmstart import check_impulses_path, warm_start, write_impulses
    from lcpcli.io import check_output
    from lcpcli.io.writing import check_distinct

    if friction < 0:
        raise OptionError(f"--friction K must be >= 0, got {friction}")
    if jobs < 1:
        raise OptionError(f"--jobs must be >= 1, got {jobs}")
    for flag, value in (("--z0", z0), ("--impulses", impulses)):
        if value is not None and not do_solve:
            raise OptionError(f"{flag} needs --solve")
    # before any work: an output is never an input (the scene, --z0), a device or a link,
    # and the two outputs are two files (lcpcli.io.writing's rule 1)
    inputs = [scene_file, z0] if z0 is not None else [scene_file]
    if impulses is not None:
        check_impulses_path(impulses)
        check_output(impulses, inputs=inputs, stdout=False, option="--impulses")
    if output is not None:
        check_output(output, inputs=inputs, stdout=False)
    check_distinct([("--output", output), ("--impulses", impulses)])
    scene = load_scene(scene_file)
    names = [nm.strip() for item in kinematic or [] for nm in item.split(",") if nm.strip()]
    scene = with_kinematic(scene, names)
    try:
        clcp = build(scene, friction=friction, storage=storage, restitution_threshold=threshold,
                     softness=softness, planar=not no_planar)
    except ProblemError as exc:  # a size or work budget refused the scene's LCP: name the file
        raise exc.with_source(scene_file) from None
    start = basis = how = None
    if do_solve:
        try:
            check_method(clcp, method, not no_islands)  # before anything is written
        except ProblemError as exc:  # a work budget refused the scene's LCP: name the file
            raise exc.with_source(scene_file) from None
        if z0 is not None:
            start, basis, how = warm_start(z0, clcp.unknowns)
    # the scene and its options are valid: now its warnings and notes (a refusal above is
    # one line on stderr, with no warning about the scene before it)
    for w in scene.warnings:
        sys.stderr.write(f"lcpcli: warning: {scene_file}: {w}\n")
    for note in [*clcp.notes, *([how] if how is not None else [])]:
        sys.stderr.write(f"lcpcli: note: {note}\n")
    if output is not None:
        from lcpcli.io import save

        save(clcp.problem, output)
    impact = None
    if do_solve:
        try:
            impact = solve(clcp, method, tol=tol, islands=not no_islands, z0=start,
                           basis0=basis, jobs=jobs)
        except ProblemError as exc:  # a work budget refused an island's LCP: name the file
            raise exc.with_source(scene_file) from None
        if impulses is not None:
            write_impulses(impulses, clcp.unknowns, impact.result.z, scene.name,
                           impact.result.status, impact.basic)
    if as_json:
        write_json_line(to_json(clcp, impact))
    else:
        from lcpcli.cli.render.contact import render_impact, render_scene

        console = stdout_console()
        console.print(render_scene(clcp, scene_file, str(output) if output else None))
        if impact is not None:
            console.print(render_impact(clcp, impact))
    if impact is not None and impact.energy_increase:
        sys.stderr.write("lcpcli: warning: kinetic energy increased in the impact "
                         f"({impact.energy_before:.6g} -> {impact.energy_after:.6g})\n")
    if impact is not None and impact.approaching.any():
        sys.stderr.write(f"lcpcli: warning: {int(impact.approaching.sum())} contacts end "
                         f"approaching (min v_rel+ = {impact.normal_velocity.min():.3g})"
                         + (": soft contacts allow it" if clcp.regularisation.any() else "")
                         + "\n")
    return exit_code_for([impact.result.status]) if impact is not None else 0


def register(app: typer.Typer) -> None:
    app.command("contact-matrix", cls=MethodListCommand)(contact_matrix)
