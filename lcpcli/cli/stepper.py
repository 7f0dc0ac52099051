"""``--step``: one page per screen on a terminal, waiting for a key; and ``--pivot K``.

Keys: ``n``, space, Enter or the right arrow: next screen; ``b``, ``p`` or the left arrow:
back; ``q``, Esc or Ctrl-C: quit.  ``--step`` needs a terminal on stdin and stdout; otherwise
it never waits: every page is printed in order (with a note on stderr), as without ``--step``.

A screen never scrolls: a step whose page is taller than the terminal goes on over several
screens ("screen 1 of 2"), the step title and the tableau first, cut between blocks (a
paragraph, a table, a column block of a wide table) wherever possible.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Callable, Iterator
from typing import Any

from rich.segment import Segment, Segments
from rich.text import Text

from lcpcli.cli.render.doc import Grid, Heading, Page, Para, to_rich
from lcpcli.core.errors import OptionError

NEXT, BACK, QUIT = "next", "back", "quit"

_KEYS = {"n": NEXT, " ": NEXT, "\r": NEXT, "\n": NEXT, "\x1b[C": NEXT, "\x1b[B": NEXT,
         "j": NEXT, "b": BACK, "p": BACK, "\x1b[D": BACK, "\x1b[A": BACK, "k": BACK,
         "q": QUIT, "\x1b": QUIT, "\x03": QUIT, "\x04": QUIT, "": QUIT}


def interactive() -> bool:
    """Whether ``--step`` can wait for keys: stdin and stdout are both terminals."""
    try:
        return sys.stdin.isatty() and sys.stdout.isatty()
    except (AttributeError, ValueError):
        return False


def read_key() -> str:
    """One key press from stdin (a terminal in cbreak mode, see :func:`_keyboard`); an arrow
    key's escape sequence comes back whole."""
    import select  # POSIX: only the --step session reads keys

    fd = sys.stdin.fileno()
    key = os.read(fd, 1)
    if key == b"\x1b" and select.select([fd], [], [], 0.05)[0]:
        key += os.read(fd, 2)
    return key.decode("utf-8", "replace")


@contextlib.contextmanager
def _keyboard() -> Iterator[None]:
    """Keys without Enter and without echo for the whole session (cbreak mode, set at once so
    that no key typed early is flushed); the terminal is restored on the way out."""
    import termios  # POSIX terminal control; imported here because only --step needs it
    import tty

    fd = sys.stdin.fileno()
    old = termios.tcgetattr(fd)
    try:
        tty.setcbreak(fd, termios.TCSANOW)
        yield
    finally:
        termios.tcsetattr(fd, termios.TCSANOW, old)


def action(key: str) -> str | None:
    """The action of a key (``None``: ignore it)."""
    if key in _KEYS:
        return _KEYS[key]
    return _KEYS.get(key[:1].lower()) if key[:1].isalpha() else None


def step_through(console: Any, pages: list[Page], labels: list[str],
                 keys: Callable[[], str] | None = None) -> int:
    """Show ``pages`` one per screen until the user quits; return the last page shown.

    ``keys`` reads one key (default: :func:`read_key`); the tests pass a scripted reader.
    """
    if keys is None:
        try:
            import termios  # noqa: F401  (POSIX only)
        except ImportError:
            raise OptionError("--step needs a POSIX terminal; use --pivot K to show one "
                              "step") from None
        with _keyboard():
            return _loop(console, pages, labels, read_key)
    return _loop(console, pages, labels, keys)


Line = list[Segment]


def footer(label: str, screen: int, screens: int, page: int, pages: int) -> str:
    """The key line under a screen (``screen``, ``page``: 0-based)."""
    more = f", screen {screen + 1} of {screens}" if screens > 1 else ""
    return f"{label}{more}  (page {page + 1} of {pages})  [n]ext [b]ack [q]uit"


def footer_height(console: Any, labels: list[str]) -> int:
    """Lines under the page: a blank line and the key line (wrapped on a narrow screen)."""
    longest = max(labels, key=len) if labels else ""
    text = footer(longest, 8, 9, len(labels), len(labels))
    return 1 + len(console.render_lines(Text(text), console.options, pad=False))


def screens(console: Any, page: Page, below: int = 2) -> list[list[Line]]:
    """``page`` cut into screens of ``console.height - below`` lines.

    Blocks stay whole when they fit a screen, a heading or paragraph together with the table
    it introduces; a taller block (a wide table in column blocks, a long list) is cut after
    its last blank line that fits, else at the screen's end.
    """
    avail = max(1, console.height - below)
    units: list[list[Any]] = []
    for block in page:  # a heading or paragraph stays with the table it introduces
        last = units[-1][-1] if units else None
        glue = isinstance(last, Heading) or (isinstance(block, Grid) and isinstance(last, Para))
        if glue:
            units[-1].append(block)
        else:
            units.append([block])
    out: list[list[Line]] = []
    current: list[Line] = []
    for unit in units:
        lines = console.render_lines(to_rich([unit]), console.options, pad=False)
        if current and len(current) + len(lines) > avail:
            out.append(current)
            current = []
        while len(current) + len(lines) > avail:
            room = avail - len(current)
            blank = [k for k in range(1, room + 1) if not Segment.get_line_length(lines[k - 1])]
            cut = blank[-1] if blank and blank[-1] > room // 2 else room
            out.append(current + lines[:cut])
            current, lines = [], lines[cut:]
        current += lines
    if current or not out:
        out.append(current)
    return out


def _loop(console: Any, pages: list[Page], labels: list[str], keys: Callable[[], str]) -> int:
    flat: list[tuple[int, int, list[Line]]] = []
    count: dict[int, int] = {}
    below = footer_height(console, labels)
    for k, page in enumerate(pages):
        parts = screens(console, page, below)
        count[k] = len(parts)
        flat += [(k, s, part) for s, part in enumerate(parts)]
    i = 0
    while True:
        k, s, lines = flat[i]
        console.clear()
        console.print(Segments([seg for line in lines for seg in (*line, Segment.line())]),
                      end="")
        console.print("\n" + footer(labels[k], s, count[k], k, len(pages)), style="dim",
                      highlight=False, markup=False)
        act = None
        while act is None:
            act = action(keys())
        if act == QUIT:
            return k
        if act == NEXT:
            if i == len(flat) - 1:
                return k
            i += 1
        elif act == BACK and i > 0:
            i -= 1


def print_all(console: Any, pages: list[Page]) -> None:
    """``--step`` without a terminal: every page in order, nothing waits."""
    sys.stderr.write("lcpcli: --step needs a terminal on stdin and stdout; printing every "
                     "step instead\n")
    console.print(to_rich(pages))


def pick(pages: list[Page], k: int, numbers: list[int], what: str) -> list[Page]:
    """``--pivot K``: the page numbered ``K`` alone (exit 2 with the valid numbers otherwise)."""
    if k not in numbers:
        valid = (f"{numbers[0]}..{numbers[-1]}" if numbers == list(range(numbers[0],
                                                                          numbers[-1] + 1))
                 else ", ".join(map(str, numbers))) if numbers else "none"
        raise OptionError(f"--pivot {k}: {what} has steps {valid}")
    return [pages[numbers.index(k)]]
