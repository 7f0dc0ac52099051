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


#: A CLI run in a subprocess whose atomic writer, right before it renames its temporary
#: file over the output (``lcpcli.io.writing._commit``), sends ``SIG`` to its own process;
#: with ``SWALLOWED`` the handler runs inside a weak reference's callback, where Python can
#: only ignore what it raises, and the writer then waits for the signal to come back.
SELF_SIGNAL = """
import os, signal, sys, time, weakref
import lcpcli.io.writing as writing
from lcpcli.cli import main

SIG, SWALLOWED = getattr(signal, sys.argv[1]), sys.argv[2] == "swallowed"
real = writing._commit


class Thing:
    pass


def spin():
    for _ in range(1000):  # the handler runs at one of these steps
        pass


def on_collect(ref):
    os.kill(os.getpid(), SIG)
    spin()


def commit(fd, tmp, target):
    if SWALLOWED:
        thing = Thing()
        ref = weakref.ref(thing, on_collect)
        del thing  # on_collect runs now, and the interrupt raised inside it is ignored
        for _ in range(30000):  # until it comes back (a lost one commits after 30 s)
            time.sleep(0.001)
    else:
        os.kill(os.getpid(), SIG)
        spin()
    return real(fd, tmp, target)


writing._commit = commit
main(sys.argv[3:])
"""


@pytest.mark.parametrize(("sig", "code", "word"), [("SIGTERM", 143, "terminated"),
                                                    ("SIGINT", 130, "interrupted"),
                                                    ("SIGHUP", 129, "hung up")])
