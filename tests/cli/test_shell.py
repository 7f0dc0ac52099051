"""Shell manners (issue 17): help, broken pipes, plurals, small-batch tables, warnings, narrow
terminals, concurrent writers, CSV names through --resume, Ctrl-C of long commands.

Processes that must be interrupted are stopped by the tests themselves after they printed
their first line (no sleeps whose length decides the verdict), and every subprocess runs under
a timeout.
"""

from __future__ import annotations

import io
import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lcpcli.batch.output import read_rows
from lcpcli.core.problem import Problem
from lcpcli.io import save
from lcpcli.io.hdf5_format import write_many

ROOT = Path(__file__).resolve().parents[2]


def popen(*args: str, cwd: Path | None = None, **kw: object) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    env.pop("LCPCLI_DEBUG", None)
    return subprocess.Popen([sys.executable, "-m", "lcpcli", *args], env=env, cwd=cwd or ROOT,
                            **kw)  # type: ignore[call-overload]


def big_problem(path: Path, n: int = 300) -> None:
    rng = np.random.default_rng(3)
    A = rng.standard_normal((n, n))
    save(Problem.create(A @ A.T + n * np.eye(n), rng.standard_normal(n)), path)


def test_bare_lcpcli_prints_the_formatted_help_and_exits_2(cli):
    r = cli()
    assert r.returncode == 2 and r.stdout == ""
    lines = r.stderr.splitlines()
    assert lines[0].startswith("Usage: lcpcli") and len(lines) > 10
    assert any(line.strip().startswith("solve ") for line in lines)  # one command per line
    assert "Exit codes" in r.stderr


@pytest.mark.parametrize("as_json", [False, True])
def test_broken_pipe_is_not_a_failure(tmp_path, as_json):
    big_problem(tmp_path / "big.json")
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the first byte: every write fails
    args = ["solve", str(tmp_path / "big.json"), "-m", "lemke"] + (["--json"] if as_json else [])
    proc = popen(*args, stdout=write_end, stderr=subprocess.PIPE)
    os.close(write_end)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert err == b""  # no traceback, no "Exception ignored" from the final flush


def test_broken_pipe_keeps_not_solved(tmp_path):
    (tmp_path / "none.json").write_text('{"M": [[-1]], "q": [-1]}')
    read_end, write_end = os.pipe()
    os.close(read_end)
    proc = popen("solve", str(tmp_path / "none.json"), stdout=write_end, stderr=subprocess.PIPE)
    os.close(write_end)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1 and err == b""


def test_small_batch_prints_one_line_per_problem_and_plurals(cli, tmp_path):
    (tmp_path / "a.json").write_text('{"M": [[2, 1], [1, 2]], "q": [-5, -6]}')
    (tmp_path / "b.json").write_text('{"M": [[-1]], "q": [-1]}')
    (tmp_path / "c.json").write_text('{"M": [[1]], "q": [true]}')
    r = cli("solve", "a.json", "b.json", "c.json", cwd=tmp_path, env={"COLUMNS": "200"})
    assert r.returncode == 2
    lines = r.stdout.splitlines()
    for name, status in (("a.json", "solved"), ("b.json", "no_solution"), ("c.json", "error")):
        assert any(name in line and status in line for line in lines), (name, r.stdout)
    assert any("q holds booleans" in line for line in lines)
    r = cli("solve", "a.json", "--jobs", "1", cwd=tmp_path)
    assert "1 problem done" in r.stdout and not re.search(r"\b1 problems\b", r.stdout)
    r = cli("solve", str(ROOT / "samples" / "collection.h5"), "-m", "lemke")
    assert "5 problems done" in r.stdout


def test_multi_problem_hdf5_runs_as_a_batch(cli, tmp_path):
    probs = [Problem.create(np.eye(2) * (k + 1), [-1.0, -2.0], name=f"p{k}") for k in range(3)]
    write_many(probs, tmp_path / "many.h5")
    r = cli("solve", str(tmp_path / "many.h5"), "--json")
    rows = [json.loads(line) for line in r.stdout.splitlines()]
    assert r.returncode == 0 and sorted(row["problem"] for row in rows) == ["p0", "p1", "p2"]
    r = cli("solve", str(tmp_path / "many.h5"), "-p", "p1", "--json")
    assert r.returncode == 0 and json.loads(r.stdout)["problem"] == "p1"


