"""Teaching in a terminal (issue 16): layouts, one step at a time, exports for lecture notes,
principal-pivoting and sweep traces, ``pivot --driving/--follow``, clean cone pictures."""

from __future__ import annotations

import json
import os
import re
import select
import shutil
import subprocess
import sys
import time

import numpy as np
import pytest

TEXT = {"NO_COLOR": "1", "COLUMNS": "120"}


# ------------------------------------------------------------------------ solve --trace
def test_json_trace_has_pivot_elements(cli, samples):
    p = cli("solve", str(samples / "seed000.json"), "--trace", "--json")
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout)
    trace = d["trace"]
    assert trace[0]["pivot"] == 0 and trace[0]["pivot_element"] is None
    assert len(trace) == d["iterations"] + 1
    for prev, st in zip(trace, trace[1:], strict=False):
        pe = st["pivot_element"]
        assert pe is not None and pe["column"] == st["entering"] and pe["row"] == st["row"]
        assert prev["tableau"][pe["row"] - 1][prev["nonbasic"].index(st["entering"])] == \
            pe["value"]
        assert st["ratio_test"]["formula"] and len(st["ratio_test"]["rows"]) == 3
    assert trace[3]["basis"] == ["z0", "w2", "z3"] and trace[3]["q_prime"] == [1, 5, 1]


def test_json_trace_has_no_negative_zero(cli, samples):
    p = cli("solve", str(samples / "seed000.json"), "--trace", "--json")
    assert p.returncode == 0 and "-0.0" not in p.stdout and json.loads(p.stdout)["trace"]


@pytest.mark.parametrize("method", ["lemke", "murty"])
def test_empty_problem_trace_says_empty_basis(cli, tmp_path, method):
    f = tmp_path / "n0.json"
    f.write_text(json.dumps({"M": [], "q": []}))
    p = cli("solve", str(f), "-m", method, "--trace", env=TEXT)
    assert p.returncode == 0, p.stderr
    text = " ".join(p.stdout.split())
    assert "empty basis" in text and "(basis ;" not in text and "(;" not in text


def test_murty_layout_text(cli, samples):
    p = cli("solve", str(samples / "seed000.json"), "--layout", "murty", env=TEXT)
    assert p.returncode == 0, p.stderr
    assert "w - M z - d z0 = q  (murty layout)" in p.stdout
    assert "Step 0: initial tableau" in p.stdout and "Step 5: after pivot 5" in p.stdout
    assert "[-1]" in p.stdout  # Murty's first pivot element, on -d
    assert "z1 enters because w1 left" in p.stdout
    assert "q_i / a_i" in p.stdout and "never blocks" in p.stdout
    assert "status             solved" in p.stdout


def test_pivot_k_alone(cli, samples):
    p = cli("solve", str(samples / "seed000.json"), "--pivot", "3", env=TEXT)
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith("Step 3: after pivot 3: z3 entered, z1 left")
    assert "Step 2" not in p.stdout and "Step 4" not in p.stdout
    assert "w2 leaves (row 2)" in p.stdout and "status" not in p.stdout
    bad = cli("solve", str(samples / "seed000.json"), "--pivot", "9")
    assert bad.returncode == 2 and "steps 0..5" in bad.stderr and bad.stdout == ""


