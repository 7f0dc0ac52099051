"""LaTeX that prints (issue 27): each sample's exports fit a portrait page, minus signs are
math, and a formula is one math environment.

The compile test runs where ``pdflatex`` is installed: every sample through every trace
(Lemke in both layouts, Murty in both, Dantzig, PGS), ``pivot --follow --full`` and
``enumerate --all-cones``, each ``\\input{}`` into a plain ``article`` (portrait, 10 pt): no
error and no overfull box wider than 5 pt.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from lcpcli.api import solve
from lcpcli.cli.render.doc import Grid, Para, tex_text, to_latex
from lcpcli.cli.render.pivot import full_pages
from lcpcli.core.errors import OptionError
from lcpcli.io import load
from lcpcli.solvers.trace.exact import EXACT_METHODS, exact_trace, wants_exact

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
TRACES = [("lemke", "dictionary"), ("lemke", "murty"), ("murty", "dictionary"),
          ("murty", "murty"), ("dantzig", "dictionary"), ("pgs", "dictionary")]
NAMES = ["seed000.json", "seed004.json", "degenerate.json", "degenerate_lex.json",
         "box_small.json"]
#: Widest overfull box allowed, in points.
OVERFULL_MAX = 5.0


def exports(name: str) -> dict[str, str]:
    """The LaTeX of every trace of one sample (as shown by default: exact where it applies),
    and of ``pivot --follow --full`` and ``enumerate --all-cones`` for an LCP."""
    prob = load(str(SAMPLES / name))
    out = {}
    for method, layout in TRACES:
        try:
            trace = solve(prob, method, trace=True).trace or []
        except OptionError:
            continue
        data = wants_exact(prob, None) if method in EXACT_METHODS else None
        if data is not None:
            trace = exact_trace(prob, method, data)
        if trace:
            out[f"{method}-{layout}"] = to_latex(full_pages(trace, layout))
    if prob.kind == "lcp":
        from lcpcli.analysis.enumeration import enumerate_cones
        from lcpcli.analysis.pivoting import parse_tuple, parse_var
        from lcpcli.cli.pivot_cmd import _exact_items, load_augmented
        from lcpcli.cli.render.enumerate import enumeration_pages
        from lcpcli.cli.render.pivot import pivot_pages
        from lcpcli.solvers.trace.exact import exact_enumeration
        from lcpcli.solvers.trace.path import follow

        res = enumerate_cones(prob, all_cones=True, max_n=8)
        data = wants_exact(prob, None)
        if data is not None:
            res = exact_enumeration(res, data)
        out["enumerate"] = to_latex(enumeration_pages(res, prob, name, all_cones=True))
        Maug, q, source = load_augmented(str(SAMPLES / name))
        n = prob.n
        items = follow(Maug, q, parse_tuple(",".join(f"w{i + 1}" for i in range(n)), n), None,
                       parse_var("z0", n), full=True)
        items, Maug, q = _exact_items(items, Maug, q, None)
        for layout in ("dictionary", "murty"):
            out[f"pivot-{layout}"] = to_latex(pivot_pages(items, Maug, q, source, layout))
    return out


def test_minus_signs_are_math_and_formulas_are_whole():
    text = tex_text("z0 rises to t = max(-q_i / d_i) over the rows with q_i < 0")
    assert "$t = \\max (-q_{i} / d_{i})$" in text and "$q_{i} < 0$" in text
    assert tex_text("pivot element -2 (row 3)") == "pivot element $-2$ (row 3)"
    assert tex_text("basic variables: z0 = 1, w2 = 5") == \
        "basic variables: $z_{0} = 1$, $w_{2} = 5$"
    assert tex_text("(0, 1, 3/2)", numbers=True).count("$") == 2  # one formula
    assert tex_text("the 1-based rows, a tie-break") == "the 1-based rows, a tie-break"


def test_numbers_side_by_side_stay_apart():
    # TeX drops the spaces of math mode: "$-2 0$" would print -20
    assert tex_text("[1 -1; 0 -2]", numbers=True) == "[$1\\ {-1}$; $0\\ {-2}$]"
    assert tex_text("[-2 0; 3 4/3]", numbers=True) == "[$-2\\ 0$; $3\\ 4/3$]"
    assert tex_text("2 z1 + q", numbers=True) == "$2 z_{1} + q$"  # a product stays one


def test_wide_spaces_and_commas_separate_formulas():
    assert tex_text("q^alpha = (-3, -1),  q^{alpha-bar} = (6)") == \
        "$q^{\\alpha} = (-3,\\allowbreak  -1)$,\\quad $q^{\\bar{\\alpha}} = (6)$"
    assert tex_text("z' = (w1, z2)   m = 2") == \
        "$z' = (w_{1},\\allowbreak  z_{2})$\\quad $m = 2$"


@pytest.mark.parametrize("name", NAMES)
def test_exports_have_no_text_minus(name):
    for key, tex in exports(name).items():
        body = "\n".join(x for x in tex.splitlines() if not x.startswith("%"))
        assert not re.search(r"(?<![\w\\])-\$", body), (key, re.findall(r".{30}-\$.{10}", body))
        for line in body.splitlines():  # a lone minus or a whole formula, never "-$x$"
            assert not re.search(r"\$\s*-\s*\$", line), (key, line)


@pytest.mark.skipif(shutil.which("pdflatex") is None, reason="pdflatex is not installed")
@pytest.mark.parametrize("name", NAMES)
def test_exports_compile_on_a_portrait_page(name, tmp_path):
    docs = exports(name)
    assert docs
    for key, tex in docs.items():
        (tmp_path / f"{key}.tex").write_text(tex)
    for key in docs:
        main = tmp_path / f"main-{key}.tex"
        main.write_text("\\documentclass{article}\n\\begin{document}\n"
                        f"\\input{{{key}}}\n\\end{{document}}\n")
        p = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error",
                            main.name], cwd=tmp_path, capture_output=True, text=True,
                           timeout=120)
        log = (tmp_path / f"main-{key}.log").read_text(errors="replace")
        assert p.returncode == 0, (key, p.stdout[-2000:])
        widths = [float(x) for x in re.findall(r"Overfull \\hbox \(([\d.]+)pt too wide", log)]
        assert max(widths, default=0.0) <= OVERFULL_MAX, (key, widths)


def test_wide_tables_split_into_column_blocks():
    header = ["basic", *[f"x{j}" for j in range(1, 25)]]
    rows = [[f"r{i}", *[f"{-(i + 1) * j}/7" for j in range(1, 25)]] for i in range(3)]
    tex = to_latex([[Para("a wide tableau"), Grid(header, rows)]])
    assert tex.count("\\begin{tabular}") >= 2 and "column blocks" in tex
    for block in re.findall(r"\\begin\{tabular\}.*?\\end\{tabular\}", tex, re.S):
        assert "basic" in block and "r_{0}" in block  # each block repeats the row names
    for row in rows:
        for v in row[1:]:
            assert f"${v}$" in tex
