"""Helpers shared by the subcommands: option parsing, consoles, exit codes, method help."""

from __future__ import annotations

import contextlib
import copy
import errno
import os
import signal
import sys
import threading
from collections.abc import Iterator
from typing import Any

import typer.core

from lcpcli.core.errors import (
    EXIT_BAD_INPUT,
    EXIT_NOT_SOLVED,
    EXIT_OK,
    EXIT_SOLVED,
    STOP_SIGNALS,
    OptionError,
    OutputError,
)
from lcpcli.core.text import option_name, plural

#: The exit code of the work finished so far (what a broken pipe on stdout exits with).
_PENDING = {"code": EXIT_OK}


class PipeClosed(Exception):  # noqa: N818 - the name says what happened, not "Error"
    """The reader of stdout went away (``lcpcli ... | head``).

    Deliberately not an OSError: typer turns an EPIPE OSError into exit status 1, which reads
    as "not solved"; ``lcpcli.cli.main`` exits with :func:`pending_exit` instead.
    """


#: One-character ASCII stand-ins (the columns stay aligned) of the non-ASCII characters that
#: the renderers and rich write, for a stream whose encoding lacks them; anything else becomes
#: the encoding's replacement character.
ASCII_STAND_INS = str.maketrans({
    "…": "~", "─": "-", "━": "-", "│": "|", "┃": "|", "╱": "/", "╲": "\\", "▒": "#",
    "█": "#", "░": ".", "┌": "+", "┐": "+", "└": "+", "┘": "+", "├": "+", "┤": "+", "┬": "+",
    "┴": "+", "┼": "+", "ú": "u",
})


def stdout_not_open() -> OutputError:
    """The one error of a standard output that cannot be written at all: closed (``>&-``,
    where Python's ``sys.stdout`` is None) or open for reading only (``1</dev/null``)."""
    return OutputError("standard output", "not open for writing (closed, as by '>&-')")


class StdoutGuard:
    """sys.stdout as the commands see it: a broken pipe raises :class:`PipeClosed`; a
    standard output that is not open for writing (``>&-``: ``stream`` None; ``EBADF``) raises
    :func:`stdout_not_open` (one line, exit 2, as a full disk does); text the stream's
    encoding cannot write (``PYTHONIOENCODING=ascii``, a legacy code page) is written with
    :data:`ASCII_STAND_INS` and replacement characters instead of failing."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        if self._stream is None:
            raise stdout_not_open()
        try:
            try:
                return self._stream.write(text)
            except UnicodeEncodeError:
                encoding = getattr(self._stream, "encoding", None) or "ascii"
                safe = text.translate(ASCII_STAND_INS).encode(encoding, errors="replace")
                self._stream.write(safe.decode(encoding))
                return len(text)
        except BrokenPipeError:
            raise PipeClosed() from None
        except OSError as exc:
            if exc.errno == errno.EBADF:
                raise stdout_not_open() from None
            raise

    def flush(self) -> None:
        if self._stream is None:
            return
        try:
            self._stream.flush()
        except BrokenPipeError:
            raise PipeClosed() from None
        except OSError as exc:
            if exc.errno == errno.EBADF:
                raise stdout_not_open() from None
            raise

    def isatty(self) -> bool:
        return self._stream is not None and self._stream.isatty()

    def __getattr__(self, name: str) -> Any:
        if self._stream is None:
            raise AttributeError(name)
        return getattr(self._stream, name)


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP (``signum``), turned into an interrupt so that what is being written
    is closed cleanly (a batch's output) or removed (the temporary file of an atomic output),
    as after Ctrl-C."""

    def __init__(self, signum: int = signal.SIGTERM) -> None:
        super().__init__()
        self.signum = signum


#: The signals :func:`catch_stop_signals` turns into :class:`Terminated` (Ctrl-C is Python's
#: own KeyboardInterrupt): every stop signal of :data:`STOP_SIGNALS` but SIGINT.
CAUGHT_SIGNALS = tuple(sig for sig in STOP_SIGNALS if sig != signal.SIGINT)

#: The word of a stopped command's line (``lcpcli: terminated``), by signal.
STOP_WORDS = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated",
              **({signal.SIGHUP: "hung up"} if hasattr(signal, "SIGHUP") else {})}