def test_pivot_k_alone_in_json(cli, samples, tmp_path):
    """``--pivot K --json``: the JSON holds step K alone (it held every step, --pivot was
    ignored); the last state's step with the ray decision after it; out of range: exit 2."""
    full = json.loads(cli("solve", str(samples / "seed000.json"), "--trace", "--json").stdout)
    one = cli("solve", str(samples / "seed000.json"), "--pivot", "3", "--json")
    assert one.returncode == 0, one.stderr
    got = json.loads(one.stdout)
    assert got["trace"] == [full["trace"][3]] and got["z"] == full["z"]
    bad = cli("solve", str(samples / "seed000.json"), "--pivot", "9", "--json")
    assert bad.returncode == 2 and "steps 0..5" in bad.stderr and bad.stdout == ""
    ray = tmp_path / "ray.json"
    ray.write_text('{"M": [[-1, 0], [0, -1]], "q": [-1, -1]}')
    last = json.loads(cli("solve", str(ray), "-m", "lemke", "--pivot", "1", "--json").stdout)
    assert [s["rule"] for s in last["trace"]] == ["initial", "ray"]
    sweeps = json.loads(cli("solve", str(samples / "seed004.json"), "-m", "pgs", "--pivot", "2",
                            "--json").stdout)
    assert [s["sweep"] for s in sweeps["trace"]] == [2]
    seq = [str(samples / "seed004.json"), "-d", "w1,w2", "--driving", "z0", "--follow"]
    steps = json.loads(cli("pivot", *seq, "--json").stdout)["steps"]
    alone = cli("pivot", *seq, "--json", "--pivot", "1")
    assert alone.returncode == 0 and json.loads(alone.stdout)["dependent"] == \
        steps[1]["dependent"], alone.stderr
    bad = cli("pivot", *seq, "--json", "--pivot", "7")
    assert bad.returncode == 2 and "steps 0..3" in bad.stderr and bad.stdout == ""


def test_degenerate_lexicographic_tie_break_is_shown(cli, samples):
    p = cli("solve", str(samples / "degenerate_lex.json"), "--pivot", "1", "--layout", "murty",
            env=TEXT)
    assert p.returncode == 0, p.stderr
    assert "Tie-break: rows of B^-1" in p.stdout
    assert "column w2: row 2: 1, row 3: 0 -> kept row 3" in p.stdout
    assert "w3 leaves (row 3)" in p.stdout


def test_step_without_a_terminal_prints_every_step(cli, samples):
    start = time.monotonic()
    p = cli("solve", str(samples / "seed000.json"), "--step", stdin="", env=TEXT, timeout=60)
    assert time.monotonic() - start < 60
    assert p.returncode == 0, p.stderr
    assert "needs a terminal" in p.stderr
    assert all(f"Step {k}:" in p.stdout for k in range(6))


@pytest.mark.skipif(not hasattr(os, "openpty") or sys.platform == "win32", reason="POSIX pty")
def test_step_on_a_terminal_waits_for_keys(root, samples):
    """Under a pseudo-terminal: one page per screen, n goes on, b goes back, q quits."""
    import pty

    pid, fd = pty.fork()
    if pid == 0:  # child: the CLI on the terminal
        env = dict(os.environ, PYTHONPATH=str(root), COLUMNS="100", LINES="60", TERM="dumb")
        os.execvpe(sys.executable, [sys.executable, "-m", "lcpcli", "solve",
                                    str(samples / "seed000.json"), "--step"], env)
    out = b""

    def read_until(needle: bytes, count: int = 1, limit: float = 60) -> None:
        nonlocal out
        end = time.monotonic() + limit
        while out.count(needle) < count:
            left = end - time.monotonic()
            assert left > 0, out.decode(errors="replace")[-2000:]
            ready, _, _ = select.select([fd], [], [], left)
            if ready:
                try:
                    chunk = os.read(fd, 65536)
                except OSError:  # the child closed the terminal
                    break
                if not chunk:
                    break
                out += chunk

    try:
        read_until(b"page 1 of 6")
        assert b"Step 0: initial tableau" in out and b"Step 1:" not in out
        os.write(fd, b"n")
        read_until(b"page 2 of 6")
        assert b"Step 1: after pivot 1" in out
        os.write(fd, b"b")
        read_until(b"page 1 of 6", count=2)  # back to the first page
        os.write(fd, b"q")
        read_until(b"status")  # quit: the result follows
        _, status = os.waitpid(pid, 0)
    finally:
        os.close(fd)
    assert os.WEXITSTATUS(status) == 0
    assert b"Step 2:" not in out


