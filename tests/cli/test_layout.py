"""The layout rule (issue 27): at 60, 80 and 120 columns no number or word is ever cut.

Every sample through every trace (Lemke in both layouts, Murty in both, Dantzig, PGS, PSOR),
``pivot --follow --full``, ``enumerate --all-cones``, ``methods`` and the result table are
rendered on a recording rich console of each width: no "…" anywhere, no line wider than the
console, and every number of the trace appears whole in the output.
"""

from __future__ import annotations

import io
import json
import re
from functools import cache
from pathlib import Path

import pytest
from rich.console import Console
from rich.table import Table

from lcpcli.api import solve
from lcpcli.cli.render.common import fit, fit_table, fmt, render_methods, render_result
from lcpcli.cli.render.pivot import full_pages, step_pages
from lcpcli.core.errors import OptionError
from lcpcli.core.problem import Problem
from lcpcli.io import load
from lcpcli.solvers.trace.exact import EXACT_METHODS, exact_trace, wants_exact

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
WIDTHS = (60, 80, 120)
TRACES = [("lemke", "dictionary"), ("lemke", "murty"), ("murty", "dictionary"),
          ("murty", "murty"), ("dantzig", "dictionary"), ("pgs", "dictionary"),
          ("psor", "dictionary")]
#: Pages rendered of a long trace (n = 200): the first and the last few.
HEAD, TAIL = 3, 2


def _problems() -> list[tuple[str, str | None]]:
    """Every sample file that holds a problem (the contact scenes are not LCP files), each
    problem of the HDF5 collection by name."""
    out: list[tuple[str, str | None]] = []
    for path in sorted(SAMPLES.iterdir()):
        if path.suffix in (".py",) or path.name.startswith("scene_"):
            continue
        if path.suffix == ".h5":
            import h5py

            with h5py.File(path) as f:
                out += [(path.name, name) for name in f]
            continue
        out.append((path.name, None))
    return out


PROBLEMS = _problems()


@cache
def _load(name: str, problem: str | None):
    try:
        return load(str(SAMPLES / name), problem)
    except Exception:  # noqa: BLE001 - the augmented seed file is read by `pivot` only
        return None


def render(renderable: object, width: int) -> str:
    console = Console(width=width, record=True, file=io.StringIO(), color_system=None,
                      highlight=False)
    console.print(renderable)
    return console.export_text()


def assert_fits(text: str, width: int, where: str) -> None:
    assert "…" not in text, (where, [x for x in text.splitlines() if "…" in x][:3])
    long = [x for x in text.splitlines() if len(x) > width]
    assert not long, (where, long[:3])


def _pages(pages: list) -> list:
    return pages if len(pages) <= HEAD + TAIL else pages[:HEAD] + pages[-TAIL:]


def test_every_sample_is_covered():
    names = {n for n, _ in PROBLEMS}
    assert {"seed000.json", "seed004.json", "degenerate_lex.json", "box_small.json",
            "collection.h5", "sparse_chain.npz", "mlcp_small.json"} <= names


@pytest.mark.parametrize("name, problem", PROBLEMS)
@pytest.mark.parametrize("method, layout", TRACES)
def test_traces_fit_every_width(name, problem, method, layout):
    from lcpcli.cli.render.doc import to_rich

    prob = _load(name, problem)
    if prob is None:
        pytest.skip(f"{name} is not a problem file")
    try:
        result = solve(prob, method, trace=True)
    except OptionError:
        pytest.skip(f"{method} does not take a {prob.kind} problem")
    trace = result.trace or []
    if not trace:
        pytest.skip("no step to show")
    data = wants_exact(prob, None) if method in EXACT_METHODS else None
    if data is not None:  # the trace as shown by default: in fractions
        trace = exact_trace(prob, method, data)
    pages = _pages(full_pages(trace, layout)) + _pages(step_pages(trace, layout))
    numbers = {fmt(v) for st in trace[:HEAD] for v in (st.get("q_prime") or st.get("z") or [])
               if v is not None}
    for width in WIDTHS:
        text = render(to_rich(pages), width)
        assert_fits(text, width, (name, problem, method, layout, width))
        flat = text.replace("\n", " ")
        for x in numbers:  # every value whole, not broken over two lines
            assert re.search(rf"(?<![\w.]){re.escape(x)}(?![\w.])", flat), (x, width)
        assert_fits(render(render_result(result, prob, name), width), width, (name, width))


