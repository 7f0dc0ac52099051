"""The ``lcpcli`` command line: a thin skin over the library.

Each subcommand lives in its own module of this package (``<name>_cmd.py``) and exposes
``register(app)``; the modules import numpy, scipy and h5py only inside the command bodies so
that ``lcpcli --help`` stays fast.  Errors become one line on stderr and an exit code:

* 0  solved (every problem solved, certificate checked)
* 1  not solved (``no_solution`` or ``unsolved``)
* 2  bad usage or bad input (malformed or missing file, wrong shapes, NaN/Inf, unknown option),
     or an output that cannot be written (``PATH: no space left on device``, permission denied)
* 3  internal error (a bug: please report it; ``LCPCLI_DEBUG=1`` shows the traceback)
* 129, 130, 143  hung up (SIGHUP), interrupted (Ctrl-C), terminated (SIGTERM): stopped cleanly
"""

from __future__ import annotations

import importlib
import os
import sys

import typer
import typer.core

from lcpcli import __version__
from lcpcli.cli import common, plain_params
from lcpcli.core.errors import (
    EXIT_BAD_INPUT,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_OK,
    STOP_SIGNALS,
    LcpError,
)
from lcpcli.core.text import one_line_warnings


def _click_exceptions():  # type: ignore[no-untyped-def]
    """typer >= 0.2x vendors click as ``typer._click``; older versions use click itself."""
    try:
        return importlib.import_module("typer._click.exceptions")
    except ImportError:
        return importlib.import_module("click.exceptions")


click_exc = _click_exceptions()
plain_params.install()  # plain str/int/float/Path coercion: no pydantic at start-up

EXIT_CODES_HELP = (
    "Exit codes: 0 solved; 1 not solved (no_solution or unsolved); "
    "2 bad usage or bad input; 3 internal error."
)

#: Subcommand modules, in the order ``--help`` lists them.
COMMAND_MODULES = [
    "solve_cmd",
    "convert_cmd",
    "methods_cmd",
    "contact_cmd",
    "pivot_cmd",
    "enumerate_cmd",
    "bench_cmd",
    "info_cmd",
]

app = typer.Typer(
    name="lcpcli",
    help="Linear complementarity problems: find z >= 0 with w = M z + q >= 0 and z^T w = 0 "
         "(and the mixed and box forms).",
    epilog=EXIT_CODES_HELP,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    context_settings={"help_option_names": ["-h", "--help"]},
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"lcpcli {__version__}")
        raise typer.Exit(EXIT_OK)


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                 help="Print the version and exit."),
) -> None:
    """Linear complementarity problems from the shell."""


for _name in COMMAND_MODULES:
    importlib.import_module(f"{__name__}.{_name}").register(app)


def error_line(message: str) -> None:
    """Print one error line on stderr."""
    text = " ".join(str(message).split())
    sys.stderr.write(f"lcpcli: error: {text}\n")


def _print_root_help() -> None:
    """The formatted top-level help, on stderr (bare ``lcpcli`` is a usage error)."""
    command = typer.main.get_command(app)
    with command.make_context("lcpcli", [], resilient_parsing=True) as ctx:
        sys.stderr.write(ctx.get_help() + "\n")


def _writable(stream: object) -> bool:
    """Whether ``stream`` can be written: not None (what Python makes of a standard stream
    closed at start), and when it has a descriptor, one open for writing (not closed since,
    not open for reading only).  A stream without one (a test's StringIO) can."""
    if stream is None:
        return False
    try:
        fd = stream.fileno()  # type: ignore[attr-defined]
    except (AttributeError, OSError, ValueError):
        return True
    try:
        import fcntl  # POSIX (a built-in module: no start-up cost)
    except ImportError:
        return True
    try:
        return fcntl.fcntl(fd, fcntl.F_GETFL) & os.O_ACCMODE in (os.O_WRONLY, os.O_RDWR)
    except OSError:
        return False


