"""Safe file access shared by every reader and writer (the one place for these rules).

Inputs:

* only regular files are read (a FIFO, a device such as ``/dev/zero``, a socket or a directory
  is refused before it is opened, and again by ``fstat`` after a non-blocking open, so a
  swapped-in FIFO cannot hang the reader); ``-`` (stdin) is the one stream accepted;
* text formats (JSON problems, scenes, warm starts and impulses; Siconos ``.dat``) are read
  up to :data:`MAX_TEXT_BYTES`, checked from the file size before reading;
* JSON is bounded (:func:`parse_json`, the one JSON parser of every reader): a key given twice
  in one object is refused (never "the last one wins"), an integer literal is at most
  :data:`MAX_JSON_INT_DIGITS` digits, nesting deeper than the parser's recursion limit is a
  one-line error (never a ``RecursionError``) and :func:`check_depth` bounds free-form objects
  (``meta``) to :data:`MAX_JSON_DEPTH` levels.

The rules are stated once for users in docs/files.md ("Reading").

Outputs follow the rules of :mod:`lcpcli.io.writing` (the one writing layer).
"""

from __future__ import annotations

import json
import math
import os
import stat
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import IO, Any

from lcpcli.core.errors import ProblemError
from lcpcli.core.numeric import fast_json

#: Largest text file (JSON, Siconos .dat, warm start) or stdin read, in bytes (256 MiB).
MAX_TEXT_BYTES = 256 * 2**20
#: Longest ``name`` / ``description`` text stored in a binary problem file, in bytes.
MAX_NAME_BYTES = 2**20
#: Deepest nesting accepted in free-form JSON objects (``meta``).
MAX_JSON_DEPTH = 64
#: Longest integer literal accepted in JSON, in digits (Python's own guard on integer parsing,
#: set to its smallest allowed value while a file is parsed).  Any integer of more than 309
#: digits is beyond float64 anyway and refused by the data rule (:mod:`lcpcli.core.numeric`).
MAX_JSON_INT_DIGITS = 640
#: Largest HDF5 chunk read beyond the data it holds, in bytes (64 MiB): HDF5 decompresses
#: whole chunks, so a 2 x 2 dataset declared in one chunk of 4 GB costs 4 GB and seconds to
#: read.  A chunk larger than both this and its dataset is refused from the header
#: (:func:`check_h5_chunks`).
MAX_H5_CHUNK_BYTES = 64 * 2**20

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"), (stat.S_ISLNK, "a symbolic link"))


class StackedFile(ProblemError):
    """A format reader's signal: the file holds a stack (``M`` of shape ``(K, n, n)`` at its
    root), not the one problem it reads.  :func:`lcpcli.io.load` and
    :func:`lcpcli.io.list_problems` catch it and read the file with :mod:`lcpcli.io.stack`, so
    the format modules never import that module (it imports them: no import circle)."""

    def __init__(self) -> None:
        super().__init__("holds stacked problems (M of shape (K, n, n)); read it with "
                         "lcpcli.io.load")


def stored_text(value: str, label: str, fmt: str) -> bytes:
    """A problem's ``name`` or ``description`` as NPZ and HDF5 store it: UTF-8 of at most
    :data:`MAX_NAME_BYTES` (what their readers accept), without NUL (HDF5 strings cannot hold
    one; NPZ strings drop a trailing one).  ProblemError otherwise, before anything is written:
    such a text (JSON holds any) was written and then refused when read back (over 1 MiB), or
    was an internal error (HDF5, a NUL or a lone surrogate)."""
    if "\x00" in value:
        raise ProblemError(f"the {label} holds a NUL character, which {fmt} cannot store "
                           f"(write .json)")
    try:
        data = value.encode("utf-8")
    except UnicodeEncodeError:
        raise ProblemError(f"the {label} is not valid Unicode (a lone surrogate), which {fmt} "
                           f"cannot store as UTF-8 (write .json)") from None
    if len(data) > MAX_NAME_BYTES:
        raise ProblemError(f"the {label} is {len(data):,} bytes of UTF-8; {fmt} holds at most "
                           f"{MAX_NAME_BYTES:,} (write .json)")
    return data


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


#: How an input is opened: read-only, non-blocking (a FIFO swapped in cannot hang the open),
#: never as a controlling terminal, closed on exec.
_INPUT_FLAGS = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) \
    | getattr(os, "O_CLOEXEC", 0)