def latex_shape(text: str) -> None:
    begins = re.findall(r"\\begin\{(\w+)\}", text)
    ends = re.findall(r"\\end\{(\w+)\}", text)
    assert sorted(begins) == sorted(ends)
    stack = []
    for m in re.finditer(r"\\(begin|end)\{(\w+)\}", text):
        if m.group(1) == "begin":
            stack.append(m.group(2))
        else:
            assert stack and stack.pop() == m.group(2)
    assert not stack
    assert text.count("{") == text.count("}") + text.count("\\{") - text.count("\\}")


def test_latex_export_shape(cli, samples):
    p = cli("solve", str(samples / "seed000.json"), "--format", "latex")
    assert p.returncode == 0, p.stderr
    tex = p.stdout
    latex_shape(tex)
    tabulars = re.findall(r"\\begin\{tabular\}.*?\\end\{tabular\}", tex, re.S)
    assert len(tabulars) == 6  # one per step: the initial tableau and 5 pivots
    for k, tab in enumerate(tabulars):
        assert tab.count("\\fbox{") == (1 if k < 5 else 0)  # the pivot element, boxed
    assert "\\fbox{$-2$}" in tabulars[2]  # pivot 3: z3 enters on -2 (dictionary signs)
    assert tex.count("\\subsection*{Step") == 6
    assert "status" not in tex  # the export alone on stdout
    assert "$z_{0}$" in tex and "\\fbox{$1$}" in tabulars[0]
    murty = cli("solve", str(samples / "seed000.json"), "--format", "tex", "--layout", "murty",
                "--pivot", "0").stdout
    latex_shape(murty)
    assert "\\fbox{$-1$}" in murty and murty.count("\\begin{tabular}") == 1


def test_markdown_export_to_file(cli, samples, tmp_path):
    target = tmp_path / "notes.md"
    p = cli("solve", str(samples / "seed000.json"), "--format", "markdown", "-o", str(target),
            env=TEXT)
    assert p.returncode == 0, p.stderr
    md = target.read_text()
    assert md.count("### Step ") == 6 and "| basic | q' |" in md and "**[-2]**" in md
    assert "status             solved" in p.stdout  # the usual result on the terminal
    assert f"wrote {target}" in p.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == ["notes.md"]


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex is not installed")
def test_latex_exports_compile(cli, samples, tmp_path):
    """Every export of the samples, \\input{} into one document, compiles without an error."""
    runs = {"trace": ["solve", "seed000.json", "--format", "latex"],
            "murty": ["solve", "degenerate_lex.json", "--format", "latex", "--layout", "murty"],
            "pivot": ["pivot", "seed000_augmented.json", "-d", "w1,w2,w3", "--driving", "z0",
                      "--follow", "--full", "--format", "latex"],
            "enum": ["enumerate", "seed004.json", "--all-cones", "--format", "latex"],
            "principal": ["solve", "seed004.json", "-m", "murty", "--format", "latex"],
            "sweeps": ["solve", "box_small.json", "-m", "psor", "--format", "latex"],
            "events": ["solve", "seed004.json", "-m", "dantzig", "--format", "latex"]}
    for name, (cmd, file, *rest) in runs.items():
        p = cli(cmd, str(samples / file), *rest, "-o", str(tmp_path / f"{name}.tex"))
        assert p.returncode == 0, (name, p.stderr)
    body = "\n".join(f"\\input{{{name}}}" for name in runs)
    (tmp_path / "main.tex").write_text("\\documentclass{article}\n\\begin{document}\n"
                                       f"{body}\n\\end{{document}}\n")
    p = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "main.tex"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stdout[-3000:]
    assert (tmp_path / "main.pdf").stat().st_size > 0


def test_export_never_overwrites_the_input(cli, samples, tmp_path):
    src = tmp_path / "p.json"
    src.write_text((samples / "seed000.json").read_text())
    before = src.read_text()
    for args in (["solve", str(src), "--format", "latex", "-o", str(src)],
                 ["pivot", str(src), "-d", "z0,w2,z3", "--format", "latex", "-o", str(src)],
                 ["enumerate", str(src), "--format", "markdown", "-o", str(src)]):
        p = cli(*args)
        assert p.returncode == 2 and "same file as the input" in p.stderr, args
        assert src.read_text() == before