def _silence_stdout() -> None:
    """After a broken pipe: send what is still buffered for stdout to /dev/null, so the
    interpreter's final flush cannot fail (and print a traceback) on the closed pipe."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass


#: Set for a command unless the user set them: idle threads of the numerical libraries sleep
#: instead of spinning.  OpenBLAS' workers spin 2^28 cycles after numpy loads (0.06-0.1 s of
#: CPU per command, measured) and OpenMP's at the end of each parallel region; on a machine
#: with no core to spare (``--jobs`` = cores) that spin takes the CPU that the reader and
#: writer threads of a stacked batch need.  No batched kernel waits on them in a loop.
QUIET_THREADS = {"OPENBLAS_THREAD_TIMEOUT": "4", "OMP_WAIT_POLICY": "PASSIVE"}


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the app, map every failure to one stderr line and an exit code.

    Bare ``lcpcli`` prints the formatted help on stderr and exits 2 (a usage error; ``lcpcli
    --help`` prints it on stdout and exits 0).  A broken pipe on stdout (``lcpcli ... | head``)
    is not a failure: the exit code is the one the finished work earned (see
    :func:`lcpcli.cli.common.pending_exit`).
    """
    args = sys.argv[1:] if argv is None else list(argv)
    if not _writable(sys.stderr):  # 2>&-: no line can be shown, the exit code still tells
        sys.stderr = open(os.devnull, "w")  # noqa: SIM115 - for the life of the process
    stderr = sys.stderr
    sys.stderr = common.StderrGuard(stderr)  # type: ignore[assignment]
    for name, value in QUIET_THREADS.items():  # before numpy and the kernels load
        os.environ.setdefault(name, value)
    one_line_warnings()
    common.pending_exit(EXIT_OK)
    if not args:
        _print_root_help()
        sys.stderr = stderr
        sys.exit(EXIT_BAD_INPUT)
    stdout = sys.stdout
    sys.stdout = common.StdoutGuard(stdout)  # type: ignore[assignment]
    held = common.catch_stop_signals()  # SIGTERM, SIGHUP end a command as Ctrl-C does: cleanly
    try:
        code = app(args=args, standalone_mode=False, prog_name="lcpcli")
        sys.stdout.flush()  # a standard output that cannot take it fails here, as one line
    except click_exc.UsageError as exc:
        hint = f" (see '{exc.ctx.command_path} --help')" if exc.ctx else ""
        error_line(f"{exc.format_message()}{hint}")
        code = EXIT_BAD_INPUT
    except click_exc.ClickException as exc:
        error_line(exc.format_message())
        code = EXIT_BAD_INPUT
    except typer.Abort:
        code = EXIT_INTERRUPTED
    except LcpError as exc:
        error_line(str(exc))
        code = EXIT_BAD_INPUT
    except KeyboardInterrupt:  # (typer returns 130 for one raised inside a command)
        code = EXIT_INTERRUPTED
    except MemoryError:
        # valid data whose work does not fit this machine: the budgets of lcpcli.core.limits
        # stop the steps they can foresee; this is the one line for the rest (exit 2, as
        # for absurd sizes)
        error_line("out of memory: this problem needs more memory than this machine has "
                   "(try a sweeping method, -m pgs or -m psor, or a smaller problem)")
        code = EXIT_BAD_INPUT
    except (common.PipeClosed, BrokenPipeError):
        _silence_stdout()
        code = common.pending_exit()
    except Exception as exc:  # noqa: BLE001 - last line of defence: no tracebacks for users
        if os.environ.get("LCPCLI_DEBUG"):
            raise
        # a write no writer wrapped (every output file is: this is stdout): still one line
        from lcpcli.io.writing import output_error

        failed = output_error(exc, getattr(exc, "filename", None) or "standard output")
        if failed is not None:
            error_line(str(failed))
            code = EXIT_BAD_INPUT
        else:
            error_line(f"internal error: {type(exc).__name__}: {exc} "
                       f"(set LCPCLI_DEBUG=1 for the traceback)")
            code = EXIT_INTERNAL
    finally:
        sys.stdout = stdout
        common.release_stop_signals(held)
    if code in STOP_SIGNALS.values():  # Ctrl-C, SIGTERM or SIGHUP: 130, 143 or 129
        code = common.stopped_code()
        if not common.stop_said():  # the command's cleanup ran; nothing more to say
            sys.stderr.write(f"lcpcli: {common.stopped_word()}\n")
    if stdout is not None:
        try:
            stdout.flush()
        except OSError:  # the reader left after the last write, or a failure reported above
            _silence_stdout()
    sys.stderr = stderr
    sys.exit(code if isinstance(code, int) else EXIT_OK)