@pytest.mark.parametrize("name, problem", PROBLEMS)
def test_enumerate_fits_every_width(name, problem):
    from lcpcli.analysis.enumeration import covers_plane, enumerate_cones
    from lcpcli.cli.render.enumerate import draw_cones_text, render_enumeration

    prob = _load(name, problem)
    if prob is None or prob.kind != "lcp" or prob.n > 8:
        pytest.skip("enumerate takes small LCPs")
    res = enumerate_cones(prob, all_cones=True, max_n=8)
    M = prob.dense_M()
    drawing = draw_cones_text(M, prob.q) if prob.n == 2 else None
    covers = covers_plane(M) if prob.n == 2 else None
    for width in WIDTHS:
        text = render(render_enumeration(res, prob, name, all_cones=True, covers=covers,
                                         drawing=drawing), width)
        assert_fits(text, width, (name, width))


@pytest.mark.parametrize("layout", ["dictionary", "murty"])
def test_pivot_pages_fit_every_width(layout):
    from lcpcli.analysis.pivoting import parse_tuple, parse_var
    from lcpcli.cli.pivot_cmd import load_augmented
    from lcpcli.cli.render.doc import to_rich
    from lcpcli.cli.render.pivot import pivot_pages
    from lcpcli.solvers.trace.path import follow

    for name in ("seed000_augmented.json", "degenerate_lex.json", "degenerate.json"):
        Maug, q, source = load_augmented(str(SAMPLES / name))
        n = q.shape[0]
        dep = parse_tuple(",".join(f"w{i + 1}" for i in range(n)), n)
        items = follow(Maug, q, dep, None, parse_var("z0", n), full=True)
        pages = pivot_pages(items, Maug, q, source, layout)
        for width in WIDTHS:
            assert_fits(render(to_rich(pages), width), width, (name, layout, width))


def test_methods_fit_every_width():
    from lcpcli.solvers.registry import methods

    for width in WIDTHS:
        text = render(render_methods(methods()), width)
        assert_fits(text, width, width)
        assert "copositive-plus/PSD)" in text


def test_info_fits_every_width(cli, samples):
    # a long file name is wrapped, never cut; auto's plan keeps a hanging indent
    f = str(samples / "seed000.json")
    for width in (40, *WIDTHS):
        p = cli("info", f, env={"COLUMNS": str(width), "NO_COLOR": "1"})
        assert p.returncode == 0, p.stderr
        assert_fits(p.stdout, width, width)
        assert f in "".join(x.split("file", 1)[-1].strip() for x in
                            p.stdout.split("problem ")[0].splitlines())
        plan = [x for x in p.stdout.split("auto would try:")[1].splitlines() if x.strip()]
        assert plan[0].startswith("  1. ")
        assert all(re.match(r"  \d\. |     \S", x) for x in plan), (width, plan)


def test_wide_tableau_splits_into_column_blocks_with_a_note():
    """A table wider than the screen whose words cannot wrap is cut into column blocks,
    each repeating the row names, every cell present exactly once outside the names."""
    table = Table(title="tableau")
    names = ["basic", *[f"x{j}" for j in range(1, 15)]]
    for h in names:
        table.add_column(h, justify="right")
    values = [[f"r{i}", *[f"{-(i + 1) * j / 3:.6g}" for j in range(1, 15)]] for i in range(3)]
    for row in values:
        table.add_row(*row)
    text = render(fit(table), 60)
    assert_fits(text, 60, "blocks")
    assert "tableau: 14 columns in 3 blocks to fit 60 columns" in " ".join(text.split())
    assert text.count("columns x") == 3 and text.count("r0") == 3  # the names in every block
    for row in values:
        for v in row[1:]:
            assert v in text