#: How a command was stopped: ``signal`` SIGTERM or SIGHUP once :func:`on_stop_signal` ran
#: (else an interrupt is Ctrl-C), ``said`` once the command said so itself
#: (:func:`say_stopped`); ``hook``: the ``sys.unraisablehook`` that
#: :func:`catch_stop_signals` replaced.
_STOPPED: dict[str, Any] = {"signal": None, "said": False, "hook": None}


def on_stop_signal(signum: int, frame: Any) -> None:
    _STOPPED["signal"] = signum
    raise Terminated(signum)


def install_stop_handlers() -> list[tuple[int, Any]]:
    """:func:`on_stop_signal` for each of :data:`CAUGHT_SIGNALS` that has its default action
    (an ignored one stays ignored: ``nohup lcpcli ...`` runs on after the terminal closed),
    in the main thread only; returns the ``(signal, previous handler)`` pairs that
    :func:`restore_handlers` puts back."""
    if threading.current_thread() is not threading.main_thread():
        return []
    return [(sig, signal.signal(sig, on_stop_signal)) for sig in CAUGHT_SIGNALS
            if signal.getsignal(sig) == signal.SIG_DFL]


def restore_handlers(installed: list[tuple[int, Any]]) -> None:
    """Undo :func:`install_stop_handlers` (``installed``: what it returned)."""
    for sig, handler in installed:
        signal.signal(sig, handler)


def catch_stop_signals() -> Any:
    """Have SIGTERM (``kill``, ``timeout``, a job scheduler) and SIGHUP (the terminal closed)
    stop a command as Ctrl-C does: every command then ends through its cleanup (no temporary
    file left beside an output) with exit code 143 or 129 (:func:`install_stop_handlers`:
    the main thread only, an ignored signal stays ignored).  An interrupt that Python can
    only ignore is delivered again (:func:`_redeliver`).  Returns what
    :func:`release_stop_signals` restores (None: nothing changed)."""
    _STOPPED["signal"], _STOPPED["said"] = None, False
    if threading.current_thread() is not threading.main_thread():
        return None
    hook = _STOPPED["hook"] = sys.unraisablehook
    sys.unraisablehook = _redeliver
    return install_stop_handlers(), hook


def release_stop_signals(held: Any) -> None:
    """Undo :func:`catch_stop_signals` (``held``: what it returned)."""
    if held is not None:
        restore_handlers(held[0])
        sys.unraisablehook = held[1]


#: How long after an ignored interrupt its signal is sent again (:func:`_redeliver`).
REDELIVER_SECONDS = 0.01


def _redeliver(unraisable: Any) -> None:
    """``sys.unraisablehook`` while a command runs: an interrupt raised where Python can only
    ignore it (the signal handler ran inside a weak reference's callback or a ``__del__``:
    "Exception ignored in ..."; h5py's object registry is one) is not lost: its signal is
    sent to this process again, and the handler raises it where the command can stop (a
    SIGTERM was swallowed so, and the command ran on to its end with exit code 0)."""
    exc = unraisable.exc_value
    if isinstance(exc, KeyboardInterrupt):
        # from another thread, a moment later: sent from here, the handler would run (and
        # be ignored) inside this hook again
        again = threading.Timer(REDELIVER_SECONDS, os.kill, (os.getpid(), exc.signum
                                if isinstance(exc, Terminated) else signal.SIGINT))
        again.daemon = True
        again.start()
        return
    (_STOPPED.get("hook") or sys.__unraisablehook__)(unraisable)


def say_stopped(text: str) -> None:
    """A stopped command's own line on stderr (what it finished): ``lcpcli.cli.main`` then
    adds none."""
    sys.stderr.write(text + "\n")
    _STOPPED["said"] = True


def stopped_signal(exc: BaseException | None = None) -> int:
    """The signal that stopped the command: ``exc``'s (a :class:`Terminated`), else the one
    :func:`on_stop_signal` recorded, else SIGINT (Ctrl-C)."""
    if isinstance(exc, Terminated):
        return exc.signum
    return _STOPPED["signal"] or signal.SIGINT


