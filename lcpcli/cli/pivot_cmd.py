"""``lcpcli pivot``: the principal pivoting transform of seed 000 for one basis."""

from __future__ import annotations

from typing import Any

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
    from lcpcli.analysis.pivoting import parse_tuple, parse_var, principal_pivot

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


def load_augmented(path: str, covering: str | None = None,
                   problem: str | None = None) -> tuple[Any, Any, str]:
    """Read ``q`` and the ``n x (n+1)`` matrix ``[M, d]`` of a problem file.

    JSON and NPZ files may store ``M`` with ``n + 1`` columns (the artificial column last,
    as in seed 000); otherwise the file holds an ordinary LCP and ``covering`` (text such as
    ``"1,2,1"``; default all ones) supplies the artificial column.  Returns ``(Maug, q, where)``
    with ``where`` saying where the artificial column came from.
    """
    import json  # file reading happens in the command body (start-up budget)
    from pathlib import Path

    import numpy as np

    from lcpcli.analysis.pivoting import augment
    from lcpcli.core.errors import ProblemError
    from lcpcli.io import detect_format, load

    kind = detect_format(path)
    raw_M: Any = None
    raw_q: Any = None
    try:
        if kind == "json" and str(path) != "-" and Path(path).is_file():
            data = json.loads(Path(path).read_text(encoding="utf-8"))
            if isinstance(data, dict) and isinstance(data.get("M"), list):
                raw_M, raw_q = data["M"], data.get("q")
        elif kind == "npz" and Path(path).is_file():
            with np.load(path, allow_pickle=False) as npz:
                if "M" in npz.files and "q" in npz.files:
                    raw_M, raw_q = npz["M"], npz["q"]
    except (ValueError, OSError, UnicodeDecodeError):
        raw_M = None  # let the regular reader produce the proper message
    if raw_M is not None and raw_q is not None:
        try:
            A = np.asarray(raw_M, dtype=np.float64)
            qv = np.asarray(raw_q, dtype=np.float64).ravel()
        except (TypeError, ValueError):
            A, qv = None, None
        if A is not None and A.ndim == 2 and A.shape == (qv.shape[0], qv.shape[0] + 1):
            if covering is not None:
                raise ProblemError("M already has n + 1 columns (the artificial column); "
                                   "drop --covering", str(path))
            if not (np.all(np.isfinite(A)) and np.all(np.isfinite(qv))):
                raise ProblemError("M or q contains NaN or Inf", str(path))
            return np.ascontiguousarray(A), qv, "file (last column of M)"
    prob = load(path, problem)
    d = None
    if covering is not None:
        try:
            d = np.array([float(x) for x in str(covering).replace(",", " ").split()])
        except ValueError:
            raise ProblemError(f"--covering must be numbers, got {covering!r}") from None
        if d.size == 0:
            raise ProblemError("--covering is empty")
    Maug = augment(prob.dense_M(), d)
    return Maug, prob.q.copy(), "--covering" if covering is not None else "all ones (default)"


def register(app: typer.Typer) -> None:
    app.command("pivot")(pivot)