@pytest.mark.parametrize("width", WIDTHS)
def test_a_title_wider_than_its_table_is_not_wrapped_at_the_table(width):
    """The result table of n = 1 under its 58-character title: the title on one line (rich
    wrapped it at the table's 30 columns, "(n =" on one line and "1)" on the next)."""
    prob = Problem.create([[-1.0]], [-1.0])  # no solution; PGS's last point is shown
    res = solve(prob, "pgs", max_iter=3)
    text = render(render_result(res, prob, "-"), width)
    assert_fits(text, width, "title")
    title = "last point, not a solution (the certificate fails) (n = 1)"
    if width >= len(title):
        assert title in [line.rstrip() for line in text.splitlines()]
    assert "(n =\n" not in text and "(n = 1)" in " ".join(text.split())


@pytest.mark.parametrize("width", WIDTHS)
def test_fit_table_keeps_a_table_that_fits(width):
    table = Table()
    table.add_column("a")
    table.add_row("1")
    console = Console(width=width, file=io.StringIO())
    assert fit_table(table, console, console.options) == [table]


def test_cli_examples_of_the_issue(cli, samples):
    """The issue's own examples, through the command line at 80 and 60 columns."""
    runs = [("solve", "degenerate_lex.json", "--trace", "--layout", "murty"),
            ("solve", "seed004.json", "-m", "dantzig", "--trace"),
            ("solve", "degenerate_lex.json", "--trace"),
            ("methods",)]
    for width in (60, 80):
        for cmd, *rest in runs:
            args = [cmd, *([str(samples / rest[0]), *rest[1:]] if rest else [])]
            p = cli(*args, env={"COLUMNS": str(width), "NO_COLOR": "1"})
            assert p.returncode == 0, p.stderr
            assert_fits(p.stdout, width, (args, width))
    p = cli("solve", str(samples / "seed004.json"), "-m", "dantzig", "--trace",
            env={"COLUMNS": "80", "NO_COLOR": "1"})
    assert "clamp_driving" in p.stdout  # the event names whole


# ------------------------------------------------------------------------ --step screens
def _step_screens(pages: list, labels: list[str], width: int, height: int) -> list[str]:
    """Every screen ``--step`` shows, going forward to the end (a scripted key reader)."""
    from lcpcli.cli.stepper import step_through

    console = Console(width=width, height=height, record=True, file=io.StringIO(),
                      color_system=None, highlight=False)
    shots: list[str] = []

    def keys() -> str:
        shots.append(console.export_text(clear=True))
        return "n"

    step_through(console, pages, labels, keys=keys)
    return shots


@pytest.mark.parametrize("name", ["seed000.json", "seed004.json", "degenerate_lex.json",
                                  "box_small.json"])
@pytest.mark.parametrize("method, layout", TRACES)
@pytest.mark.parametrize("width", [60, 80])
def test_step_screens_fit_24_lines(name, method, layout, width):
    """At 80 x 24 (and 60 x 24) every screen fits, the step title comes first and the
    tableau whole on the step's first screen; nothing of a page is lost or repeated."""
    from lcpcli.cli.render.doc import to_rich
    from lcpcli.cli.render.pivot import step_labels

    prob = _load(name, None)
    try:
        result = solve(prob, method, trace=True)
    except OptionError:
        pytest.skip(f"{method} does not take a {prob.kind} problem")
    trace = result.trace or []
    if not trace:
        pytest.skip("no step to show")
    pages = step_pages(trace, layout)
    labels = step_labels(trace)
    shots = _step_screens(pages, labels, width, 24)
    assert len(shots) >= len(pages)
    k = -1
    body = []
    for shot in shots:
        lines = shot.rstrip("\n").split("\n")
        assert len(lines) <= 24, (len(lines), shot)
        assert_fits(shot, width, (name, method))
        start = max(i for i, x in enumerate(lines) if x.startswith(("step ", "sweep ")))
        assert lines[start - 1] == ""
        footer = " ".join(lines[start:])
        body += lines[:start - 1]
        if "screen" not in footer or ", screen 1 of" in footer:  # a step's first screen
            k += 1
            assert lines[0].startswith(("Step", "Sweep")), lines[0]
            if prob.n <= 3 and width == 80 and "┏" in shot:
                assert "└" in shot[shot.index("┏"):]  # the tableau whole on its first screen
        assert f"(page {k + 1} of {len(pages)})" in footer
    assert k == len(pages) - 1
    body = "\n".join(body)
    whole = render(to_rich(pages), width)
    assert sorted(x for x in body.split() if x) == sorted(x for x in whole.split() if x)