def test_export_and_json_cannot_share_stdout(cli, samples, tmp_path):
    p = cli("solve", str(samples / "seed000.json"), "--format", "latex", "--json")
    assert p.returncode == 2 and "-o FILE" in p.stderr and p.stdout == ""
    target = tmp_path / "t.tex"
    p = cli("solve", str(samples / "seed000.json"), "--format", "latex", "--json", "-o",
            str(target))
    assert p.returncode == 0 and json.loads(p.stdout)["trace"]
    latex_shape(target.read_text())
    p = cli("solve", str(samples / "seed000.json"), "--step", "--format", "latex")
    assert p.returncode == 2 and "--step" in p.stderr


@pytest.mark.parametrize("method, kind", [("murty", "principal"), ("dantzig", "dantzig"),
                                          ("pgs", "sweep"), ("psor", "sweep")])
def test_principal_and_sweep_traces(cli, samples, method, kind):
    p = cli("solve", str(samples / "seed004.json"), "-m", method, "--trace", "--json")
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout)
    assert {s["kind"] for s in d["trace"]} == {kind}
    text = cli("solve", str(samples / "seed004.json"), "-m", method, "--trace", env=TEXT).stdout
    if kind == "principal":
        steps = d["trace"]
        assert [s["alpha"] for s in steps] == [[], [1], [1, 2]]
        assert [(s["entering"], s["leaving"]) for s in steps[1:]] == [("z1", "w1"),
                                                                      ("z2", "w2")]
        assert "Principal pivots at a glance" in text and "alpha = beta = {1, 2}" in text
        # the JSON says how the method ended, and the page states that, not its own test
        assert [s.get("end") for s in steps] == [None, None, "solved"]
        assert "this basis solves the LCP" in text
    elif kind == "dantzig":
        assert [s["sets"]["clamped"] for s in d["trace"]] == [[], [1], [1, 2]]
        assert "Events at a glance" in text
    else:
        sweeps = [s["sweep"] for s in d["trace"]]
        assert sweeps[0] == 0 and sweeps[-1] == d["iterations"]
        assert "the first sweeps and the last" in text


@pytest.mark.parametrize("exact", ["--exact", "--no-exact"])
def test_murty_trace_when_q_is_nonnegative(cli, tmp_path, exact):
    # no pivot, but the starting basis (z = 0) is a step that solves the LCP
    f = tmp_path / "qpos.json"
    f.write_text(json.dumps({"M": [[1, 2], [3, 4]], "q": [1, 0]}))
    d = json.loads(cli("solve", str(f), "-m", "murty", "--trace", "--json", exact).stdout)
    assert [(s["pivot"], s["rule"], s.get("end")) for s in d["trace"]] == [(0, "start", "solved")]
    p = cli("solve", str(f), "-m", "murty", "--pivot", "0", exact, env=TEXT)
    assert p.returncode == 0 and p.stdout.startswith("Step 0: starting basis")
    assert "this basis solves the LCP" in p.stdout and "--exact" not in p.stderr


def test_murty_glance_lists_only_the_pivots_made(cli, samples):
    # seed000's first pivot element is 0: Murty stops without a pivot
    f = str(samples / "seed000.json")
    d = json.loads(cli("solve", f, "-m", "murty", "--trace", "--json").stdout)
    assert d["iterations"] == 0 and d["trace"][-1]["rule"] == "bad_pivot"
    text = cli("solve", f, "-m", "murty", "--trace", "--no-exact", env=TEXT).stdout
    glance = text[text.index("Principal pivots at a glance"):text.index("problem ")]
    rows = [x.split() for x in glance.splitlines() if x.strip()[:1].isdigit()]
    assert [r[0] for r in rows] == ["0"] and "not > 0" not in glance
    assert "Not made: least index with q' < 0 is row 1" in " ".join(glance.split())