@pytest.mark.parametrize("where", ["plain", "swallowed"])
def test_signal_while_an_output_is_written_leaves_the_previous_file(tmp_path, sig, code, word,
                                                                   where):
    """SIGTERM (``kill``, ``timeout``, a job scheduler) and SIGHUP (the terminal closed)
    stop a one-file output as Ctrl-C does: exit 143 or 129, one line, the previous output
    byte for byte, no temporary file (each killed the process, exit -15 or -1, and left
    ``.out.json.XXXXXXXX.tmp`` beside it).  An interrupt raised where Python ignores it (a
    weak reference's callback) is delivered again, not lost (it was: the command ran on and
    exited 0)."""
    out = tmp_path / "out.json"
    out.write_text("previous\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("LCPCLI_DEBUG", None)
    r = subprocess.run([sys.executable, "-c", SELF_SIGNAL, sig, where, "solve", str(SAMPLE),
                        "-o", str(out)], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == code, r.stderr
    assert r.stderr == f"lcpcli: {word}\n"
    assert out.read_text() == "previous\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


@pytest.mark.parametrize("ext", ["npz", "h5"])
def test_sighup_while_a_stack_is_converted_leaves_the_previous_file(tmp_path, ext):
    """``lcpcli convert many.h5 out.npz --stack`` hung up as it replaces its output: exit
    129, one line, the previous output byte for byte and no temporary file beside it."""
    import numpy as np

    from lcpcli.core.problem import Problem
    from lcpcli.io.hdf5_format import write_many

    many, out = tmp_path / "in" / "many.h5", tmp_path / "out" / f"out.{ext}"
    many.parent.mkdir(), out.parent.mkdir()
    write_many([Problem.create(np.eye(2) * (k + 1), [-1.0, k], name=f"p{k}") for k in range(5)],
               many)
    out.write_bytes(b"previous\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("LCPCLI_DEBUG", None)
    r = subprocess.run([sys.executable, "-c", SELF_SIGNAL, "SIGHUP", "plain", "convert",
                        str(many), str(out), "--stack", "--force"],
                       env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 129, r.stderr
    assert r.stderr == "lcpcli: hung up\n"
    assert out.read_bytes() == b"previous\n"
    assert sorted(p.name for p in out.parent.iterdir()) == [out.name]


def test_nohup_keeps_a_command_running_after_sighup(tmp_path):
    """Started with SIGHUP ignored (``nohup lcpcli ...``), a command keeps ignoring it: the
    output is written and the exit code is the work's (0)."""
    import signal

    out = tmp_path / "out.json"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("LCPCLI_DEBUG", None)
    r = subprocess.run([sys.executable, "-c", SELF_SIGNAL, "SIGHUP", "plain", "solve",
                        str(SAMPLE), "-o", str(out)], env=env, capture_output=True, text=True,
                       timeout=120, preexec_fn=lambda: signal.signal(signal.SIGHUP,
                                                                     signal.SIG_IGN))
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert '"status": "solved"' in out.read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]


def run_with_broken_stderr(*args: str) -> tuple[int, str]:
    """``lcpcli ARGS`` whose stderr is a pipe whose reader is gone before the first byte:
    the exit code and stdout."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("LCPCLI_DEBUG", None)
    try:
        r = subprocess.run([sys.executable, "-m", "lcpcli", *args], stderr=write_end,
                           stdout=subprocess.PIPE, text=True, env=env, cwd=ROOT, timeout=120)
    finally:
        os.close(write_end)
    return r.returncode, r.stdout


def test_a_broken_stderr_loses_the_lines_never_the_work(tmp_path):
    """A reader of stderr that went away (``2>&1 | head -1``, a stopped log collector)
    loses the diagnostics, not the work nor its exit code: a note on stderr stopped the
    solve (exit 1, nothing on stdout), a bad input exited 1 instead of 2."""
    import json

    import numpy as np

    from lcpcli.core.problem import Problem
    from lcpcli.io import save

    rng = np.random.default_rng(5)
    A = rng.standard_normal((20, 20))
    save(Problem.create(A @ A.T + 20 * np.eye(20), rng.standard_normal(20)), tmp_path / "p.json")
    # -m enum from n = 20 on announces its cost on stderr first
    code, out = run_with_broken_stderr("solve", str(tmp_path / "p.json"), "-m", "enum", "--json")
    assert code == 0 and json.loads(out)["status"] == "solved"
    assert run_with_broken_stderr("solve", str(tmp_path / "missing.json"))[0] == 2
    assert run_with_broken_stderr()[0] == 2  # bare lcpcli: the help goes to stderr


def test_a_batch_stopped_before_its_output_exists_does_not_point_at_it(tmp_path, monkeypatch,
                                                                        capsys):
    """Ctrl-C before the result file was made: the line said "finished results are in
    r.jsonl: run again with --resume" about a file that did not exist."""
    import lcpcli.batch.run
    from lcpcli.cli import main

    def stopped(*args, **kwargs):  # type: ignore[no-untyped-def]
        raise KeyboardInterrupt

    monkeypatch.setattr(lcpcli.batch.run, "run_batch", stopped)
    out = tmp_path / "r.jsonl"
    with pytest.raises(SystemExit) as exc:
        main(["solve", str(SAMPLE), str(SAMPLE.parent / "degenerate.json"), "-o", str(out)])
    err = capsys.readouterr().err
    assert exc.value.code == 130
    assert err == f"lcpcli: interrupted; nothing was written to {out}\n"
    assert not out.exists()


def on_a_terminal(args: list[str], term: str) -> str:
    """``lcpcli ARGS`` on a pseudo-terminal (100 columns) with ``TERM=term``: what it wrote
    there, CR LF as LF."""
    import pty
    import select

    env = {**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "100", "LINES": "60", "TERM": term}
    for name in ("NO_COLOR", "FORCE_COLOR", "FORCE_TERMINAL", "TTY_COMPATIBLE", "LCPCLI_DEBUG"):
        env.pop(name, None)
    pid, fd = pty.fork()
    if pid == 0:  # child: the CLI on the terminal
        os.execvpe(sys.executable, [sys.executable, "-m", "lcpcli", *args], env)
    out = b""
    try:
        while select.select([fd], [], [], 120)[0]:
            try:
                chunk = os.read(fd, 65536)
            except OSError:  # the child closed the terminal
                break
            if not chunk:
                break
            out += chunk
    finally:
        os.close(fd)
        os.waitpid(pid, 0)
    return out.decode().replace("\r\n", "\n")


@pytest.mark.skipif(not hasattr(os, "openpty") or sys.platform == "win32", reason="POSIX pty")
@pytest.mark.parametrize("args", [["solve", str(SAMPLE)], ["methods"],
                                  ["solve", str(SAMPLE), str(SAMPLE.parent / "degenerate.json")],
                                  ["info", str(SAMPLE)]])
def test_a_dumb_terminal_gets_ascii_rules_and_nothing_else_changes(args):
    """``TERM=dumb`` (Emacs' shell, a terminal that cannot draw boxes): tables are ruled with
    ASCII (``+--+``, ``|``), no escape sequence (colour, bold) is written, and every line is
    the one a capable terminal gets with its box characters and styles taken out (the table
    was drawn with ``┏━┳`` and ``│`` there too); a batch's progress bar is drawn with ``-``
    (it is shown once, at its end: rich draws no live display on a dumb terminal)."""
    import re

    dumb, xterm = on_a_terminal(args, "dumb"), on_a_terminal(args, "xterm-256color")
    assert dumb.isascii() and "\x1b" not in dumb, dumb
    assert "+--" in dumb and "|" in dumb
    assert "━" in xterm and "\x1b[" in xterm  # the same run on a terminal that draws them
    plain = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", xterm)  # styles, and the live display's moves

    def masked(text: str) -> list[str]:  # timings vary from run to run
        lines = [re.sub(r"\d", "0", line) for line in text.splitlines()]
        bar = [i for i, line in enumerate(lines) if line.startswith("solving ")]
        if bar:  # what follows the progress bar (after it, rich's end of a live display)
            lines = lines[bar[-1] + 1:]
            while lines and not lines[0]:
                lines.pop(0)
        return lines

    rules = str.maketrans({"┃": "|", "│": "|", "━": "-"})  # and the joints are ASCII's own
    wanted = [line.translate(rules) for line in masked(plain)]
    got = masked(dumb)
    if "solving " in dumb:
        assert re.search(r"^solving -{10,} 2/2 solved 2 ", dumb, re.M), dumb
    assert len(got) == len(wanted)
    for mine, theirs in zip(got, wanted, strict=True):
        if not set(theirs) <= set("|- ") and not any(c.isalnum() for c in theirs):
            # a rule (┏━┳━┓, ┡━╇━┩, └─┴─┘): ASCII's edges and joints
            assert len(mine) == len(theirs) and set(mine) <= set("+-|"), (mine, theirs)
        else:
            assert mine == theirs
