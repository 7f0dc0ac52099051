"""The CLI as a Unix tool under an operator's hands: standard streams that are closed or
point the wrong way, and signals.

Every run is a subprocess started by ``sh`` (so that the redirections are the shell's own)
under a timeout.  A signal is sent by the process to itself at a fixed point of its work (a
patched function), never after a sleep, so the verdicts do not depend on timing.
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "samples" / "seed004.json"


def sh(command: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """``command`` run by sh, where ``LCPCLI`` is this checkout's CLI; stderr captured
    (unless the command redirects it)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("LCPCLI_DEBUG", None)
    lcpcli = f"{shlex.quote(sys.executable)} -m lcpcli"
    return subprocess.run(["sh", "-c", command.replace("LCPCLI", lcpcli)], cwd=cwd or ROOT,
                          env=env, capture_output=True, text=True, timeout=120)


def one_error_line(stderr: str, text: str) -> None:
    lines = stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("lcpcli: error: ") and text in lines[0], \
        stderr


@pytest.mark.parametrize("redirect", [">&-", "1</dev/null"])
@pytest.mark.parametrize("args", [f"solve {SAMPLE} --json", f"solve {SAMPLE}",
                                  f"convert {SAMPLE} -", "methods", "--version"])
def test_stdout_that_cannot_be_written_is_one_line_and_exit_2(args, redirect):
    """A closed standard output (``>&-``) or one open for reading only is an output that
    cannot be written: one line, exit 2 (it was a traceback and exit 1, or exit 3)."""
    r = sh(f"LCPCLI {args} {redirect}")
    assert r.returncode == 2, r.stderr
    one_error_line(r.stderr, "standard output: not open for writing")


@pytest.mark.parametrize("redirect", ["2>&-", "2</dev/null"])
def test_closed_stderr_keeps_the_exit_codes(tmp_path, redirect):
    """With no usable stderr the line is lost, never the exit code: bad input stays 2 (it
    was 1, the status of the traceback that writing the line raised), solved stays 0."""
    assert sh(f"LCPCLI solve {tmp_path / 'missing.json'} {redirect}").returncode == 2
    assert sh(f"LCPCLI solve {SAMPLE} --json {redirect} >/dev/null").returncode == 0
    assert sh(f"LCPCLI solve {SAMPLE} --json {redirect} >&-").returncode == 2


def test_closed_stdin_for_dash_is_one_line_and_exit_2():
    r = sh("LCPCLI solve - <&-")
    assert r.returncode == 2 and r.stdout == ""
    one_error_line(r.stderr, "-: standard input is not open")
