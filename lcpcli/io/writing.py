"""The one writing layer: every file lcpcli creates, replaces or appends to goes through here.

The rules (stated for users in ``docs/files.md``, section "Writing"):

1. **Never an input, a link or a device.**  :func:`check_output` runs before any work: an output
   is refused when it is a symbolic link, not a regular file (directory, device, FIFO,
   socket), the same file as an input (by device and inode: hard links and other spellings
   count), or the same file as another output of the command (:func:`check_distinct`).
2. **One-file outputs are replaced atomically** (:func:`atomic_path`, :func:`atomic_file`,
   :func:`write_atomic_text`): a temporary file is created beside the target with
   ``O_CREAT | O_EXCL | O_NOFOLLOW`` (mode 0600 until it is complete), written, ``fsync``-ed
   and renamed over the target (``os.replace``), then the folder is ``fsync``-ed.  Any failure
   removes the temporary file: the previous output is intact and nothing partial is left.
3. **Files written in place are opened without following links**: batch rows, the HDF5
   journal, lock files (:func:`open_append`, :func:`output_lock`) and resumed result files
   (:func:`open_hdf5`) are opened with ``O_NOFOLLOW`` and must be regular files; a symbolic
   link is refused, never written through.  A failed append is cut back to the last complete
   row, so the file stays resumable (:class:`AppendFile`).
4. **HDF5 is written through** :class:`SafeSink` (h5py's ``fileobj`` driver over a descriptor we
   opened): the first failed write is recorded and later writes are discarded, so the HDF5
   library never sees an I/O error.  With HDF5's own driver a failed flush leaves the library
   in a state that segfaults at exit (``convert DIR stack.h5 --stack`` on a full disk did, every
   time); here the file closes cleanly and the error is raised afterwards.
5. **Resumed HDF5 result files hold nothing from outside**: :func:`check_hdf5_tree` refuses
   external and soft links, virtual datasets and external storage before anything is read or
   written.
6. **Write failures are one line**: ``ENOSPC``, ``EDQUOT``, ``EACCES``, ``EPERM``, ``EROFS``,
   ``EFBIG`` and ``EIO`` (raised by the OS or reported inside an h5py message) become
   :class:`~lcpcli.core.errors.OutputError` (``PATH: no space left on device``, exit code 2).
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import re
import stat
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from lcpcli.core.errors import OutputError, ProblemError
from lcpcli.io.files import check_h5_chunks, file_kind

#: The write failures reported as one line (errno -> the reason users read).
WRITE_ERRORS = {
    errno.ENOSPC: "no space left on device",
    errno.EDQUOT: "disk quota exceeded",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.EROFS: "read-only file system",
    errno.EFBIG: "file too large",
    errno.EIO: "input/output error",
}
_H5_ERRNO = re.compile(r"errno = (\d+)")
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)
_NONBLOCK = getattr(os, "O_NONBLOCK", 0)


# ----------------------------------------------------------------------------- failures
class ForeignObjectError(ProblemError):
    """A file of lcpcli's holds what lcpcli never writes and must not follow (rule 5): it is
    refused, not repaired or rebuilt."""


def write_errno(exc: BaseException) -> int | None:
    """The errno of a failed write in ``exc`` (an OSError, or an h5py error whose message
    carries ``errno = N``), when it is one of :data:`WRITE_ERRORS`; else None."""
    if isinstance(exc, OSError) and exc.errno in WRITE_ERRORS:
        return exc.errno
    if isinstance(exc, (OSError, RuntimeError, ValueError, KeyError)):
        m = _H5_ERRNO.search(str(exc))
        if m and int(m.group(1)) in WRITE_ERRORS:
            return int(m.group(1))
    return None


def output_error(exc: BaseException, path: str | os.PathLike[str], note: str = ""
                 ) -> OutputError | None:
    """``exc`` as an :class:`OutputError` naming ``path`` (``note`` appended), or None when
    it is not a failed write."""
    code = write_errno(exc)
    if code is None:
        return None
    return OutputError(str(path), WRITE_ERRORS[code] + (f" ({note})" if note else ""))


def restated(exc: OutputError, path: str | os.PathLike[str], note: str = "") -> OutputError:
    """``exc`` (a failed write) naming ``path`` instead, with ``note`` in place of its own."""
    reason = next((r for r in WRITE_ERRORS.values() if exc.reason.startswith(r)), exc.reason)
    return OutputError(str(path), reason + (f" ({note})" if note else ""))


@contextmanager
def writing(path: str | os.PathLike[str], note: str = "") -> Iterator[None]:
    """Turn a failed write inside the block into ``OutputError(path)`` (other errors pass)."""
    try:
        yield
    except OutputError:
        raise
    except (OSError, RuntimeError, ValueError, KeyError) as exc:
        err = output_error(exc, path, note)
        if err is None:
            raise
        raise err from None


def _regular_fd(fd: int, path: str | os.PathLike[str]) -> os.stat_result:
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        raise ProblemError(f"is {file_kind(st.st_mode)}, not a regular file: refusing to "
                           f"write to it", str(path))
    return st


def _open_nofollow(path: str | os.PathLike[str], flags: int, mode: int = 0o666) -> int:
    """``os.open`` with ``O_NOFOLLOW | O_CLOEXEC | O_NONBLOCK`` (a FIFO cannot block it); a
    symbolic link is a ProblemError, a write failure an OutputError; the result is a
    descriptor of a regular file."""
    try:
        fd = os.open(path, flags | _NOFOLLOW | _CLOEXEC | _NONBLOCK, mode)
    except OSError as exc:
        if exc.errno == errno.ELOOP or (exc.errno == errno.EMLINK and os.path.islink(path)):
            target = os.readlink(path) if os.path.islink(path) else "?"
            raise ProblemError(f"is a symbolic link (to {target}): refusing to read or write "
                               f"through it; remove it or give another path", str(path)) from None
        if exc.errno == errno.ENXIO:  # a FIFO without a reader
            raise ProblemError("is a FIFO (named pipe), not a regular file: refusing to write "
                               "to it", str(path)) from None
        err = output_error(exc, path)
        if err is not None:
            raise err from None
        raise ProblemError(f"cannot open it ({exc.strerror or type(exc).__name__})",
                           str(path)) from None
    _regular_fd(fd, path)
    return fd


def own_file(path: str | os.PathLike[str]) -> os.stat_result | None:
    """The ``lstat`` of a file lcpcli wrote and will read back or write again (a result file,
    a journal), None when it does not exist; a link or anything but a regular file is a
    ProblemError (it is never followed)."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise ProblemError(f"cannot access it ({exc.strerror or type(exc).__name__})",
                           str(path)) from None
    if stat.S_ISLNK(st.st_mode):
        raise ProblemError(f"is a symbolic link (to {os.readlink(path)}): refusing to read or "
                           f"write through it; remove it or give another path", str(path))
    if not stat.S_ISREG(st.st_mode):
        raise ProblemError(f"is {file_kind(st.st_mode)}, not a regular file", str(path))
    return st