@contextmanager
def open_input(path: str | os.PathLike[str], what: str = "a problem file") -> Iterator[IO[bytes]]:
    """Open a regular file for reading (non-blocking open, then ``fstat``: no FIFO can hang)."""
    fd, _ = _open_regular(path, what)
    try:
        fh = os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise
    with fh:
        yield fh


def _open_regular(path: str | os.PathLike[str], what: str) -> tuple[int, os.stat_result]:
    """``(fd, fstat)`` of a regular file opened for reading: :func:`check_input_file`, a
    non-blocking open (no FIFO can hang), then ``fstat`` (a file replaced between the stat and
    the open is refused).  The caller closes ``fd``."""
    check_input_file(path, what)
    try:
        fd = os.open(path, _INPUT_FLAGS)
    except OSError as exc:
        raise _stat_error(exc) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):  # replaced between the stat and the open
            raise ProblemError(f"is {file_kind(st.st_mode)}, not a regular file")
    except BaseException:
        os.close(fd)
        raise
    return fd, st


def _mib(n: int) -> str:
    return f"{n / 2**20:,.0f} MiB" if n >= 2**20 else f"{n:,} bytes"


def too_big(size: int, limit: int, what: str) -> ProblemError:
    return ProblemError(f"{what} of {_mib(size)} is over the limit of {_mib(limit)}")


def check_h5_chunks(did: Any, label: str) -> None:
    """ProblemError when the HDF5 dataset ``did`` (an h5py ``DatasetID``) is stored in chunks
    larger than both its data and :data:`MAX_H5_CHUNK_BYTES`; from the header, nothing read.
    Every HDF5 dataset a reader reads passes here (:func:`lcpcli.io.hdf5_format.dataset`,
    :func:`lcpcli.io.writing.check_dataset`)."""
    import h5py

    plist = did.get_create_plist()
    if plist.get_layout() != h5py.h5d.CHUNKED:
        return
    itemsize = did.get_type().get_size()
    chunk = math.prod(plist.get_chunk()) * itemsize
    data = math.prod(did.shape or ()) * itemsize
    if chunk > max(data, MAX_H5_CHUNK_BYTES):
        raise ProblemError(f"'{label}' is stored in HDF5 chunks of {_mib(chunk)} for "
                           f"{_mib(data)} of data (limit: the data's size or "
                           f"{_mib(MAX_H5_CHUNK_BYTES)}); refused before reading")


def read_input_bytes(path: str | os.PathLike[str], limit: int = MAX_TEXT_BYTES,
                     what: str = "a text file") -> bytes:
    """The content of a regular file of at most ``limit`` bytes (checked before reading).

    :func:`open_input`'s checks (``stat``, non-blocking open, ``fstat``) on the bare file
    descriptor: the ``fstat`` also gives the size, and no file object is built (a batch reads
    10^4+ small files this way).
    """
    fd, st = _open_regular(path, "a problem file")
    try:
        size = st.st_size
        if size > limit:
            raise too_big(size, limit, what)
        # size + 1 bytes, not limit + 1 (an allocation of the limit for each small file); a
        # file that grew since the fstat is read on, in blocks, up to the limit
        parts, total, want = [], 0, size + 1
        while total < want:
            block = os.read(fd, min(want - total, max(size + 1, 1 << 20)))
            if not block:
                break
            parts.append(block)
            total += len(block)
            if total > size:
                want = limit + 1
    finally:
        os.close(fd)
    data = parts[0] if len(parts) == 1 else b"".join(parts)
    if len(data) > limit:  # the file grew while we read it
        raise too_big(len(data), limit, what)
    return data