def test_sweep_trace_covers_every_kernel_call(cli, tmp_path):
    # the method calls its kernel several times (blocks of sweeps, a tightened target): the
    # trace is the whole run's, numbered by the true sweep count, from z = 0
    lap5 = tmp_path / "lap5.json"
    lap5.write_text(json.dumps({"M": (2 * np.eye(5) - np.eye(5, k=1) - np.eye(5, k=-1))
                                .tolist(), "q": [-1] * 5}))
    d = json.loads(cli("solve", str(lap5), "-m", "pgs", "--trace", "--json").stdout)
    n = d["iterations"]
    assert n > 50
    assert [s["sweep"] for s in d["trace"]] == [*range(11), n]
    assert d["trace"][0]["z"] == [0.0] * 5 and d["trace"][-1]["z"] == d["z"]
    p = cli("solve", str(lap5), "-m", "pgs", "--pivot", str(n), env=TEXT)
    assert p.returncode == 0 and p.stdout.startswith(f"Sweep {n}")
    pm3 = tmp_path / "pmatrix3.json"
    pm3.write_text(json.dumps({"M": [[4, -1, 0], [-1, 4, -1], [0, -1, 4]], "q": [-1, -2, 3]}))
    d = json.loads(cli("solve", str(pm3), "-m", "pgs", "--trace", "--json").stdout)
    assert [s["sweep"] for s in d["trace"]] == list(range(d["iterations"] + 1))
    assert d["trace"][0]["z"] == [0.0] * 3 and d["trace"][1]["z"] != d["z"]


def test_default_method_traces_the_problems_kind(cli, samples):
    # auto + --trace: Lemke on an LCP, Dantzig on a box LCP; an MLCP has no traced method
    d = json.loads(cli("solve", str(samples / "box_small.json"), "--trace", "--json").stdout)
    assert d["method"] == "dantzig" and d["status"] == "solved" and d["trace"]
    assert json.loads(cli("solve", str(samples / "seed000.json"), "--trace", "--json")
                      .stdout)["method"].startswith("lemke")
    p = cli("solve", str(samples / "mlcp_small.json"), "--trace")
    assert p.returncode == 2 and "no method with a step-by-step replica handles MLCP" in \
        p.stderr and "dantzig" in p.stderr and "Traceback" not in p.stderr


def test_methods_without_a_replica_refuse_trace(cli, samples):
    p = cli("solve", str(samples / "seed004.json"), "-m", "newton", "--trace")
    assert p.returncode == 2 and "no step-by-step replica" in p.stderr
    assert "murty" in p.stderr and "psor" in p.stderr and "Traceback" not in p.stderr


# ------------------------------------------------------------------------ pivot
def test_pivot_driving_ratio_test_json(cli, samples):
    p = cli("pivot", str(samples / "seed000_augmented.json"), "-d", "z4,w2,z3", "-i",
            "w1,w3,z2,z1", "--driving", "z2", "--json")
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout)
    rt = d["ratio_test"]
    assert rt["blocking"] == "z0" and rt["row"] == 1 and rt["pivot_element"]["value"] == -1
    assert [r["eligible"] for r in rt["rows"]] == [True, True, False]
    text = cli("pivot", str(samples / "seed000_augmented.json"), "-d", "z0,w2,z3",
               "--driving", "w1", env=TEXT).stdout
    text = " ".join(text.split())  # rich wraps long lines
    assert "blocking variable: w2 (row 2 of w')" in text
    assert "by the complementary rule z2 enters at the next Lemke step" in text