def read_own_file(path: str | os.PathLike[str]) -> bytes:
    """The bytes of a file lcpcli wrote (``O_NOFOLLOW``, regular files only; b"" if missing)."""
    if own_file(path) is None:
        return b""
    fd = _open_nofollow(path, os.O_RDONLY)
    with os.fdopen(fd, "rb") as fh:
        return fh.read()


def remove_file(path: str | os.PathLike[str]) -> None:
    """Remove ``path`` if it exists (a link is removed, never its target)."""
    with contextlib.suppress(FileNotFoundError):
        os.unlink(path)


# ----------------------------------------------------------------------------- checks
def check_output(target: str | os.PathLike[str], inputs: Iterable[Any] = (), *,
                 force: bool = True, stdout: bool = True, option: str = "--output") -> None:
    """Refuse an output before any work is done (ProblemError naming ``target``).

    Refused: a symbolic link, anything that is not a regular file (directory, device, FIFO,
    socket; whatever ``force`` says), a name that ends in ``/`` (or ``/.``: it names a folder,
    and ``pathlib`` would drop the slash and write a file of the name without it), the same
    file as one of ``inputs`` (compared by device and inode, so hard links and other
    spellings count), a missing folder, and an existing file when ``force`` is false.  ``-``
    is stdout: accepted when ``stdout`` is true, else refused naming ``option`` (the
    command-line option that gave it).  Give ``target`` as the user typed it (a ``str``: a
    ``Path`` has lost its trailing slash already).
    """
    if str(target) == "-":
        if not stdout:
            raise ProblemError("'-' is not a file here: --json prints the result on stdout",
                               option)
        return
    source = str(target)
    if names_folder(source) and not os.path.isdir(source):  # a directory: refused below
        raise ProblemError("not a directory: a name ending in '/' names a folder; give the "
                           "file's name without it", source)
    try:
        st = os.lstat(target)
    except FileNotFoundError:
        st = None
    except OSError as exc:
        raise ProblemError(f"cannot access it ({exc.strerror or type(exc).__name__})",
                           source) from None
    if st is None:
        folder = Path(target).parent
        if not folder.is_dir():
            raise ProblemError(f"folder {folder} does not exist", source)
        return
    if stat.S_ISLNK(st.st_mode):
        raise ProblemError(f"is a symbolic link (to {os.readlink(target)}); give the path of "
                           f"a regular file", source)
    if not stat.S_ISREG(st.st_mode):
        raise ProblemError(f"is {file_kind(st.st_mode)}, not a regular file: refusing to "
                           f"write to it", source)
    for item in inputs:
        if item is None or str(item) == "-":
            continue
        try:
            ist = os.stat(item)
        except OSError:
            continue
        if (ist.st_dev, ist.st_ino) == (st.st_dev, st.st_ino):
            raise ProblemError(f"is the same file as the input {item}: refusing to overwrite "
                               f"it (choose another output file)", source)
    if not force:
        raise ProblemError("exists already (use --force to overwrite)", source)