def read_stdin_bytes(limit: int = MAX_TEXT_BYTES) -> bytes:
    """At most ``limit`` bytes of stdin (more is refused, not silently cut; a file redirected
    to stdin is measured before it is read).  A standard input that is not open (``<&-``:
    Python's ``sys.stdin`` is None) or cannot be read is a ProblemError naming ``-``."""
    if sys.stdin is None:
        raise ProblemError("standard input is not open (closed, as by '<&-'): give the "
                           "problem on stdin, or a file", "-")
    stream = getattr(sys.stdin, "buffer", None)
    try:
        st = os.fstat(sys.stdin.fileno())
    except (OSError, ValueError, AttributeError):
        st = None
    if st is not None and stat.S_ISREG(st.st_mode) and st.st_size > limit:
        raise too_big(st.st_size, limit, "stdin")
    try:
        data = stream.read(limit + 1) if stream is not None \
            else sys.stdin.read(limit + 1).encode()
    except OSError as exc:  # open for writing only, a terminal that went away, ...
        raise ProblemError(f"cannot read standard input ({exc.strerror or exc})", "-") from None
    if len(data) > limit:
        raise too_big(len(data), limit, "stdin")
    return data


def decode_text(data: bytes, what: str = "a UTF-8 text file") -> str:
    """``data`` as UTF-8 text (a BOM is skipped); ProblemError for binary data."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ProblemError(f"not {what}") from None


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``object_pairs_hook`` of :func:`parse_json`: a key given twice in one object is refused."""
    obj = dict(pairs)
    if len(obj) != len(pairs):
        seen: set[str] = set()
        for key, _value in pairs:
            if key in seen:
                raise ProblemError(f"invalid JSON: key {key[:40]!r} appears twice in one object "
                                   f"(duplicate keys are refused, not overwritten)")
            seen.add(key)
    return obj


#: Byte map for :func:`_long_integer`: digits to ``0``, what precedes fraction or exponent
#: digits (``.``, ``e``, ``E``) to ``.``, everything else to a space.
_DIGIT_MAP = bytes(ord("0") if chr(b).isdigit() and b < 128 else ord(".") if chr(b) in ".eE"
                   else ord(" ") for b in range(256))
_DIGITS = b"0" * 19
_LONG_RUN = b" " + _DIGITS


def _long_integer(text: str | bytes) -> bool:
    """True when ``text`` may hold an integer literal of 19 or more digits (19 digits after a
    non-digit other than ``.``/``e``, or at the start; fraction digits may run longer), which
    orjson turns into a float beyond 64 bits where the stdlib keeps an int.  C-speed passes:
    one ``translate``, then a search for 19 digits in a row (rare: floats have at most 17
    significant digits), and only where there are such for what precedes them."""
    data = text.encode("utf-8", "surrogatepass") if isinstance(text, str) else bytes(text)
    mapped = data.translate(_DIGIT_MAP)
    if mapped.find(_DIGITS) == -1:
        return False
    return mapped.startswith(_DIGITS) or mapped.find(_LONG_RUN) != -1


def _key_count(obj: Any, braces: int) -> int:
    """Number of keys in all objects of a decoded document (``braces``: ``{`` in its text)."""
    if braces == 0:
        return 0
    if braces == 1 and isinstance(obj, dict):  # the root is the only object
        return len(obj)
    count, stack = 0, [obj]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            count += len(item)
            stack.extend(v for v in item.values() if isinstance(v, (dict, list)))
        elif isinstance(item, list):
            stack.extend(v for v in item if isinstance(v, (dict, list)))
    return count


#: Nesting that the stdlib parser always reaches within its recursion limit; a deeper document
#: is left to it, which refuses one nested too deeply for Python as before.
_SHALLOW = 100