def stopped_code(exc: BaseException | None = None) -> int:
    """The exit code of a command stopped by a signal (:data:`STOP_SIGNALS`): 143 after
    SIGTERM, 129 after SIGHUP, 130 after Ctrl-C (``exc``: as :func:`stopped_signal`)."""
    return STOP_SIGNALS[stopped_signal(exc)]


def stopped_word(exc: BaseException | None = None) -> str:
    """``terminated``, ``hung up`` or ``interrupted``: the word of the stopped command's line
    (``exc``: as :func:`stopped_signal`)."""
    return STOP_WORDS[stopped_signal(exc)]


def stop_said() -> bool:
    """Whether the stopped command said so itself (:func:`say_stopped`)."""
    return bool(_STOPPED["said"])


class StderrGuard:
    """sys.stderr as the commands see it: when its reader went away (a broken pipe: ``2>&1 |
    head -1``, a log collector that stopped) or its descriptor cannot be written, the
    diagnostics are lost, never the work or its exit code (a note on a broken stderr stopped
    ``solve -m enum`` with exit 1): the failed line and every later one are dropped, and
    the descriptor is pointed at the null device so that no later flush fails."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream
        self._lost = False

    def write(self, text: str) -> int:
        if not self._lost:
            try:
                return self._stream.write(text)
            except OSError:
                self._lose()
        return len(text)

    def flush(self) -> None:
        if not self._lost:
            try:
                self._stream.flush()
            except OSError:
                self._lose()

    def _lose(self) -> None:
        self._lost = True
        with contextlib.suppress(OSError, ValueError, AttributeError):
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self._stream.fileno())
            os.close(devnull)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def pending_exit(code: int | None = None) -> int:
    """Record (with ``code``) or read the exit code the finished work has earned.

    Commands record it once the work is done and before printing, so that a reader that
    closes the pipe early (``lcpcli solve p.json | head -1``) does not turn a solved problem
    into a failure (exit 0 when solved; 1 stays 1).
    """
    if code is not None:
        _PENDING["code"] = code
    return _PENDING["code"]


def duration(seconds: float) -> str:
    """``"42 s"``, ``"3.5 min"``, ``"2.1 h"``, ``"3.0 days"`` (estimates on stderr)."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 2 * 3600:
        return f"{seconds / 60:.1f} min"
    if seconds < 2 * 86400:
        return f"{seconds / 3600:.1f} h"
    if seconds < 1000 * 365 * 86400:
        return f"{seconds / 86400:,.1f} days"
    return f"{seconds / (365 * 86400):.1e} years"




class MethodListCommand(typer.core.TyperCommand):
    """A command whose ``--help`` ends with the registered solver methods (built lazily)."""

    def format_epilog(self, ctx: Any, formatter: Any) -> None:
        from lcpcli.solvers.registry import methods

        rows = []
        for name, m in methods().items():
            alias = f" (alias: {', '.join(m.aliases)})" if m.aliases else ""
            kinds = "/".join(k.upper() for k in m.kinds)
            rows.append((name + alias, f"{m.summary}. Classes: {m.matrix_classes}. "
                                       f"Problems: {kinds}."))
        with formatter.section("Methods"):
            formatter.write_dl(rows)
        super().format_epilog(ctx, formatter)


def parse_key_values(pairs: list[str] | None) -> dict[str, str]:
    """``["omega=1.2", "max-iter=50"]`` -> ``{"omega": "1.2", "max_iter": "50"}``."""
    out: dict[str, str] = {}
    for item in pairs or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise OptionError(f"method option must look like KEY=VALUE, got {item!r}")
        out[option_name(key.strip())] = value.strip()
    return out


