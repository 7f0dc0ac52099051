"""``lcpcli pivot``: the principal pivoting transform of seed 000 for one basis."""

from __future__ import annotations

import typer

from lcpcli.core.errors import EXIT_OK


def pivot(
    file: str = typer.Argument(..., metavar="FILE",
                               help="Problem file with q and M; M may have n + 1 columns (the "
                                    "last is the artificial variable z{n+1}, JSON/NPZ)."),
    dependent: str = typer.Option(..., "--dependent", "-d",
                                  help="Dependent tuple w' (n names), e.g. 'z4,w2,z3'."),
    independent: str = typer.Option(None, "--independent", "-i",
                                    help="Independent tuple z' (n+1 names), e.g. "
                                         "'w1,w3,z2,z1' [default: the others, w's then z's]."),
    driving: str = typer.Option(None, "--driving",
                                help="Driving variable (one of z'): print its column of M'."),
    covering: str = typer.Option(None, "--covering",
                                 help="Artificial column when M has n columns, e.g. '1,2,1' "
                                      "[default: all ones]."),
    full: bool = typer.Option(False, "--full", help="Also print the whole pivoted tableau."),
    any_basis: bool = typer.Option(False, "--any-basis",
                                   help="Allow w_i and z_i both dependent (non-complementary)."),
    problem: str = typer.Option(None, "--problem", "-p",
                                help="Problem (group) name inside an HDF5 file."),
    as_json: bool = typer.Option(False, "--json",
                                 help="Print one JSON object on stdout and nothing else."),
) -> int:
    """Principal pivoting transform (seed 000): q' and M'_driving of w' = q' + M' z'.

    Variable names are 1-based: w1..wn, z1..z{n+1}; z0 is an alias of the artificial z{n+1}.
    Exit codes: 0 done; 2 bad input (bad basis, singular M^{alpha beta}, bad file).
    """
    from lcpcli.analysis.pivoting import load_augmented, parse_tuple, parse_var, principal_pivot

    Maug, q, source = load_augmented(file, covering, problem)
    n = q.shape[0]
    dep = parse_tuple(dependent, n)
    ind = parse_tuple(independent, n) if independent is not None else None
    drv = parse_var(driving, n) if driving is not None else None
    t = principal_pivot(Maug, q, dep, ind, driving=drv, full=full, any_basis=any_basis)
    if as_json:
        from lcpcli.cli.common import write_json_line

        payload = t.to_dict()
        payload["file"] = file
        payload["artificial_column"] = source
        write_json_line(payload)
    else:
        from lcpcli.cli.common import stdout_console
        from lcpcli.cli.render.pivot import render_pivot

        stdout_console().print(render_pivot(t, Maug, q, source))
    return EXIT_OK


def register(app: typer.Typer) -> None:
    app.command("pivot")(pivot)
