"""``lcpcli solve``: read a problem, call :func:`lcpcli.solve`, render the certified result."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from lcpcli.cli.common import (
    MethodListCommand,
    exit_code_for,
    parse_key_values,
    stdout_console,
    write_json_line,
)
from lcpcli.cli.export import EXACT_HELP, check_export_options, check_format, emit, exact_view
from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.solvers import DEFAULT_METHOD


def solve(
    file: str = typer.Argument(..., metavar="FILE",
                               help="Problem file (.json, .npz, .h5, .dat); '-' reads JSON "
                                    "from stdin."),
    more_files: list[str] = typer.Argument(None, metavar="FILE", show_default=False,  # noqa: B008
                                           help="More files, folders or globs: a batch "
                                                "(see docs/batch.md)."),
    method: str = typer.Option(DEFAULT_METHOD, "--method", "-m",
                               help="Solver method (listed below)."),
    tol: float = typer.Option(None, "--tol",
                              help="Tolerance on the certified error for the verdict 'solved' "
                                   "[default: 1e-8, every method's default_tol]."),
    max_iter: int = typer.Option(None, "--max-iter", help="Pivot / iteration limit."),
    covering: str = typer.Option(None, "--covering",
                                 help="Lemke covering vector d > 0, e.g. '1,2,1', for -m "
                                      "lemke, lemke-revised or lemke-tableau "
                                      "[default: all ones]."),
    omega: float = typer.Option(None, "--omega",
                                help="Relaxation parameter of psor, 0 < omega < 2."),
    z0: Path = typer.Option(None, "--z0", metavar="FILE",
                            help="Warm start z: a JSON list, a result JSON with \"z\" (a "
                                 "previous --json: its basis), or an NPZ/NPY array. auto, bpp "
                                 "and the pivoting methods first pivot (BPP) from its basis, "
                                 "then solve cold if needed; pgs, psor, newton, newton-min start "
                                 "from z. Stacked inputs: a previous stacked result file "
                                 "(.h5/.npz), each problem from its basis."),
    option: list[str] = typer.Option(None, "--option", "-O", metavar="KEY=VALUE",
                                     help="Other method option (repeatable)."),
    problem: str = typer.Option(None, "--problem", "-p",
                                help="Problem (group) name inside an HDF5 file, or one problem "
                                     "of a stacked file (name or index)."),
    as_json: bool = typer.Option(False, "--json",
                                 help="Print one JSON object on stdout and nothing else. "
                                      "Batch: one object per problem per line (with "
                                      "--output: one summary object)."),
    output: str = typer.Option(None, "--output", "-o", metavar="PATH",
                                help="Also write the JSON result to this file (atomically). "
                                     "Batch: a .jsonl/.ndjson, .csv or .h5/.hdf5 result "
                                     "file, written incrementally (.npz: stacked inputs)."),
    recursive: bool = typer.Option(False, "--recursive", "-r",
                                   help="Batch: look for problem files in sub-folders too."),
    jobs: int = typer.Option(None, "--jobs", "-j", min=1,
                             help="Batch: worker processes (stacked files: threads) "
                                  "[default: number of cores]."),
    resume: bool = typer.Option(False, "--resume",
                                help="Batch: skip problems already in --output."),
    timeout: float = typer.Option(None, "--timeout",
                                  help="Batch: seconds per problem; a problem that runs over "
                                       "is stopped and recorded as unsolved (timeout)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Batch: no progress bar."),
    scheduler: str = typer.Option(None, "--scheduler",
                                  help="Batch: run on the Dask cluster at this address "
                                       "(e.g. tcp://host:8786; needs lcpcli[dask])."),
    backend: str = typer.Option(None, "--backend",
                                help="Stacked files: the batched kernels' backend: cpu, c (the "
                                     "single-source kernels on the CPU), cuda (a CUDA device; "
                                     "needs lcpcli[gpu]) or auto (cuda for large stacks when "
                                     "a device is present) [default: cpu]."),
    trace: bool = typer.Option(False, "--trace",
                               help="Print every step: Lemke's pivots (lemke, lemke-tableau, "
                                    "lemke-revised), principal pivots (murty, dantzig), a "
                                    "sweep table (pgs, psor); with --json the steps are a "
                                    "list under \"trace\". One problem only."),
    layout: str = typer.Option(None, "--layout",
                               help="Trace tableaux: dictionary (Dai & Drumwright: "
                                    "w' = q' + M' z') or murty (textbook: w - M z - d z0 = q) "
                                    "[default: "
                                    "dictionary]. Implies --trace."),
    pivot_step: int = typer.Option(None, "--pivot", metavar="K", min=0,
                                   help="Trace: show step K alone (0 = the initial tableau; with "
                                        "--json the trace list holds it alone). Implies "
                                        "--trace."),
    step: bool = typer.Option(False, "--step",
                              help="Trace: one step per screen, keys n(ext)/b(ack)/q(uit); "
                                   "without a terminal every step is printed. Implies "
                                   "--trace."),
    fmt: str = typer.Option("text", "--format",
                            help="Trace output: text, markdown or latex (lecture notes; on "
                                 "stdout, or in the -o FILE). Implies --trace unless text."),
    exact: bool = typer.Option(None, "--exact/--no-exact", show_default=False,
                               help="Trace: " + EXACT_HELP + " --exact implies --trace."),
) -> int:
    """Solve an LCP: find z >= 0 with w = M z + q >= 0 and z^T w = 0.

    The answer is certified: the componentwise error (see the README) is recomputed from M and
    q; 'solved' is printed only when it is below the tolerance (1e-16 <= --tol <= 1e-2). For a
    P-matrix of a known class a bound on ||z - z*||_inf is shown too. Exit codes: 0 solved; 1
    not solved (no_solution or unsolved); 2 bad usage or bad input; 3 internal error.
    """
    from lcpcli.api import solve as solve_problem
    from lcpcli.core.numeric import json_text
    from lcpcli.io import check_output, load, write_atomic_text
    from lcpcli.solvers.options import positive_int

    opts: dict[str, object] = parse_key_values(option)
    if max_iter is not None:  # checked up front, by the rule of -O max_iter=
        try:
            opts["max_iter"] = positive_int(max_iter)
        except ValueError as exc:
            raise OptionError(f"option 'max_iter' (--max-iter): {exc}") from None
    if covering is not None:
        opts["covering"] = covering
    if omega is not None:
        opts["omega"] = omega
    if backend is not None:  # unknown, or cuda without a device: one line, exit 2
        from lcpcli.solvers.batched import set_default_backend

        set_default_backend(backend)
    from lcpcli.cli.batch_run import run_batch_command, wants_batch

    files = [file, *(more_files or [])]
    batch = {"recursive": recursive, "jobs": jobs, "resume": resume, "timeout": timeout,
             "quiet": quiet, "scheduler": scheduler}

    fmt = check_format(fmt)
    trace = (trace or layout is not None or pivot_step is not None or step or fmt != "text"
             or bool(exact))
    if wants_batch(files, output, problem=problem, **batch):
        from lcpcli.io.stack.results import is_stack_results

        if z0 is not None and is_stack_results(z0):  # a previous stack's results: per problem
            batch["warm"] = str(z0)
        elif z0 is not None:  # one warm start for problems of any size: the vector limit only
            from lcpcli.io.warmstart import load_z0

            opts["z0"] = load_z0(z0)
        if trace:
            raise OptionError("--trace (and --layout, --pivot, --step, --format) shows one "
                              "problem's steps; it does not apply to a batch")
        return run_batch_command(files, method=method, tol=tol, opts=opts, problem=problem,
                                 as_json=as_json, output=output, **batch)
    if trace:
        method = _traced_method(method)
        opts["trace"] = True
        layout = _check_layout(layout)
        check_export_options(fmt, output, [file], as_json)
    if output is not None:  # before any work: never the input, a device or a link
        check_output(output, inputs=[file, z0], stdout=False)
    from lcpcli.api import dense_check

    prob = load(file, problem, check_dense=dense_check(method))  # the budget, from the header
    if z0 is not None:  # n values, checked from the header before it is decompressed
        from lcpcli.io.warmstart import load_z0

        opts["z0"] = load_z0(z0, n=prob.n)
    if trace and method == "auto":
        from lcpcli.solvers.registry import get_method

        # auto's own options first (--covering is Lemke's: refused as without --trace)
        get_method("auto").parse_options({k: v for k, v in opts.items() if k != "trace"})
        method = _traced_auto(prob.kind)
    try:
        warm = opts.pop("z0", None)  # lcpcli.solve's warm start (the basis of z0)
        result = solve_problem(prob, method, tol=tol, warm=warm, **opts)
    except ProblemError as exc:  # a work budget (lcpcli.core.limits) refused it: name the file
        raise exc.with_source(file) from None
    payload = result.to_dict(file=file)
    from lcpcli.analysis.bounds import forward_error_bound

    forward = forward_error_bound(prob, result.z) if result.solved else None
    payload["forward_error_bound"] = forward.as_dict() if forward is not None else None
    code = exit_code_for([result.status])
    if result.trace is not None:  # the teaching view; the JSON above keeps the floats

        result.trace = exact_view(prob, method, exact, opts, result.trace)
    if output is not None and fmt == "text":
        write_atomic_text(output, json_text(payload) + "\n")
    if as_json:
        if pivot_step is not None and payload.get("trace") is not None:
            from lcpcli.cli.render.pivot import step_entries

            payload["trace"] = step_entries(payload["trace"], pivot_step)
        write_json_line(payload)
        if result.trace is not None and fmt != "text":
            _show_trace(result.trace, fmt, layout, output, file, pivot_step, False)
    else:
        from lcpcli.cli.render.common import render_result

        console = stdout_console()
        if result.trace is not None:
            on_stdout = _show_trace(result.trace, fmt, layout, output, file, pivot_step, step)
            if on_stdout or pivot_step is not None:
                return exit_code_for([result.status])
            console.print()
        console.print(render_result(result, prob, file, forward))
    return code


#: With ``--trace``, ``auto`` runs the first of these that handles the problem's kind (Lemke
#: for an LCP, Cottle-Dantzig for a box LCP): auto picks by matrix class, the trace is a
#: textbook method's.
TRACED_AUTO = ("lemke", "dantzig")


def _traced_method(method: str) -> str:
    """The method that runs with ``--trace``: one with a replica (``auto`` stays ``auto`` until
    the problem's kind is known, see :func:`_traced_auto`)."""
    from lcpcli.solvers.registry import get_method

    if method != "auto" and "trace" not in get_method(method).options:
        raise OptionError(f"--trace: method '{method}' has no step-by-step replica (methods "
                          f"with one: {', '.join(_replicas())})")
    return method


def _traced_auto(kind: str) -> str:
    """``auto`` with ``--trace`` on a problem of ``kind``: the first of :data:`TRACED_AUTO`
    that handles it; OptionError naming the methods with a replica when none does."""
    from lcpcli.solvers.registry import get_method

    for name in TRACED_AUTO:
        if kind in get_method(name).kinds:
            return name
    raise OptionError(f"--trace: no method with a step-by-step replica handles {kind.upper()} "
                      f"problems (methods with one: {', '.join(_replicas())}); solve without "
                      f"--trace")


def _replicas() -> list[str]:
    """The methods with a step-by-step replica (option ``trace``)."""
    from lcpcli.solvers.registry import methods

    return [name for name, m in methods().items() if "trace" in m.options]


def _check_layout(layout: str | None) -> str:
    from lcpcli.solvers.trace.tableau import LAYOUTS

    value = (layout or LAYOUTS[0]).lower()
    if value not in LAYOUTS:
        raise OptionError(f"--layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
    return value


def _show_trace(trace: list, fmt: str, layout: str, output: str | None, file: str,
                pivot_step: int | None, step: bool) -> bool:
    """The trace on the terminal or as an export; True when the export used stdout."""

    from lcpcli.cli.render.pivot import full_pages, step_labels, step_numbers, step_pages

    whole = pivot_step is None and not step
    pages = full_pages(trace, layout) if whole else step_pages(trace, layout)
    on_stdout = emit(pages, fmt=fmt, output=output, inputs=[file], pivot=pivot_step,
                     numbers=step_numbers(trace), labels=step_labels(trace), step=step,
                     what="this trace", console=stdout_console(), title=f"lcpcli trace of {file}")
    if fmt != "text" and output is not None:
        sys.stderr.write(f"lcpcli: wrote {output}\n")
    return on_stdout


def register(app: typer.Typer) -> None:
    app.command("solve", cls=MethodListCommand)(solve)