def _console_class() -> Any:
    """rich's Console, except that a broken pipe raises BrokenPipeError (rich's own handler
    exits with status 1, which reads as "not solved" under ``set -o pipefail``), and that
    tables are drawn with rules only on a terminal without ``NO_COLOR``: elsewhere (a pipe, a
    file, ``NO_COLOR``) the same rows come as plain columns (two spaces apart, no box
    characters), every table at any depth (rich renders nested renderables through
    :meth:`render`).  A terminal that cannot draw boxes (``TERM=dumb`` or ``unknown``, as
    Emacs' shell sets it: rich's ``is_dumb_terminal``, which also turns colour and styles
    off) is rendered for as an ASCII-only stream: rich's own substitutes, ASCII rules
    (``+--+``, ``|``: ``box.ASCII``) and ``-`` bars, in the same widths."""
    from rich.console import Console  # rich only where something is rendered (start-up)
    from rich.table import Table

    class PipeConsole(Console):
        def on_broken_pipe(self) -> None:
            self.quiet = True
            raise PipeClosed()

        @property
        def options(self) -> Any:
            options = super().options
            if self.is_dumb_terminal:
                options.encoding = "ascii"  # what ConsoleOptions.ascii_only reads
            return options

        def render(self, renderable: Any, options: Any = None) -> Any:
            if isinstance(renderable, Table) and renderable.box is not None \
                    and (self.no_color or not self.is_terminal):
                renderable = copy.copy(renderable)
                renderable.box = None
            return super().render(renderable, options)

    return PipeConsole


def stdout_console() -> Any:
    """A rich console on stdout (colour only on a TTY and never with NO_COLOR)."""
    return _console_class()(highlight=False, force_terminal=is_terminal(sys.stdout))


def stderr_console() -> Any:
    return _console_class()(stderr=True, highlight=False, force_terminal=is_terminal(sys.stderr))


def progress_allowed() -> bool:
    """Whether a progress bar may be drawn on stderr: a terminal, and no ``NO_COLOR`` (the one
    rule of every command's live display)."""
    return is_terminal(sys.stderr) and not os.environ.get("NO_COLOR")


def is_terminal(stream: Any) -> bool:
    """Whether ``stream`` is a terminal: the one rule of both consoles and the progress bars,
    without importing rich.  rich's environment overrides first (``TTY_COMPATIBLE`` 1 / 0,
    then ``FORCE_TERMINAL`` as rich 13 read it, then ``FORCE_COLOR`` set and not empty: a
    terminal), else the stream's ``isatty``."""
    env = os.environ
    tty = env.get("TTY_COMPATIBLE", "")
    if tty in ("0", "1"):
        return tty == "1"
    force = env.get("FORCE_TERMINAL")
    if force is not None:
        return force.lower() not in ("", "0", "false", "no")
    color = env.get("FORCE_COLOR")
    if color is not None:
        return color != ""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def exit_code_for(statuses: list[str]) -> int:
    """0 if every status is ``solved``, 1 otherwise (bad input is raised, not returned)."""
    from lcpcli.core.result import Status  # imports numpy: not at --help time

    code = EXIT_SOLVED if all(s == Status.SOLVED for s in statuses) else EXIT_NOT_SOLVED
    return pending_exit(code)


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold the stop signals (:data:`STOP_SIGNALS`) back while the block runs (main thread,
    where the platform can): a Ctrl-C arriving mid-write is delivered after it, so a line is
    written whole."""
    block = getattr(signal, "pthread_sigmask", None)
    if block is None or threading.current_thread() is not threading.main_thread():
        yield
        return
    old = block(signal.SIG_BLOCK, set(STOP_SIGNALS))
    try:
        yield
    finally:
        block(signal.SIG_SETMASK, old)


def write_json_line(obj: Any) -> None:
    """One JSON object on stdout, as one whole line (nothing else goes there with ``--json``;
    non-finite numbers as ``null``: :func:`lcpcli.core.numeric.json_text`); an interrupt
    never cuts a line: it takes effect after the line is out."""
    from lcpcli.core.numeric import json_text  # imports numpy: not at --help time

    line = json_text(obj) + "\n"
    with signals_deferred():
        sys.stdout.write(line)
        sys.stdout.flush()


__all__ = ["EXIT_BAD_INPUT", "MethodListCommand", "PipeClosed", "StderrGuard", "StdoutGuard",
           "Terminated",
           "catch_stop_signals", "duration", "exit_code_for", "install_stop_handlers",
           "is_terminal", "on_stop_signal", "parse_key_values", "pending_exit", "plural",
           "progress_allowed", "release_stop_signals", "restore_handlers", "say_stopped",
           "stderr_console", "stdout_console", "stop_said", "stopped_code", "stopped_signal",
           "stopped_word", "write_json_line"]
