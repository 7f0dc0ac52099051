"""Rich renderables for ``lcpcli pivot`` and ``lcpcli solve --trace`` (no computing here).

Names are 1-based (``w1``, ``z4``) as in seed 000; the artificial variable is ``z{n+1}``.
"""

from __future__ import annotations

from typing import Any

from rich.console import Group
from rich.table import Table
from rich.text import Text

from lcpcli.cli.render.common import fmt


def _tableau(title: str, rows: list[str], q: Any, cols: list[str], A: Any,
             qname: str = "q") -> Table:
    table = Table(title=title, title_justify="left")
    table.add_column("", style="bold")
    table.add_column(qname, justify="right")
    for c in cols:
        table.add_column(c, justify="right")
    for i, r in enumerate(rows):
        table.add_row(r, fmt(q[i]), *[fmt(A[i][j]) for j in range(len(cols))])
    return table


def _matrix(title: str, A: Any) -> Text:
    rows = ["[" + ", ".join(fmt(x) for x in row) + "]" for row in A]
    return Text(f"{title} = [" + ", ".join(rows) + "]")


def _vec(v: Any) -> str:
    return "(" + ", ".join(fmt(x) for x in v) + ")"


def render_pivot(t: Any, M: Any, q: Any, source: str = "") -> Group:
    """Original tableau, index sets, blocks, q' and the driving column of a PivotTransform."""
    n = t.n
    wn = [f"w{i + 1}" for i in range(n)]
    zn = [f"z{j + 1}" for j in range(n + 1)]
    parts: list[Any] = []
    parts.append(_tableau("original tableau  w = q + M z", wn, q, zn, M))
    if source:
        parts.append(Text(f"artificial column z{n + 1} (z0): {source}"))
    parts.append(Text(f"dependent   w' = ({', '.join(t.names(t.dependent))})"))
    parts.append(Text(f"independent z' = ({', '.join(t.names(t.independent))})   m = {t.m}"))
    sets = Table(title="index sets (1-based, seed 000)", title_justify="left")
    for name in ("set", "value", "meaning"):
        sets.add_column(name)

    def s(xs: list[int]) -> str:
        return "{" + ", ".join(str(x + 1) for x in xs) + "}"

    sets.add_row("alpha", s(t.alpha), "positions in w of the independent w's")
    sets.add_row("alpha'", s(t.alpha_prime), "their positions in z'")
    sets.add_row("beta", s(t.beta), "positions in z of the dependent z's")
    sets.add_row("beta'", s(t.beta_prime), "their positions in w'")
    sets.add_row("alpha-bar", s(t.alpha_bar), "positions in w of the dependent w's")
    sets.add_row("alpha-bar'", s(t.alpha_bar_prime), "their positions in w'")
    sets.add_row("beta-bar", s(t.beta_bar), "positions in z of the independent z's")
    sets.add_row("beta-bar'", s(t.beta_bar_prime), "their positions in z'")
    parts.append(sets)
    parts.append(_matrix("M^{alpha beta}", t.M_ab))
    parts.append(_matrix("M^{alpha-bar beta}", t.M_abar_b))
    parts.append(Text(f"q^alpha = {_vec(t.q_a)}   q^{{alpha-bar}} = {_vec(t.q_abar)}"))
    qtab = Table(title="q' (eqs 2-3), in w' order", title_justify="left")
    qtab.add_column("w'", style="bold")
    qtab.add_column("q'", justify="right")
    qtab.add_column("from")
    beta_p = set(t.beta_prime)
    for k, v in enumerate(t.dependent):
        qtab.add_row(f"{k + 1}: {t.names((v,))[0]}", fmt(t.q_prime[k]),
                     "eq 2 (beta')" if k in beta_p else "eq 3 (alpha-bar')")
    parts.append(qtab)
    if t.driving is not None:
        name = t.names((t.driving,))[0]
        if t.driving_case == "w":
            gamma = t.alpha.index(t.driving[1]) + 1
            case = (f"driving variable {name} is a w (seed 2.2.1, eqs 5-6): gamma = {gamma}, "
                    f"M'_d^{{beta'}} = (M^{{alpha beta}})^-1 e_gamma")
        else:
            case = (f"driving variable {name} is a z (seed 2.2.2, eqs 7-8): zeta = "
                    f"{t.driving[1] + 1}, g^alpha = {_vec(t.g_alpha)}, "
                    f"g^{{alpha-bar}} = {_vec(t.g_alpha_bar)}")
        parts.append(Text(case))
        dtab = Table(title=f"M'_driving for {name}, in w' order", title_justify="left")
        dtab.add_column("w'", style="bold")
        dtab.add_column("M'_driving", justify="right")
        dtab.add_column(f"as {name} rises")
        for k, v in enumerate(t.dependent):
            c = float(t.driving_column[k])
            trend = "rises" if c > 0 else ("falls" if c < 0 else "unchanged")
            dtab.add_row(f"{k + 1}: {t.names((v,))[0]}", fmt(c),
                         f"{trend}{' by ' + fmt(abs(c)) if c else ''}")
        parts.append(dtab)
    if t.full is not None:
        parts.append(_tableau("pivoted tableau  w' = q' + M' z'", t.names(t.dependent),
                              t.q_prime, t.names(t.independent), t.full, "q'"))
    spaced: list[Any] = []
    for p in parts:
        spaced += [p, Text("")]
    return Group(*spaced[:-1])


def render_trace(trace: list[dict[str, Any]], n: int) -> Group:
    """Lemke's pivots one by one (see :func:`lcpcli.lemke_trace.lemke_trace`)."""
    out: list[Any] = []
    for step in trace:
        head = Text(f"pivot {step['pivot']}: {step['entering']} enters, "
                    f"{step['leaving']} leaves (row {step['row']})", style="bold")
        out.append(head)
        if step.get("candidates"):
            rt = Table(title="ratio test", title_justify="left")
            for c in ("row", "basic", "q'", "column", "ratio", ""):
                rt.add_column(c, justify="right" if c in ("q'", "column", "ratio") else "left")
            for c in step["candidates"]:
                mark = "<- leaves" if c["row"] == step["row"] else (
                    "tie" if c.get("tied") else "")
                rt.add_row(str(c["row"]), c["basic"], fmt(c["q"]), fmt(c["column"]),
                           fmt(c["ratio"]), mark)
            out.append(rt)
        out.append(Text(f"why: {step['reason']}"))
        out.append(Text(f"basis: ({', '.join(step['basis'])})"))
        if step.get("tableau") is not None:
            out.append(_tableau("tableau after the pivot", step["basis"], step["q_prime"],
                                step["nonbasic"], step["tableau"], "q'"))
        else:
            out.append(Text(f"q' = {_vec(step['q_prime'])}"))
            if step.get("driving_column") is not None:
                out.append(Text(f"column of the next entering variable "
                                f"{step.get('next_entering')} = "
                                f"{_vec(step['driving_column'])}"))
        out.append(Text(""))
    return Group(*out)
