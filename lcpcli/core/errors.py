"""Exceptions and the process exit codes (the one definition of both; the CLI imports them).

Exit codes (documented in ``lcpcli --help`` and the README):

* 0 - every problem solved (certificate checked); for commands without a verdict: done;
* 1 - a problem was not solved (``no_solution`` or ``unsolved``), or ``bench`` found a defect;
* 2 - bad usage or bad input (malformed file, wrong shapes, NaN/Inf, unknown option, ...), and
  an output that cannot be written (:class:`OutputError`: disk full, permission denied, ...);
* 3 - internal error (a bug);
* 129 - hung up (SIGHUP: the terminal closed; under ``nohup`` it is ignored and the command
  runs on); 130 - interrupted (Ctrl-C); 143 - terminated (SIGTERM).  Each stops a command
  cleanly (a batch closes its output first, an atomic output removes its temporary file):
  :data:`STOP_SIGNALS`.
"""

from __future__ import annotations

import signal

EXIT_OK = 0
EXIT_SOLVED = EXIT_OK  # the same code, named for commands with a verdict
EXIT_NOT_SOLVED = 1
EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3
EXIT_HANGUP = 129
EXIT_INTERRUPTED = 130
EXIT_TERMINATED = 143

#: The signals that stop a command as Ctrl-C does, each with its exit code (128 + its number,
#: as a shell reports a process it killed); SIGHUP only where the platform has it.
STOP_SIGNALS: dict[int, int] = {
    signal.SIGINT: EXIT_INTERRUPTED,
    signal.SIGTERM: EXIT_TERMINATED,
    **({signal.SIGHUP: EXIT_HANGUP} if hasattr(signal, "SIGHUP") else {}),
}


class LcpError(Exception):
    """Base class of the package's own errors."""


class ProblemError(LcpError, ValueError):
    """Invalid or unreadable problem data; the message is one line meant for users."""

    def __init__(self, message: str, source: str | None = None) -> None:
        self.source = source
        super().__init__(f"{source}: {message}" if source else message)

    def with_source(self, source: str) -> ProblemError:
        """Return the same error prefixed by ``source`` (unless it already has one)."""
        if self.source:
            return self
        return ProblemError(str(self), source)


class OutputError(LcpError):
    """An output could not be written (``PATH: no space left on device``, ``permission
    denied``, ...): exit code 2, one line; the writer left the previous file as it was, or a
    resumable prefix it names in ``message`` (:mod:`lcpcli.io.writing`)."""

    def __init__(self, path: str, reason: str) -> None:
        self.path, self.reason = path, reason
        super().__init__(f"{path}: {reason}")


class OptionError(LcpError, ValueError):
    """Invalid solver option (unknown name, wrong type, out of range)."""
