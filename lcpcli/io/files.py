"""Safe file access shared by every reader and writer (the one place for these rules).

Inputs:

* only regular files are read (a FIFO, a device such as ``/dev/zero``, a socket or a directory
  is refused before it is opened, and again by ``fstat`` after a non-blocking open, so a
  swapped-in FIFO cannot hang the reader); ``-`` (stdin) is the one stream accepted;
* text formats (JSON, Siconos ``.dat``, warm starts) are read up to :data:`MAX_TEXT_BYTES`,
  checked from the file size before reading;
* JSON nesting never surfaces as a ``RecursionError``: :func:`parse_json` turns it into a
  one-line error and :func:`check_depth` bounds free-form objects (``meta``).

Outputs follow the rules of :mod:`lcpcli.io.writing` (the one writing layer).
"""

from __future__ import annotations

import json
import os
import stat
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import IO, Any

from lcpcli.core.errors import ProblemError

#: Largest text file (JSON, Siconos .dat, warm start) or stdin read, in bytes (256 MiB).
MAX_TEXT_BYTES = 256 * 2**20
#: Longest ``name`` / ``description`` text stored in a binary problem file, in bytes.
MAX_NAME_BYTES = 2**20
#: Deepest nesting accepted in free-form JSON objects (``meta``).
MAX_JSON_DEPTH = 64

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"), (stat.S_ISLNK, "a symbolic link"))


def file_kind(mode: int) -> str:
    """``"a directory"``, ``"a FIFO (named pipe)"``, ... for a non-regular ``st_mode``."""
    for test, name in _KINDS:
        if test(mode):
            return name
    return "not a regular file"


def _stat_error(exc: OSError) -> ProblemError:
    if isinstance(exc, (FileNotFoundError, NotADirectoryError)):
        return ProblemError("no such file")
    if isinstance(exc, PermissionError):
        return ProblemError("permission denied")
    return ProblemError(f"cannot access the file ({exc.strerror or type(exc).__name__})")


def check_input_file(path: str | os.PathLike[str], what: str = "a problem file"
                     ) -> os.stat_result:
    """The ``stat`` of ``path`` if it is a regular file (symlinks followed), else ProblemError."""
    try:
        st = os.stat(path)
    except OSError as exc:
        raise _stat_error(exc) from None
    if stat.S_ISDIR(st.st_mode):
        raise ProblemError(f"is a directory, not {what}")
    if not stat.S_ISREG(st.st_mode):
        raise ProblemError(f"is {file_kind(st.st_mode)}, not a regular file (to read a stream, "
                           f"give '-' and redirect it to stdin)")
    return st


@contextmanager
def open_input(path: str | os.PathLike[str], what: str = "a problem file") -> Iterator[IO[bytes]]:
    """Open a regular file for reading (non-blocking open, then ``fstat``: no FIFO can hang)."""
    check_input_file(path, what)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) \
        | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise _stat_error(exc) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):  # replaced between the stat and the open
            raise ProblemError(f"is {file_kind(st.st_mode)}, not a regular file")
        fh = os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise
    with fh:
        yield fh


def _mib(n: int) -> str:
    return f"{n / 2**20:,.0f} MiB" if n >= 2**20 else f"{n:,} bytes"


def too_big(size: int, limit: int, what: str) -> ProblemError:
    return ProblemError(f"{what} of {_mib(size)} is over the limit of {_mib(limit)}")


def read_input_bytes(path: str | os.PathLike[str], limit: int = MAX_TEXT_BYTES,
                     what: str = "a text file") -> bytes:
    """The content of a regular file of at most ``limit`` bytes (checked before reading)."""
    with open_input(path) as fh:
        size = os.fstat(fh.fileno()).st_size
        if size > limit:
            raise too_big(size, limit, what)
        # size + 1 bytes, not limit + 1: a buffered read(n) allocates n bytes first (25 us
        # per small file for a 256 MiB limit)
        data = fh.read(size + 1)
        if len(data) > size:  # the file grew since the fstat: the rest, up to the limit
            data += fh.read(limit + 1 - len(data))
    if len(data) > limit:  # the file grew while we read it
        raise too_big(len(data), limit, what)
    return data


def read_stdin_bytes(limit: int = MAX_TEXT_BYTES) -> bytes:
    """At most ``limit`` bytes of stdin (more is refused, not silently cut; a file redirected
    to stdin is measured before it is read)."""
    stream = getattr(sys.stdin, "buffer", None)
    try:
        st = os.fstat(sys.stdin.fileno())
    except (OSError, ValueError, AttributeError):
        st = None
    if st is not None and stat.S_ISREG(st.st_mode) and st.st_size > limit:
        raise too_big(st.st_size, limit, "stdin")
    data = stream.read(limit + 1) if stream is not None else sys.stdin.read(limit + 1).encode()
    if len(data) > limit:
        raise too_big(len(data), limit, "stdin")
    return data


def decode_text(data: bytes, what: str = "a UTF-8 text file") -> str:
    """``data`` as UTF-8 text (a BOM is skipped); ProblemError for binary data."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ProblemError(f"not {what}") from None


def parse_json(text: str | bytes, *, parse_constant: Any = None) -> Any:
    """``json.loads`` with every failure as one ProblemError line (deep nesting included);
    ``parse_constant`` handles NaN/Infinity literals as ``json.loads`` does."""
    try:
        return json.loads(text, parse_constant=parse_constant)
    except json.JSONDecodeError as exc:
        raise ProblemError(f"invalid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") \
            from None
    except RecursionError:
        raise ProblemError("invalid JSON: arrays or objects nested too deeply") from None
    except ValueError as exc:  # e.g. an integer literal of more than 4300 digits
        raise ProblemError(f"invalid JSON: {str(exc).splitlines()[0][:100]}") from None


def check_depth(obj: Any, label: str, limit: int = MAX_JSON_DEPTH) -> None:
    """ProblemError when lists/objects in ``obj`` nest more than ``limit`` deep (iterative)."""
    stack = [(obj, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, (list, dict)):
            if depth > limit:
                raise ProblemError(f"{label} is nested more than {limit} levels deep")
            children = item.values() if isinstance(item, dict) else item
            stack.extend((c, depth + 1) for c in children)