def test_pivot_follow_is_lemkes_path(cli, samples):
    p = cli("pivot", str(samples / "seed000_augmented.json"), "-d", "w1,w2,w3", "--driving",
            "z0", "--follow", "--json")
    assert p.returncode == 0, p.stderr
    steps = json.loads(p.stdout)["steps"]
    assert [s["dependent"] for s in steps] == [["w1", "w2", "w3"], ["z0", "w2", "w3"],
                                               ["z0", "w2", "z1"], ["z0", "w2", "z3"],
                                               ["z0", "w1", "z3"], ["z2", "w1", "z3"]]
    assert [s["ratio_test"]["blocking"] for s in steps[:-1]] == ["w1", "w3", "z1", "w2", "z0"]
    assert steps[-1]["ratio_test"] is None and steps[-1]["q_prime"] == [1, 2, 3]
    assert steps[3]["q_prime"] == [1, 5, 1] and steps[3]["driving_column"][1] == -1
    one = cli("pivot", str(samples / "seed000_augmented.json"), "-d", "w1,w2,w3", "--driving",
              "z0", "--follow", "--pivot", "3", "--layout", "murty", "--full", env=TEXT)
    assert one.returncode == 0, one.stderr
    assert "dependent   w' = (z0, w2, z3)" in one.stdout and "Basis 4 of 6" in one.stdout
    assert "original tableau" not in one.stdout


def test_pivot_sequence_and_errors(cli, samples):
    f = str(samples / "seed000_augmented.json")
    p = cli("pivot", f, "-d", "z0,w2,w3", "-d", "z0,w2,z1", "--json")
    assert p.returncode == 0 and len(json.loads(p.stdout)["steps"]) == 2
    p = cli("pivot", f, "-d", "z0,w2,w3", "-d", "z0,w2,z1", "--driving", "z1")
    assert p.returncode == 2 and "one --driving per --dependent" in p.stderr
    p = cli("pivot", f, "-d", "z0,w2,w3", "--follow")
    assert p.returncode == 2 and "--follow" in p.stderr
    p = cli("pivot", f, "-d", "z0,w2,w3", "--layout", "tableau")
    assert p.returncode == 2 and "--layout" in p.stderr
    p = cli("pivot", f, "-d", "z0,w2,w3", "-o", "x.tex")
    assert p.returncode == 2 and "--format" in p.stderr


def test_pivot_latex_export(cli, samples, tmp_path):
    target = tmp_path / "pivot.tex"
    p = cli("pivot", str(samples / "seed000_augmented.json"), "-d", "z4,w2,z3", "-i",
            "w1,w3,z2,z1", "--driving", "z2", "--full", "--format", "latex", "-o", str(target))
    assert p.returncode == 0, p.stderr
    tex = target.read_text()
    latex_shape(tex)
    assert "$\\{3,\\allowbreak  1\\}$" in tex  # beta', one formula (issue 27)
    line = next(x for x in tex.splitlines() if x.startswith("$q^{\\alpha}"))
    assert line.count("$") == 4 and "$,\\quad $q^{\\bar{\\alpha}}" in line  # two formulas
    assert tex.count("\\fbox{") >= 2  # the pivot element in the ratio test and the tableau


# ------------------------------------------------------------------------ enumerate
def test_enumerate_exports(cli, samples):
    p = cli("enumerate", str(samples / "seed004.json"), "--all-cones", "--format", "latex")
    assert p.returncode == 0, p.stderr
    latex_shape(p.stdout)
    assert p.stdout.count("\\begin{tabular}") == 2  # cones and solutions
    md = cli("enumerate", str(samples / "seed004.json"), "--format", "markdown").stdout
    assert "| 4 | [-2 -1; -1 -2] |" in md and "unique solution" in md


def test_output_streams_without_unicode_get_ascii(cli, samples, tmp_path):
    # an output stream that cannot encode the box characters: the cone drawing is ASCII and
    # no command fails on a character (exit 3)
    three = tmp_path / "three_sol.json"
    three.write_text(json.dumps({"M": [[1, 2], [2, 1]], "q": [-1, -1]}))
    ascii_env = {**TEXT, "PYTHONIOENCODING": "ascii"}
    p = cli("enumerate", str(three), env=ascii_env)
    assert p.returncode == 0, p.stderr
    assert "#" in p.stdout and "|" in p.stdout and "# 2+ cones" in p.stdout
    utf = cli("enumerate", str(three), env={**TEXT, "PYTHONIOENCODING": "utf-8"}).stdout
    assert "\u2502" in utf and "\u2592 2+ cones" in utf  # box characters where they encode
    seed = str(samples / "seed000.json")
    for args in (["enumerate", str(three), "--all-cones", "--lemke-path"],
                 ["solve", seed], ["solve", seed, "--trace"], ["solve", seed, "-m", "murty",
                                                              "--trace"],
                 ["pivot", str(samples / "seed000_augmented.json"), "-d", "z0,w2,z3",
                  "--driving", "z2"], ["info", seed], ["methods"],
                 ["contact-matrix", str(samples / "scene_two_balls.json")],
                 ["contact-matrix", str(samples / "scene_2d_boxes.json"), "--solve"]):
        p = cli(*args, env=ascii_env)
        assert p.returncode in (0, 1) and "internal error" not in p.stderr, (args, p.stderr)


