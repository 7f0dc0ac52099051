"""``lcpcli pivot``: Dai & Drumwright's principal pivoting transform, for one basis or a
sequence of bases."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import typer

from lcpcli.cli.common import stdout_console, write_json_line
from lcpcli.cli.export import EXACT_HELP, check_export_options, check_format, emit, note
from lcpcli.core.errors import EXIT_OK, OptionError, ProblemError


def pivot(
    file: str = typer.Argument(..., metavar="FILE",
                               help="Problem file with q and M; M may have n + 1 columns (the "
                                    "last is the artificial variable z0, JSON/NPZ)."),
    dependent: list[str] = typer.Option(..., "--dependent", "-d",
                                        help="Dependent tuple w' (n names), e.g. 'z0,w2,z3'. "
                                             "Repeat for a sequence of bases."),
    independent: str = typer.Option(None, "--independent", "-i",
                                    help="Independent tuple z' (n+1 names), e.g. "
                                         "'w1,w3,z2,z1' [default: the others, w's, z's, z0]. "
                                         "With one --dependent only."),
    driving: list[str] = typer.Option(None, "--driving",
                                      help="Driving variable (one of z'): its column of M', "
                                           "Lemke's ratio test and the blocking variable. "
                                           "Repeat once per --dependent."),
    follow: bool = typer.Option(False, "--follow",
                                help="From the (one) basis and --driving, follow Lemke's rule "
                                     "basis by basis until z0 leaves or a ray. The start must "
                                     "be on Lemke's path: w1..wn (any basis without z0) with "
                                     "--driving z0, or a basis with z0 and a variable of the "
                                     "pair with neither dependent."),
    covering: str = typer.Option(None, "--covering",
                                 help="Artificial column when M has n columns, e.g. '1,2,1' "
                                      "[default: all ones]."),
    full: bool = typer.Option(False, "--full", help="Also print the whole pivoted tableau."),
    any_basis: bool = typer.Option(False, "--any-basis",
                                   help="Allow w_i and z_i both dependent (non-complementary)."),
    layout: str = typer.Option("dictionary", "--layout",
                               help="Tableaux: dictionary (w' = q' + M' z') or murty "
                                    "(w - M z - d z0 = q)."),
    pivot_step: int = typer.Option(None, "--pivot", metavar="K", min=0,
                                   help="Show step K of the sequence alone (0 = the first "
                                        "basis; also with --json)."),
    step: bool = typer.Option(False, "--step",
                              help="One basis per screen, keys n(ext)/b(ack)/q(uit); without "
                                   "a terminal every step is printed."),
    fmt: str = typer.Option("text", "--format",
                            help="text, markdown or latex (lecture notes; stdout or -o)."),
    output: str = typer.Option(None, "--output", "-o", metavar="PATH",
                                help="Write the markdown/latex export to this file "
                                     "(atomically; never over the input)."),
    problem: str = typer.Option(None, "--problem", "-p",
                                help="Problem (group) name inside an HDF5 file."),
    as_json: bool = typer.Option(False, "--json",
                                 help="Print one JSON object on stdout and nothing else."),
    exact: bool = typer.Option(None, "--exact/--no-exact", show_default=False,
                               help=EXACT_HELP),
) -> int:
    """Principal pivoting transform (Dai & Drumwright): q' and M'_driving of w' = q' + M' z'.

    Variable names are 1-based: w1..wn, z1..zn; z0 is the artificial variable (alias
    z{n+1}, its position in Dai & Drumwright's z). With --driving, Lemke's ratio test on M'_driving
    names the blocking variable and the next Lemke step. Exit codes: 0 done; 2 bad input
    (bad basis, singular M^{alpha beta}, bad file, bad option).
    """

    from lcpcli.analysis.pivoting import parse_tuple, parse_var, principal_pivot
    from lcpcli.solvers.trace.path import driving_step
    from lcpcli.solvers.trace.path import follow as follow_path
    from lcpcli.solvers.trace.tableau import LAYOUTS

    fmt = check_format(fmt)
    layout = layout.lower()
    if layout not in LAYOUTS:
        raise OptionError(f"--layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
    if output is not None and fmt == "text":
        raise OptionError("-o writes the --format markdown or latex export; give --format")
    check_export_options(fmt, output, [file], as_json)
    driving = list(driving or [])
    if independent is not None and len(dependent) > 1:
        raise OptionError("--independent goes with a single --dependent (later bases list "
                          "their independent variables in the original order)")
    if follow and (len(dependent) != 1 or len(driving) != 1):
        raise OptionError("--follow starts from one --dependent basis and one --driving "
                          "variable")
    if not follow and driving and len(driving) != len(dependent):
        raise OptionError(f"give one --driving per --dependent ({len(dependent)} bases, "
                          f"{len(driving)} driving variables)")
    Maug, q, source = load_augmented(file, covering, problem)
    n = q.shape[0]
    deps = [parse_tuple(d, n) for d in dependent]
    ind = parse_tuple(independent, n) if independent is not None else None
    drvs = [parse_var(d, n) for d in driving]
    if follow:
        items = follow_path(Maug, q, deps[0], ind, drvs[0], full=full, any_basis=any_basis)
    else:
        items = []
        for k, dep in enumerate(deps):
            drv = drvs[k] if drvs else None
            t = principal_pivot(Maug, q, dep, ind if k == 0 else None, driving=drv, full=full,
                                any_basis=any_basis)
            items.append((t, driving_step(t, Maug) if drv is not None else None))
    if as_json:
        shown = items
        if pivot_step is not None:  # step K alone, as the printed sequence shows it
            from lcpcli.cli.stepper import pick

            shown = pick(items, pivot_step, list(range(len(items))), "this sequence")
        objs = []
        for t, st in shown:
            obj = t.to_dict()
            obj["ratio_test"] = st
            objs.append(obj)
        payload = dict(objs[0]) if len(objs) == 1 else {"steps": objs}
        payload["file"] = file
        payload["artificial_column"] = source
        write_json_line(payload)
        if fmt == "text":
            return EXIT_OK
    from lcpcli.cli.render.pivot import pivot_pages

    items, Maug, q = _exact_items(items, Maug, q, exact)
    pages = pivot_pages(items, Maug, q, source, layout)
    emit(pages, fmt=fmt, output=output, inputs=[file], pivot=pivot_step,
         numbers=list(range(len(pages))), labels=[f"step {k}" for k in range(len(pages))],
         step=step, what="this sequence", console=stdout_console(),
         title=f"lcpcli pivot {file}")
    if output is not None:
        sys.stderr.write(f"lcpcli: wrote {output}\n")
    return EXIT_OK


def _exact_items(items: list[tuple[Any, Any]], Maug: Any, q: Any,
                 flag: bool | None) -> tuple[list[tuple[Any, Any]], Any, Any]:
    """The bases recomputed in fractions for the pages (``--exact``, or by default on small
    rational data), with Lemke's rule applied again on the exact numbers."""
    from lcpcli.solvers.trace.exact import (
        AUTO_MAX_N,
        FLAG_MAX_ABS,
        FLAG_MAX_DENOMINATOR,
        exact_transform,
        rational_array,
    )
    from lcpcli.solvers.trace.path import driving_step

    if flag is False or (flag is None and q.shape[0] > AUTO_MAX_N):
        return items, Maug, q
    limits = (FLAG_MAX_DENOMINATOR, FLAG_MAX_ABS) if flag else ()
    Me, qe = rational_array(Maug, *limits), rational_array(q, *limits)
    if Me is None or qe is None:
        if flag:
            note("--exact: the data are not fractions with small denominators; the pages "
                 "stay in decimals")
        return items, Maug, q
    out = []
    for t, step in items:
        te = exact_transform(t, Me, qe)
        se = driving_step(te, Me) if step is not None else None
        if se is not None and se.get("blocking") != step.get("blocking"):
            note("--exact: in exact arithmetic Lemke's rule blocks a different variable than "
                 "in floating point (a tie decided by rounding)")
        out.append((te, se))
    return out, Me, qe


def load_augmented(path: str, covering: str | None = None,
                   problem: str | None = None) -> tuple[Any, Any, str]:
    """Read ``q`` and the ``n x (n+1)`` matrix ``[M, d]`` of a problem file.

    JSON and NPZ files may store ``M`` with ``n + 1`` columns (the artificial column last,
    as in Dai & Drumwright); otherwise the file holds an ordinary LCP and ``covering`` (text such as
    ``"1,2,1"``; default all ones) supplies the artificial column.  Returns ``(Maug, q, where)``
    with ``where`` saying where the artificial column came from.
    """

    import numpy as np  # file reading happens in the command body (start-up budget)

    from lcpcli.analysis.pivoting import augment
    from lcpcli.core.limits import check_dense_work
    from lcpcli.io import detect_format, load
    from lcpcli.io.files import decode_text, parse_json, read_input_bytes
    from lcpcli.io.npz_format import read_augmented

    kind = detect_format(path)
    raw_M: Any = None
    raw_q: Any = None
    try:
        if kind == "json" and str(path) != "-":
            data = parse_json(decode_text(read_input_bytes(path)))
            if isinstance(data, dict) and isinstance(data.get("M"), list):
                raw_M, raw_q = data["M"], data.get("q")
        elif kind == "npz":
            found = read_augmented(Path(path))
            if found is not None:
                raw_M, raw_q = found
    except ProblemError:
        raw_M = None  # the regular reader below gives the proper one-line message
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
    check_dense_work(prob.n, "pivot works on a dense tableau of M", cubic=False, source=path)
    Maug = augment(prob.dense_M(), d)
    return Maug, prob.q.copy(), "--covering" if covering is not None else "all ones (default)"


def register(app: typer.Typer) -> None:
    app.command("pivot")(pivot)