# ------------------------------------------------------------------------ one notation
def _flat(text: str) -> str:
    return " ".join(text.split())


def test_murty_names_its_pivot_element_one_way(cli, samples):
    """M'_rr is the dictionary's diagonal entry; Murty's tableau shows -M'_rr: every mention
    says which, with the same number."""
    for layout, shown in (("dictionary", "pivot element M'_rr = 2:"),
                          ("murty", "pivot element -M'_rr = -2 (M'_rr = 2; Murty's tableau "
                                    "holds -M')")):
        p = cli("solve", str(samples / "seed004.json"), "-m", "murty", "--trace", "--layout",
                layout, env={"NO_COLOR": "1", "COLUMNS": "100"})
        text = _flat(p.stdout)
        assert shown in text, text
        assert "principal pivot on the diagonal entry M'_rr = 2)" in text
        assert "pivot element -2" not in text


def test_lemke_tie_break_names_the_entry_of_its_layout(cli, samples):
    base = ["solve", str(samples / "degenerate_lex.json"), "--pivot", "1"]
    env = {"NO_COLOR": "1", "COLUMNS": "100"}
    dic = _flat(cli(*base, env=env).stdout)
    assert "divided by -c_i" in dic and "pivot element c_3 = -1" in dic and "a_i" not in dic
    mur = _flat(cli(*base, "--layout", "murty", env=env).stdout)
    assert "divided by a_i" in mur and "pivot element a_3 = 1" in mur and "c_i" not in mur


def test_sweep_table_has_no_dead_column(cli, samples):
    p = cli("solve", str(samples / "seed004.json"), "-m", "pgs", "--trace", "--json")
    assert all(s["estimate"] in (None, 0.0) for s in json.loads(p.stdout)["trace"])
    text = cli("solve", str(samples / "seed004.json"), "-m", "pgs", "--trace",
               env={"NO_COLOR": "1", "COLUMNS": "100"}).stdout
    assert "estimate" not in text and "normwise error" in text


def test_no_solution_is_shown_as_such(cli, tmp_path):
    f = tmp_path / "none.json"
    f.write_text(json.dumps({"M": [[1, -1], [-1, 1]], "q": [-1, -1]}))
    p = cli("solve", str(f), env={"NO_COLOR": "1", "COLUMNS": "80"})
    assert p.returncode == 1 and "no_solution" in p.stdout
    assert "no solution (n = 2)" in p.stdout and "solution (n = 2)" not in \
        p.stdout.replace("no solution (n = 2)", "")


def test_no_seed_numbers_in_teaching_output(cli, samples):
    env = {"NO_COLOR": "1", "COLUMNS": "100"}
    runs = [("pivot", "seed000_augmented.json", "-d", "z0,w2,z3", "--driving", "w1", "--full"),
            ("pivot", "seed000_augmented.json", "-d", "z0,w2,z3", "--driving", "z2"),
            ("solve", "degenerate_lex.json", "-m", "murty", "--trace"),
            ("solve", "seed000.json", "--trace", "--format", "latex"),
            ("enumerate", "seed004.json", "--all-cones", "--format", "markdown")]
    for cmd, name, *rest in runs:
        out = cli(cmd, str(samples / name), *rest, env=env).stdout
        text = out.replace(str(samples), "").replace("seed000_augmented.json", "") \
            .replace("seed000.json", "").replace("seed004.json", "")
        assert not re.search(r"(?i)\bseeds?\b", text), (cmd, re.findall(r".{40}seed.{20}", text))
    assert "Dai & Drumwright" in cli("pivot", "--help", env=env).stdout
    assert "seed" not in cli("pivot", "--help", env=env).stdout