def test_enumerate_singular_counts_agree_with_the_cones(cli, tmp_path):
    # skew: both singular cones are excluded by the sign tests, so none is factorised; the
    # summary says which count is which, and with --all-cones counts the table's marks
    f = tmp_path / "skew.json"
    f.write_text(json.dumps({"M": [[0, 1], [-1, 0]], "q": [0, -1]}))
    d = json.loads(cli("enumerate", str(f), "--all-cones", "--json").stdout)
    marked = sum(c["singular"] for c in d["cones"])
    assert marked == 2 and d["counts"]["singular"] == 0 and d["counts"]["pruned"] == 4
    text = " ".join(cli("enumerate", str(f), "--all-cones", env=TEXT).stdout.split())
    assert "0 singular of the 0 factorised" in text and f"{marked} singular of all 4" in text
    assert text.count(" singular ") - 2 == marked  # the two counts, then one mark per cone
    text = " ".join(cli("enumerate", str(f), env=TEXT).stdout.split())
    assert "0 singular of the 0 factorised" in text and "of all" not in text


def test_enumerate_lemke_path_text_and_errors(cli, samples, tmp_path):
    p = cli("enumerate", str(samples / "seed004.json"), "--lemke-path", env=TEXT)
    assert p.returncode == 0, p.stderr
    assert "Lemke's path q + z0 d" in p.stdout and "*" in p.stdout
    p = cli("enumerate", str(samples / "seed004.json"), "--lemke-path", "--json")
    path = json.loads(p.stdout)["lemke_path"]
    assert [x["z0"] for x in path] == [0, 6, 4, 0]
    p = cli("enumerate", str(samples / "seed000.json"), "--lemke-path")
    assert p.returncode == 2 and "n = 3" in p.stderr


LABELS = ("w1", "w2", "z1", "z2", "q")


@pytest.mark.parametrize("M, q", [([[2, 1], [1, 2]], [-5, -6]), ([[-1, 0], [0, -1]], [1, 2]),
                                  ([[1, 2], [2, 1]], [4, 4.5]), ([[0, 0], [1, 1]], [-1, -1]),
                                  ([[1, -1], [1, 1]], [0.3, -1]), ([[1, 0], [0, 1]], [0, 0])])
def test_ascii_cone_labels_never_collide(M, q):
    from lcpcli.cli.render.enumerate import draw_cones_text

    rows = draw_cones_text(np.array(M, float), np.array(q, float)).plain.splitlines()[:-1]
    found = set()
    for row in rows:
        for m in re.finditer(r"[wzq]\d?", row):
            label = m.group(0)
            if label not in LABELS:
                continue
            found.add(label)
            left = row[m.start() - 1] if m.start() > 0 else " "
            right = row[m.end()] if m.end() < len(row) else " "
            assert left == " " and right == " ", (label, row)
    expected = {"w1", "w2", "q"} | {f"z{j + 1}" for j in range(2) if np.any(np.array(M)[:, j])}
    assert found == expected