def names_folder(name: str | os.PathLike[str]) -> bool:
    """Whether ``name`` as typed names a folder: it ends in a separator or in ``/.``."""
    raw = os.fspath(name)
    seps = tuple(c for c in (os.sep, os.altsep) if c)
    return raw.endswith(seps) or any(raw.endswith(c + ".") for c in seps)


def _identity(path: str | os.PathLike[str]) -> tuple[Any, ...]:
    """(device, inode) of an existing file, else its absolute path with the folder resolved."""
    try:
        st = os.stat(path)
        return (st.st_dev, st.st_ino)
    except OSError:
        p = Path(path)
        return (str(p.parent.resolve() / p.name),)


def check_distinct(outputs: Iterable[tuple[str, Any]]) -> None:
    """Refuse two outputs of one command that are the same file (``-o X --impulses X``):
    ``outputs`` are ``(option, path)`` pairs, None paths skipped."""
    seen: dict[tuple[Any, ...], str] = {}
    for option, path in outputs:
        if path is None or str(path) == "-":
            continue
        ident = _identity(path)
        if ident in seen:
            raise ProblemError(f"is the same file as {seen[ident]}: one file cannot hold both "
                               f"outputs; give two different files", f"{option} {path}")
        seen[ident] = f"{option} {path}"


def _check_replaceable(target: Path) -> None:
    """The last check before a rename: ``target`` is absent or a regular file (no link)."""
    try:
        st = os.lstat(target)
    except FileNotFoundError:
        return
    if stat.S_ISLNK(st.st_mode) or not stat.S_ISREG(st.st_mode):
        raise ProblemError(f"is {file_kind(st.st_mode)}, not a regular file: refusing to "
                           f"replace it", str(target))