def _depth(obj: Any) -> int:
    """Deepest nesting of lists/objects in a decoded document (1 for a flat list)."""
    deepest, stack = 0, [(obj, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, (list, dict)):
            deepest = max(deepest, depth)
            children = item.values() if isinstance(item, dict) else item
            stack.extend((c, depth + 1) for c in children if isinstance(c, (list, dict)))
    return deepest


def fast_parse(text: str | bytes) -> tuple[bool, Any]:
    """:func:`_fast_parse`: ``(True, value)`` when orjson decodes ``text`` (also the UTF-8
    bytes of a file, undecoded: orjson refuses invalid UTF-8, a BOM and lone surrogates, which
    the caller then decodes and parses as before) to exactly what :func:`parse_json` gives,
    else ``(False, None)``."""
    return _fast_parse(text)


def _fast_parse(text: str | bytes) -> tuple[bool, Any]:
    """``(True, value)`` when orjson decodes ``text`` to exactly what ``json.loads`` gives under
    this module's rules, else ``(False, None)`` (the caller then parses with the stdlib, which
    also words every error).  Exactness: orjson refuses NaN/Infinity literals, numbers that
    overflow to infinity, lone surrogates and a BOM (all go to the stdlib); an integer of 19
    or more digits is left to the stdlib (orjson would return a float beyond 64 bits), so is a
    document nested deeper than :data:`_SHALLOW` (the stdlib may refuse it); and
    orjson keeps the last of duplicate keys, so the keys found must account for every ``:`` in
    the text (each key has one; others must lie in the strings found, :func:`_string_colons`;
    with a backslash in the text, which may escape a ``:``, the stdlib parses instead)."""
    codec = fast_json(len(text))
    if codec is None:
        return False, None
    if _long_integer(text):
        return False, None
    try:
        value = codec.loads(text)
    except (ValueError, TypeError):
        return False, None
    is_bytes = isinstance(text, (bytes, bytearray))
    colons, braces = (text.count(b":"), text.count(b"{")) if is_bytes else \
        (text.count(":"), text.count("{"))
    opened = braces + (text.count(b"[") if is_bytes else text.count("["))
    if opened > _SHALLOW and _depth(value) > _SHALLOW:
        return False, None  # the stdlib's recursion limit words what it refuses
    keys = _key_count(value, braces)
    if keys != colons and ((b"\\" if is_bytes else "\\") in text
                           or keys + _string_colons(value) != colons):
        return False, None
    return True, value


def _string_colons(obj: Any) -> int:
    """Number of ``:`` in all strings (keys and values) of a decoded document.  For a text
    without backslashes each is one ``:`` of the text, so keys + these = the text's ``:`` count
    exactly when no key was dropped as a duplicate (its own ``:`` would be missing)."""
    count, stack = 0, [obj]
    while stack:
        item = stack.pop()
        if isinstance(item, str):
            count += item.count(":")
        elif isinstance(item, dict):
            count += sum(k.count(":") for k in item)
            stack.extend(v for v in item.values() if isinstance(v, (dict, list, str)))
        elif isinstance(item, list):
            stack.extend(v for v in item if isinstance(v, (dict, list, str)))
    return count


def parse_json(text: str | bytes, *, parse_constant: Any = None) -> Any:
    """``json.loads`` under the JSON bounds of this module (duplicate keys, integer length,
    nesting), every failure as one ProblemError line; ``parse_constant`` handles NaN/Infinity
    literals as ``json.loads`` does.  With orjson installed, a document it decodes exactly
    (:func:`_fast_parse`: about 10x faster) is taken from it; the result is the same."""
    ok, value = _fast_parse(text)
    if ok:
        return value
    old = None  # a text shorter than the limit holds no longer integer: no toggle (1 us)
    if len(text) > MAX_JSON_INT_DIGITS and hasattr(sys, "get_int_max_str_digits"):
        old = sys.get_int_max_str_digits()
        if old == 0 or old > MAX_JSON_INT_DIGITS:
            sys.set_int_max_str_digits(MAX_JSON_INT_DIGITS)
        else:
            old = None
    try:
        return json.loads(text, parse_constant=parse_constant, object_pairs_hook=_unique_keys)
    except ProblemError:
        raise
    except json.JSONDecodeError as exc:
        raise ProblemError(f"invalid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}") \
            from None
    except RecursionError:
        raise ProblemError("invalid JSON: arrays or objects nested too deeply") from None
    except ValueError as exc:  # an integer literal beyond MAX_JSON_INT_DIGITS
        if "integer string conversion" in str(exc):
            raise ProblemError(f"invalid JSON: Exceeds the limit of {MAX_JSON_INT_DIGITS} "
                               f"digits for an integer") from None
        raise ProblemError(f"invalid JSON: {str(exc).splitlines()[0][:100]}") from None
    finally:
        if old is not None:
            sys.set_int_max_str_digits(old)


def read_json_file(path: str | os.PathLike[str], what: str = "a JSON file", *,
                   parse_constant: Any = None) -> Any:
    """The decoded content of a JSON file under every reading rule: a regular file of at most
    :data:`MAX_TEXT_BYTES` (checked before reading), UTF-8, and :func:`parse_json`'s bounds."""
    data = read_input_bytes(path, MAX_TEXT_BYTES, what)
    return parse_json(decode_text(data, "a UTF-8 text file (is it really JSON?)"),
                      parse_constant=parse_constant)


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