def test_png_legend_names_the_cones_and_nothing_is_clipped():
    pytest.importorskip("matplotlib")
    from lcpcli.cli.render.enumerate import cones_figure

    M, q = np.array([[2.0, 1], [1, 2]]), np.array([-5.0, -6])
    path = [{"step": 0, "z0": 0.0, "point": [-5, -6]}, {"step": 1, "z0": 6.0, "point": [1, 0]},
            {"step": 2, "z0": 4.0, "point": [-1, -2]}, {"step": 3, "z0": 0.0, "point": [-5, -6]}]
    fig = cones_figure(M, q, "seed004", path)
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[:4] == ["r = 1: Pos(I1, I2)", "r = 2: Pos(I1, -M2)", "r = 3: Pos(-M1, I2)",
                          "r = 4: Pos(-M1, -M2)"] and "Lemke's path q + z0 d" in labels
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    box = ax.get_window_extent(renderer)
    texts = [t for t in ax.texts if t.get_text()]
    assert {t.get_text() for t in texts} >= {"$I_1$", "$I_2$", "$-M_1$", "$-M_2$"}
    for t in texts + [a for a in ax.get_children() if hasattr(a, "xyann") and a.get_text()]:
        ext = t.get_window_extent(renderer)
        assert box.x0 <= ext.x0 and ext.x1 <= box.x1 and box.y0 <= ext.y0 and ext.y1 <= box.y1, \
            t.get_text()
    legend = ax.get_legend().get_window_extent(renderer)
    assert legend.y1 <= box.y0  # below the axes: it hides no cone
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_plot_with_lemke_path(cli, samples, tmp_path):
    pytest.importorskip("matplotlib")
    target = tmp_path / "cones.png"
    p = cli("enumerate", str(samples / "seed004.json"), "--lemke-path", "--plot", str(target))
    assert p.returncode == 0, p.stderr
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"



@pytest.mark.parametrize("extra", [[], ["-m", "murty"], ["-m", "dantzig"], ["-m", "pgs"],
                                   ["-m", "psor"], ["--exact"]])
def test_traces_of_data_at_the_ends_of_the_float64_range(cli, extra):
    """A trace (and the plain table) of data near 1e308 or subnormal: exit 0 or 1 with the
    trace, and no numpy warning line (intermediates past the range are inf or NaN, as in the
    kernels, and the verdict is the certificate's).  The last four printed warnings from the
    analysis around the traces (the MLCP polish's residual, the forward error bound's 2-norm,
    the not-P witness's 2 x 2 products; found by mutating the sample files)."""
    for doc in ({"M": [[1e308, -1e308], [1e308, 1e308]], "q": [-1e308, 1e308]},
                {"M": [[5e-324]], "q": [-5e-324]},
                {"M": [[2, 1], [100.0, 2]], "q": [-1e308, -1e-308]},
                {"M": [[2.0, 2.0, -1.0, 0.0], [0.0, 9.332636185032189e-302, 0.0, 1.0],
                       [-1.0, -1.0, 2.0, 1.0], [0.0, 1.0, 0.0, 2.0]], "q": [1.0, -2.0, -2.0, -2.0]},
                {"M": [[1.0, 1e16, 0.0, 0.0], [-1e308, 1.0, 2.0, 0.0], [0.0, -5e-324, 1.0, 2.0],
                       [2.0, 100.0, 0.0, 0.5]], "q": [-1.0, 0.0, 0.0, -1.0]},
                {"M": [[5e-324, 1e16], [1, 2]], "q": [-0.5, -6]}):
        for args in (["solve", "-", "--trace", *extra], ["solve", "-"]):
            out = cli(*args, stdin=json.dumps(doc))
            assert out.returncode in (0, 1), out.stderr
            assert "warning" not in out.stderr, (args, out.stderr)


def test_auto_refuses_lemkes_options_with_trace_as_without(cli, samples):
    """``--trace`` runs auto's traced method (Lemke), but the options are still auto's:
    ``--covering`` was accepted with ``--trace`` and refused without it."""
    seed = str(samples / "seed004.json")
    plain = cli("solve", seed, "--covering", "1,2")
    traced = cli("solve", seed, "--covering", "1,2", "--trace")
    assert plain.returncode == traced.returncode == 2
    assert traced.stderr == plain.stderr and "no option 'covering'" in plain.stderr
    assert cli("solve", seed, "-m", "lemke", "--covering", "1,2", "--trace").returncode == 0