def test_warnings_are_one_clean_line():
    """A warning raised inside a command is one 'lcpcli: warning:' line, no path, no code."""
    code = ("import warnings, sys\n"
            "from lcpcli.cli import app, main\n"
            "@app.command('warn-test')\n"
            "def warn_test() -> int:\n"
            "    warnings.warn('something odd\\nover two lines', RuntimeWarning)\n"
            "    return 0\n"
            "main(['warn-test'])\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                       timeout=60)
    assert r.returncode == 0
    assert r.stderr == "lcpcli: warning: something odd over two lines\n"


def test_bench_tables_fit_narrow_terminals():
    """At 50 columns nothing is cut with an ellipsis: tables split or fold instead."""
    from rich.console import Console

    from lcpcli.bench.runner import BenchReport, Record
    from lcpcli.cli.render.bench import render_report

    methods = ["lemke-revised", "lemke-tableau", "newton-min", "interior-point"]
    records = [Record(problem=f"FrictionContactProblem{k:05d}", n=10 + k, method=m,
                      status="solved", seconds=0.00123456 * (k + 1), iterations=7,
                      error=1.234e-17 * (i + 1), expected="solvable", defect=False, tol=1e-8,
                      success=True, repeats=3)
               for k in range(3) for i, m in enumerate(methods)]
    report = BenchReport(records=records, methods=methods, tols=[1e-8],
                         problems=[(f"FrictionContactProblem{k:05d}", 10 + k, "lcp", "solvable")
                                   for k in range(3)])
    console = Console(width=50, record=True, file=open(os.devnull, "w"))  # noqa: SIM115
    console.print(render_report(report, "narrow", width=50))
    text = console.export_text()
    assert "…" not in text
    for m in methods:
        assert m in text
    for cell in ("1.2e-17", "2.5e-17", "3.7e-17", "4.9e-17", "1.23", "3.7"):
        assert cell in text, cell
    assert max(len(line) for line in text.splitlines()) <= 50


def test_second_writer_of_one_output_is_refused(tmp_path):
    """Two batches, one output: the second is refused at once; the first loses no row."""
    for k in range(4):  # Murty's problems: 2^n pivots for Lemke, slow enough to overlap
        n = 20
        M = np.tril(2.0 * np.ones((n, n)), -1) + np.eye(n)
        save(Problem.create(M, -np.ones(n)), tmp_path / f"m{k}.json")
    first = popen("solve", *[f"m{k}.json" for k in range(4)], "-m", "lemke-tableau", "-j", "1",
                  "-O", "max_iter=10000000", "-o", "r.jsonl", "--json", cwd=tmp_path,
                  stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        lock = tmp_path / "r.jsonl.lock"
        deadline = 600
        import time

        start = time.monotonic()
        while not lock.exists() and first.poll() is None and time.monotonic() - start < deadline:
            time.sleep(0.05)
        second = popen("solve", "m0.json", "m1.json", "-o", "r.jsonl", cwd=tmp_path,
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        out2, err2 = second.communicate(timeout=120)
        out1, err1 = first.communicate(timeout=600)
    finally:
        first.kill()
    if first.returncode == 0 and b"being written" not in err2:
        pytest.skip("the first batch finished before the second started (machine too fast)")
    assert second.returncode == 2 and out2 == b""
    assert err2.decode().startswith("lcpcli: error: r.jsonl: is being written by another "
                                    f"lcpcli run (pid {first.pid}")
    rows = read_rows(tmp_path / "r.jsonl")
    assert first.returncode == 0, err1
    assert sorted(r["source"] for r in rows) == [f"m{k}.json" for k in range(4)]
    assert not (tmp_path / "r.jsonl.lock").exists()


def test_csv_names_with_commas_quotes_newlines_resume(cli, tmp_path):
    names = ['comma,name', 'quote"name', "new\nline", "cr\rname", " spaced ", "plain"]
    probs = [Problem.create(np.eye(2) * (k + 1), [-1.0, -1.0], name=name)
             for k, name in enumerate(names)]
    write_many(probs, tmp_path / "odd.h5")
    (tmp_path / 'file,with "odd"\nname.json').write_text('{"M": [[1]], "q": [-1]}')
    inputs = ["odd.h5", 'file,with "odd"\nname.json']
    r = cli("solve", *inputs, "-o", "r.csv", "-j", "1", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    first = read_rows(tmp_path / "r.csv")
    assert sorted(row["problem"] for row in first) == sorted(names + ['file,with "odd"\nname'])
    r = cli("solve", *inputs, "-o", "r.csv", "--resume", "--json", cwd=tmp_path)
    summary = json.loads(r.stdout)
    assert summary["skipped"] == 7 and summary["new"] == 0
    assert read_rows(tmp_path / "r.csv") == first
    # a torn last record (cut inside a quoted name) is dropped and re-solved on --resume
    data = (tmp_path / "r.csv").read_bytes()
    cut = data.rfind(b'"new\nline"') + 5
    if cut > 5:
        (tmp_path / "r.csv").write_bytes(data[:cut])
        r = cli("solve", *inputs, "-o", "r.csv", "--resume", "--json", cwd=tmp_path)
        assert r.returncode == 0
        rows = read_rows(tmp_path / "r.csv")
        assert len(rows) == 7 and {row["problem"] for row in rows} == set(names) | {
            'file,with "odd"\nname'}


def _interrupt_after_first_line(proc: subprocess.Popen, stream: str) -> tuple[bytes, bytes]:
    """The first line of ``stream``, then SIGINT, then everything else.  ``proc``'s pipes must
    be unbuffered (``bufsize=0``): communicate() reads the file descriptors directly, so bytes
    a buffered readline() had read ahead would be lost (a record's first half)."""
    pipe = proc.stderr if stream == "stderr" else proc.stdout
    assert isinstance(pipe, io.RawIOBase), "popen(..., bufsize=0)"
    first = pipe.readline()  # type: ignore[union-attr]
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    return (out, first + err) if stream == "stderr" else (first + out, err)


def test_enumerate_beyond_2_24_cones_estimates_and_stops_on_ctrl_c(tmp_path):
    n = 30
    rng = np.random.default_rng(0)
    A = rng.standard_normal((n, n))
    save(Problem.create(A @ A.T / n + np.eye(n), rng.standard_normal(n)), tmp_path / "e.json")
    proc = popen("enumerate", "e.json", "--max-n", "30", cwd=tmp_path, stdout=subprocess.PIPE,
                 stderr=subprocess.PIPE, bufsize=0)
    out, err = _interrupt_after_first_line(proc, "stderr")
    text = err.decode()
    assert text.startswith("lcpcli: enumerating 2^30 = 1,073,741,824 complementary cones")
    assert proc.returncode == 130 and out == b""
    assert "lcpcli: interrupted after" in text and "of 1,073,741,824 cones" in text
    assert "Traceback" not in text


def test_bench_stops_on_ctrl_c_with_the_finished_runs(tmp_path):
    proc = popen("bench", "--suite", "hard", "--n", "3", "-m", "lemke,murty", "--no-peers",
                 "--timeout", "0", "--json", cwd=tmp_path, stdout=subprocess.PIPE,
                 stderr=subprocess.PIPE, bufsize=0)
    out, err = _interrupt_after_first_line(proc, "stdout")
    records = [json.loads(line) for line in out.decode().splitlines()]
    assert proc.returncode == 130, err
    assert records and all("method" in r for r in records)
    text = err.decode()
    assert text.startswith("lcpcli: bench: ") and "lcpcli: interrupted after" in text
    assert "Traceback" not in text


BOX = re.compile("[\u2500-\u257f]")  # box-drawing characters (rules, corners, edges)
COLOUR = re.compile(r"(^|;)(3[0-9]|4[0-9]|9[0-7]|10[0-7])(;|$)")  # SGR colour parameters
TABLE_COMMANDS = [
    ("solve", "samples/degenerate.json"),
    ("solve", "samples/degenerate.json", "--trace", "-m", "lemke"),
    ("enumerate", "samples/degenerate.json", "--all-cones"),
    ("info", "samples/degenerate.json"),
    ("methods",),
    ("contact-matrix", "samples/scene_two_balls.json", "--solve"),
    ("solve", "samples/degenerate.json", "samples/seed004.json"),
]


def _words(text):
    """The words of an output, escape codes and rules aside, numbers of the timing kind left
    out (times and rates differ from run to run, and so does the rate's plural: '(1
    problem/s)' in a slow run, '(12 problems/s)' in another)."""
    text = BOX.sub(" ", re.sub(r"\x1b\[[0-9;]*m", "", text))
    return {w for w in text.split()
            if not re.fullmatch(r"\(?[0-9.]+(ms|s|us)?|problems?/s\)?", w)}


@pytest.mark.parametrize("args", TABLE_COMMANDS, ids=lambda a: " ".join(a[:3]))
def test_tables_have_rules_only_on_a_terminal_without_no_color(cli, args):
    """Tables drawn with rules on a terminal; piped, or with NO_COLOR even on a terminal, the
    same rows as plain columns: no box-drawing character, every word still there."""
    terminal = {"TTY_COMPATIBLE": "1", "FORCE_TERMINAL": "1", "COLUMNS": "100"}  # rich 14+ / 13
    boxed = cli(*args, env={**terminal, "NO_COLOR": ""})
    assert boxed.returncode in (0, 1), boxed.stderr
    assert BOX.search(boxed.stdout)
    for env in ({"TTY_COMPATIBLE": "", "FORCE_TERMINAL": "", "NO_COLOR": "", "COLUMNS": "100"},
                {**terminal, "NO_COLOR": "1"}):
        plain = cli(*args, env=env)
        assert plain.returncode == boxed.returncode, plain.stderr
        assert not BOX.search(plain.stdout), plain.stdout[:400]
        if env["NO_COLOR"]:  # on a terminal: bold may stay, no colour (no-color.org)
            codes = re.findall(r"\x1b\[([0-9;]*)m", plain.stdout)
            assert not [c for c in codes if COLOUR.search(c)], codes
        else:
            assert "\x1b[" not in plain.stdout
        assert _words(plain.stdout) == _words(boxed.stdout)


@pytest.mark.parametrize(("env", "tty", "expected"), [
    ({}, False, False), ({}, True, True),
    ({"TTY_COMPATIBLE": "1"}, False, True), ({"TTY_COMPATIBLE": "0"}, True, False),
    ({"TTY_COMPATIBLE": "0", "FORCE_TERMINAL": "1"}, False, False),
    ({"FORCE_TERMINAL": "1"}, False, True), ({"FORCE_TERMINAL": "0"}, True, False),
    ({"FORCE_COLOR": "1"}, False, True), ({"FORCE_COLOR": ""}, True, False),
])
def test_one_terminal_rule_for_both_consoles_and_the_progress_bars(monkeypatch, env, tty,
                                                                   expected):
    """rich's overrides (TTY_COMPATIBLE, then FORCE_TERMINAL, then FORCE_COLOR), else the
    stream's isatty: the stdout and stderr consoles and the progress bars ask the same rule."""
    from lcpcli.cli import common

    for name in ("TTY_COMPATIBLE", "FORCE_TERMINAL", "FORCE_COLOR", "NO_COLOR"):
        monkeypatch.delenv(name, raising=False)
    for name, value in env.items():
        monkeypatch.setenv(name, value)

    class Stream(io.StringIO):
        def isatty(self):
            return tty

    monkeypatch.setattr(sys, "stdout", Stream())
    monkeypatch.setattr(sys, "stderr", Stream())
    assert common.is_terminal(sys.stdout) is expected
    assert common.stdout_console().is_terminal is expected
    assert common.stderr_console().is_terminal is expected
    assert common.progress_allowed() is expected


def test_a_name_with_a_newline_stays_on_its_row(cli, tmp_path, samples):
    """A file name holding a newline or an escape split its table row ('a' on one line,
    'b.json' on the next) or sent a control sequence: names are shown with such characters
    escaped, in the batch table and in the one-problem table."""
    for name in ("a\nb.json", "c\x1b[31md.json"):
        (tmp_path / name).write_bytes((samples / "seed004.json").read_bytes())
    out = cli("solve", "a\nb.json", "c\x1b[31md.json", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "a\\nb.json" in out.stdout and "c\\x1b[31md.json" in out.stdout
    assert "\x1b" not in out.stdout and not any(
        line.strip().startswith("b.json") for line in out.stdout.splitlines())
    one = cli("solve", "a\nb.json", cwd=tmp_path)
    assert one.returncode == 0 and "a\\nb.json : seed004" in one.stdout