# ----------------------------------------------------------------------------- atomic
def _target_mode(target: Path) -> int:
    """The existing file's mode, else what a plain ``open(..., "w")`` would give (umask)."""
    try:
        return os.stat(target).st_mode & 0o777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def _create_temp(target: Path) -> tuple[int, Path]:
    """A new empty file beside ``target`` (``O_CREAT | O_EXCL | O_NOFOLLOW``, mode 0600)."""
    folder = target.parent
    stem = target.name[:200]
    for _ in range(100):
        tmp = folder / f".{stem}.{os.urandom(4).hex()}.tmp"  # os: no secrets/hmac import
        try:
            fd = os.open(tmp, os.O_RDWR | os.O_CREAT | os.O_EXCL | _NOFOLLOW | _CLOEXEC, 0o600)
        except FileExistsError:
            continue
        except OSError as exc:
            err = output_error(exc, target, f"cannot create a file in {folder}")
            if err is not None:
                raise err from None
            raise ProblemError(f"cannot create a file in {folder} "
                               f"({exc.strerror or type(exc).__name__})", str(target)) from None
        return fd, tmp
    raise ProblemError(f"cannot create a temporary file in {folder}", str(target))


def _fsync_folder(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | _CLOEXEC)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _commit(fd: int, tmp: Path, target: Path) -> None:
    """fsync the temporary file, check it is still ours, give it the target's mode, rename."""
    mine = os.fstat(fd)
    try:
        now = os.lstat(tmp)
    except FileNotFoundError:
        now = None
    if now is None or (now.st_dev, now.st_ino) != (mine.st_dev, mine.st_ino):
        raise ProblemError(f"its temporary file {tmp.name} was replaced while it was written: "
                           f"refusing to rename it over the output", str(target))
    os.fsync(fd)
    os.fchmod(fd, _target_mode(target))
    _check_replaceable(target)
    os.replace(tmp, target)
    _fsync_folder(target.parent)


@contextmanager
def _atomic(target: str | os.PathLike[str]) -> Iterator[tuple[int, Path]]:
    target = Path(target)
    if not target.parent.is_dir():
        raise ProblemError(f"folder {target.parent} does not exist", str(target))
    _check_replaceable(target)
    fd, tmp = _create_temp(target)
    done = False
    try:
        try:
            with writing(target):
                yield fd, tmp
                _commit(fd, tmp, target)
        except OutputError as exc:
            if exc.path != str(tmp):
                raise
            raise OutputError(str(target), exc.reason) from None  # users know the target
        done = True
    finally:
        os.close(fd)
        if not done:
            remove_file(tmp)


