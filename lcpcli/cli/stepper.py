"""``--step``: one page per screen on a terminal, waiting for a key; and ``--pivot K``.

Keys: ``n``, space, Enter or the right arrow: next page; ``b``, ``p`` or the left arrow:
back; ``q``, Esc or Ctrl-C: quit.  ``--step`` needs a terminal on stdin and stdout; otherwise
it never waits: every page is printed in order (with a note on stderr), as without ``--step``.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Callable, Iterator
from typing import Any

from lcpcli.cli.render.doc import Page, to_rich
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


def _loop(console: Any, pages: list[Page], labels: list[str], keys: Callable[[], str]) -> int:
    k = 0
    while True:
        console.clear()
        console.print(to_rich([pages[k]]))
        console.print(f"\n{labels[k]}  (page {k + 1} of {len(pages)})   [n]ext  [b]ack  "
                      f"[q]uit", style="dim", highlight=False, markup=False)
        act = None
        while act is None:
            act = action(keys())
        if act == QUIT:
            return k
        if act == NEXT:
            if k == len(pages) - 1:
                return k
            k += 1
        elif act == BACK and k > 0:
            k -= 1


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