@contextmanager
def atomic_path(target: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a new temporary path beside ``target``; rename it over ``target`` on success only
    (rule 2).  For writers that need a path (HDF5 via :func:`open_hdf5`, NPZ, plots); a write
    failure in the block is an :class:`OutputError` and the temporary file is removed."""
    with _atomic(target) as (_fd, tmp):
        yield tmp


@contextmanager
def atomic_file(target: str | os.PathLike[str]) -> Iterator[IO[bytes]]:
    """Yield a binary file object on a new temporary file beside ``target`` (rule 2)."""
    with _atomic(target) as (fd, tmp):
        yield SafeSink(fd, tmp, strict=True)  # type: ignore[misc]


def write_atomic_bytes(target: str | os.PathLike[str], data: bytes) -> None:
    """Replace ``target`` by ``data`` atomically."""
    with atomic_file(target) as fh:
        fh.write(data)


def write_atomic_text(target: str | os.PathLike[str], text: str) -> None:
    """Replace ``target`` by ``text`` (UTF-8) atomically (result files of the CLI)."""
    write_atomic_bytes(target, text.encode("utf-8"))


class StagedFiles:
    """Several outputs written all or nothing (``convert STACK DIR --format json``).

    :meth:`add` creates a temporary file beside each target (rule 2) and returns its path;
    :meth:`commit` renames every one over its target once all are written; :meth:`abort` (or
    leaving the ``with`` block on an error) removes them, so a failure in the middle (a bad
    problem, a full disk) leaves no output behind, and a folder this run created is removed
    when it is left empty.
    """

    def __init__(self, created_folder: Path | None = None) -> None:
        self.staged: list[tuple[Path, Path, tuple[int, int]]] = []
        self.created_folder = created_folder

    def add(self, target: str | os.PathLike[str]) -> Path:
        target = Path(target)
        _check_replaceable(target)
        fd, tmp = _create_temp(target)
        try:
            st = os.fstat(fd)
        finally:
            os.close(fd)
        self.staged.append((tmp, target, (st.st_dev, st.st_ino)))
        return tmp

    def commit(self) -> None:
        with writing(self.staged[0][1] if self.staged else "."):
            for tmp, target, ident in self.staged:  # everything on disk before any rename
                fd = _open_nofollow(tmp, os.O_RDONLY)
                try:
                    st = os.fstat(fd)
                    if (st.st_dev, st.st_ino) != ident:
                        raise ProblemError(f"its temporary file {tmp.name} was replaced while "
                                           f"it was written", str(target))
                    os.fsync(fd)
                    os.fchmod(fd, _target_mode(target))
                finally:
                    os.close(fd)
            for tmp, target, _ident in self.staged:
                _check_replaceable(target)
                os.replace(tmp, target)
            if self.staged:
                _fsync_folder(self.staged[0][1].parent)
        self.staged = []

    def abort(self) -> None:
        for tmp, _target, _ident in self.staged:
            remove_file(tmp)
        self.staged = []
        if self.created_folder is not None:
            with contextlib.suppress(OSError):
                self.created_folder.rmdir()  # only when empty

    def __enter__(self) -> StagedFiles:
        return self

    def __exit__(self, kind: Any, exc: Any, tb: Any) -> None:
        if kind is not None:
            self.abort()


# ----------------------------------------------------------------------------- appending
class AppendFile:
    """A text file written in place by appending rows (batch results, the HDF5 journal).

    Opened ``O_WRONLY | O_APPEND | O_CREAT | O_NOFOLLOW``: a link is refused.  Every
    :meth:`write` either lands completely or is cut back (``ftruncate``) to the end of the last
    complete row and raises :class:`OutputError`, so the file is always a resumable prefix.
    Text is UTF-8; names that are not valid UTF-8 (file names from ``os.fsdecode``) are written
    as their original bytes (``surrogateescape``).
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = Path(path)
        self.fd = _open_nofollow(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT)
        self.end = os.fstat(self.fd).st_size
        self.rows = 0

    def write(self, text: str, rows: int = 1) -> None:
        data = memoryview(text.encode("utf-8", "surrogateescape"))
        try:
            done = 0
            while done < len(data):
                done += os.write(self.fd, data[done:])
        except OSError as exc:
            with contextlib.suppress(OSError):
                os.ftruncate(self.fd, self.end)
            err = output_error(exc, self.path, "the rows written before are kept: free space "
                                               "or fix the permissions, then run again with "
                                               "--resume")
            if err is None:
                raise
            raise err from None
        self.end += len(data)
        self.rows += rows

    def sync(self) -> None:
        with writing(self.path):
            os.fsync(self.fd)

    @property
    def closed(self) -> bool:
        return self.fd < 0

    def close(self) -> None:
        if self.fd >= 0:
            fd, self.fd = self.fd, -1
            try:
                with writing(self.path):
                    os.fsync(fd)
            finally:
                os.close(fd)


def truncate_file(path: str | os.PathLike[str], size: int) -> None:
    """Cut an own file (no link followed) to ``size`` bytes and fsync it."""
    fd = _open_nofollow(path, os.O_WRONLY)
    try:
        with writing(path):
            os.ftruncate(fd, size)
            os.fsync(fd)
    finally:
        os.close(fd)


# ----------------------------------------------------------------------------- HDF5
class SafeSink(io.RawIOBase):
    """A file descriptor as h5py's ``fileobj`` driver sees it (rule 4).

    The first failed write (or truncate) is kept in :attr:`error` and every later write is
    discarded while reporting success, so HDF5 never fails a flush or a close; callers ask
    :meth:`check` after each step and once the file is closed.  Reads past the end of the file
    give zeros, as HDF5's own driver does.  With ``strict`` a failed write raises at once (the
    file object of :func:`atomic_file`).
    """

    def __init__(self, fd: int, path: str | os.PathLike[str], *, strict: bool = False) -> None:
        super().__init__()
        self.fd, self.path, self.strict = fd, str(path), strict
        self.pos = 0
        self.error: OSError | None = None

    def readable(self) -> bool:
        return True

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def seek(self, offset: int, whence: int = 0) -> int:
        if whence == os.SEEK_SET:
            self.pos = offset
        else:
            self.pos = os.lseek(self.fd, offset, whence)
        return self.pos

    def tell(self) -> int:
        return self.pos

    def read(self, size: int = -1) -> bytes:
        if size is None or size < 0:
            size = max(0, os.fstat(self.fd).st_size - self.pos)
        data = os.pread(self.fd, size, self.pos)
        while len(data) < size:
            more = os.pread(self.fd, size - len(data), self.pos + len(data))
            if not more:
                data += bytes(size - len(data))
                break
            data += more
        self.pos += size
        return data

    def readinto(self, buffer: Any) -> int:
        data = self.read(len(buffer))
        buffer[:len(data)] = data
        return len(data)

    def write(self, data: Any) -> int:
        view = memoryview(data).cast("B")
        size = len(view)
        if self.error is None:
            try:
                done = 0
                while done < size:
                    done += os.pwrite(self.fd, view[done:], self.pos + done)
            except OSError as exc:
                self.error = exc
                if self.strict:
                    raise
        self.pos += size
        return size

    def truncate(self, size: int | None = None) -> int:
        size = self.pos if size is None else size
        if self.error is None:
            try:
                os.ftruncate(self.fd, size)
            except OSError as exc:
                self.error = exc
        return size

    def flush(self) -> None:
        pass

    def check(self, note: str = "") -> None:
        """Raise the recorded write failure as an :class:`OutputError`."""
        if self.error is not None:
            raise output_error(self.error, self.path, note) or OSError(self.error)


class Hdf5Handle:
    """An HDF5 file opened through a :class:`SafeSink` (:func:`open_hdf5`): ``file`` is the
    ``h5py.File``; :meth:`check` raises a recorded write failure; :meth:`close` closes the
    h5py file first, then the descriptor, and raises a write failure after both."""

    def __init__(self, path: str | os.PathLike[str], mode: str, **kwargs: Any) -> None:
        import h5py

        self.path = str(path)
        flags = {"r": os.O_RDONLY, "r+": os.O_RDWR, "w": os.O_RDWR | os.O_CREAT | os.O_TRUNC}[mode]
        fd = _open_nofollow(path, flags)
        self.sink = SafeSink(fd, path)
        try:
            self.file = h5py.File(self.sink, mode, **kwargs)
        except BaseException as exc:
            os.close(fd)
            if isinstance(exc, (OSError, RuntimeError, ValueError)) and mode != "w":
                raise ProblemError(f"not a readable HDF5 file ({str(exc).splitlines()[0][:80]})",
                                   self.path) from None
            raise
        self.mode = mode

    def check(self, note: str = "") -> None:
        self.sink.check(note)

    def flush(self) -> None:
        self.file.flush()
        self.sink.check()

    def start_writeback(self) -> None:
        """Have the OS start writing what was written so far to the disk, without waiting
        (:func:`start_writeback`), so that the ``fsync`` of :meth:`close` is left little to
        wait for."""
        if self.mode != "r" and self.sink.fd >= 0 and self.sink.error is None:
            start_writeback(self.sink.fd)

    def close(self, note: str = "") -> None:
        """Close (idempotent); a write failure is raised after everything is closed."""
        if self.sink.fd < 0:
            return
        try:
            if self.file.id.valid:
                self.file.close()
            if self.mode != "r" and self.sink.error is None:
                try:
                    os.fsync(self.sink.fd)
                except OSError as exc:
                    self.sink.error = exc
        finally:
            os.close(self.sink.fd)
            self.sink.fd = -1
        self.sink.check(note)


#: ``sync_file_range`` of the C library (Linux), once looked up; False where there is none.
_SYNC_FILE_RANGE: Any = None
#: ``SYNC_FILE_RANGE_WRITE`` (linux/fs.h): start writing the dirty pages, do not wait.
_SYNC_FILE_RANGE_WRITE = 2


def start_writeback(fd: int) -> None:
    """Start writing the dirty pages of the file open on ``fd`` to the disk and return
    without waiting for them (Linux ``sync_file_range(fd, 0, 0, SYNC_FILE_RANGE_WRITE)``);
    nothing where the C library has no such call, and nothing on its failure.  Durability
    is still the ``fsync`` at the file's close; this only starts the writing earlier, so
    that ``fsync`` has less left to wait for (a stacked result file written chunk by chunk:
    closing it after the last chunk took 4.7-6.8 ms, 0.6-0.7 ms with the writeback of each
    chunk started as it was written, n = 12, K = 100,000)."""
    global _SYNC_FILE_RANGE
    if _SYNC_FILE_RANGE is None:
        try:
            import ctypes

            call = ctypes.CDLL(None, use_errno=True).sync_file_range
            call.argtypes = [ctypes.c_int, ctypes.c_int64, ctypes.c_int64, ctypes.c_uint]
            call.restype = ctypes.c_int
            _SYNC_FILE_RANGE = call
        except (ImportError, OSError, AttributeError, TypeError):  # not Linux
            _SYNC_FILE_RANGE = False
    if _SYNC_FILE_RANGE:
        _SYNC_FILE_RANGE(fd, 0, 0, _SYNC_FILE_RANGE_WRITE)  # an error (-1) changes nothing


@contextmanager
def open_hdf5(path: str | os.PathLike[str], mode: str = "w", **kwargs: Any
              ) -> Iterator[Any]:
    """An ``h5py.File`` on ``path`` through a :class:`SafeSink` (rule 4): ``mode`` "w" (the
    path is a temporary file of :func:`atomic_path`), "r+" or "r" (no link followed).  The
    file is closed before a write failure is raised as :class:`OutputError`."""
    handle = Hdf5Handle(path, mode, **kwargs)
    try:
        with writing(path):
            yield handle.file
    except BaseException:
        with contextlib.suppress(Exception):  # the error on its way is the one to report
            handle.close()
        raise
    handle.close()


def check_dataset(d: Any, path: str | os.PathLike[str]) -> None:
    """Refuse a virtual dataset or one stored in another file (rule 5), or one stored in
    chunks far larger than its data (:func:`~lcpcli.io.files.check_h5_chunks`), before it is
    read."""
    dcpl = d.id.get_create_plist()
    import h5py

    what = "a virtual dataset" if dcpl.get_layout() == h5py.h5d.VIRTUAL else \
        "a dataset stored in another file" if dcpl.get_external_count() > 0 else None
    if what is not None:
        raise ForeignObjectError(f"holds {what} ({d.name}), which lcpcli never writes: refusing "
                                 f"to read or write through it (run again without --resume to "
                                 f"replace the file)", str(path))
    try:
        check_h5_chunks(d.id, d.name)
    except ProblemError as exc:  # lcpcli never writes such chunks: refused, never rebuilt
        raise ForeignObjectError(str(exc), str(path)) from None


def check_hdf5_tree(f: Any, path: str | os.PathLike[str], *, datasets: bool = True) -> None:
    """Refuse an HDF5 file whose objects reach outside it (rule 5): an external or soft link
    anywhere, and with ``datasets`` a virtual dataset or a dataset with external storage
    (ForeignObjectError).  Without ``datasets`` the caller checks the datasets it reads
    (:func:`check_dataset`): one pass over the links only, for files of many groups."""
    import h5py

    bad: list[str] = []

    def visit(name: bytes, info: Any) -> None:
        if info.type == h5py.h5l.TYPE_EXTERNAL:
            bad.append(f"an external link ({name.decode(errors='replace')})")
        elif info.type != h5py.h5l.TYPE_HARD:
            bad.append(f"a soft link ({name.decode(errors='replace')})")
        return None

    f.id.links.visit(visit, info=True)
    if not bad and datasets:
        datasets: list[bytes] = []

        def collect(name: bytes) -> None:
            obj = h5py.h5o.get_info(f.id, name)
            if obj.type == h5py.h5o.TYPE_DATASET:
                datasets.append(name)

        f.id.links.visit(collect)
        for name in datasets:
            d = h5py.h5d.open(f.id, name)
            dcpl = d.get_create_plist()
            if dcpl.get_layout() == h5py.h5d.VIRTUAL:
                bad.append(f"a virtual dataset ({name.decode(errors='replace')})")
            elif dcpl.get_external_count() > 0:
                bad.append(f"a dataset stored in another file ({name.decode(errors='replace')})")
            if bad:
                break
            try:
                check_h5_chunks(d, name.decode(errors="replace"))
            except ProblemError as exc:  # lcpcli never writes such chunks
                raise ForeignObjectError(str(exc), str(path)) from None
    if bad:
        raise ForeignObjectError(f"holds {bad[0]}, which lcpcli never writes: refusing to read or "
                           f"write through it (run again without --resume to replace the "
                           f"file)", str(path))


# ----------------------------------------------------------------------------- locks
def lock_path(target: str | os.PathLike[str]) -> Path:
    """The lock file of an incrementally written output: ``OUTPUT.lock`` beside it."""
    target = Path(target)
    return target.with_name(target.name + ".lock")


@contextmanager
def output_lock(target: str | os.PathLike[str]) -> Iterator[None]:
    """Hold an exclusive ``flock`` on ``OUTPUT.lock`` while ``target`` is being written.

    A second writer of the same output is refused at once (ProblemError with the first one's
    pid).  The lock file (``O_NOFOLLOW``: a link is refused) is removed when the holder is
    done; one left by a killed run holds no lock and is taken over.
    """
    import fcntl

    lock = lock_path(target)
    while True:
        try:
            fd = _open_nofollow(lock, os.O_RDWR | os.O_CREAT, 0o644)
        except ProblemError as exc:
            raise ProblemError(f"cannot use the lock file ({exc})", str(target)) from None
        except OutputError as exc:
            raise OutputError(str(target), f"{exc.reason} (cannot create the lock file "
                                           f"{lock})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 32).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise ProblemError(f"is being written by another lcpcli run (pid {holder}; lock "
                               f"file {lock}): wait for it to finish or choose another "
                               f"output", str(target)) from None
        except OSError:
            os.close(fd)
            raise
        mine = os.fstat(fd)
        try:
            now = os.lstat(lock)
        except FileNotFoundError:
            now = None
        if now is not None and (now.st_dev, now.st_ino) == (mine.st_dev, mine.st_ino):
            break
        os.close(fd)  # the previous holder removed this lock file meanwhile: take a new one
    try:
        with contextlib.suppress(OSError):  # the pid is a courtesy; a full disk must not stop us
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()}\n".encode())
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(lock)  # while still holding it: nobody can lock this inode after us
        os.close(fd)
