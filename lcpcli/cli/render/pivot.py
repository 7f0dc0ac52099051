"""Teaching pages for ``lcpcli solve --trace`` and ``lcpcli pivot`` (no computing here).

The library records the steps (:mod:`lcpcli.solvers.trace`, :mod:`lcpcli.analysis.pivoting`)
and lays out tableaux (:func:`lcpcli.solvers.trace.tableau.tableau_view`); this module turns
them into pages of :mod:`lcpcli.cli.render.doc` blocks, one page per step, which go to the
terminal, to Markdown or to LaTeX.  Names are 1-based (``w1``, ``z2``); the artificial
variable is ``z0``.
"""

from __future__ import annotations

from typing import Any

from lcpcli.analysis.pivoting import ARTIFICIAL
from lcpcli.cli.render.common import fmt
from lcpcli.cli.render.doc import Grid, Heading, Items, Page, Para
from lcpcli.solvers.trace.tableau import TableauView, canonical_key, tableau_view


def _vec(v: Any) -> str:
    return "(" + ", ".join(fmt(x) for x in v) + ")"


def _group(name: str) -> int:
    if name in ("q", "q'"):
        return 4
    try:
        return 1 + canonical_key(name)[0]
    except ValueError:
        return 0


def view_grid(view: TableauView, title: str = "") -> Grid:
    """A tableau view as a grid; the pivot element is the marked cell."""
    header = [view.label, *view.columns]
    rows = [[name, *[fmt(x) for x in view.values[i]]] for i, name in enumerate(view.rows)]
    marked = {(view.pivot[0], view.pivot[1] + 1)} if view.pivot is not None else set()
    groups = [0] + [_group(c) for c in view.columns]
    rules = tuple(j for j in range(len(groups) - 1) if groups[j] != groups[j + 1])
    return Grid(header, rows, ["l"] + ["r"] * len(view.columns), title, marked, rules)


def _pivot_text(pe: dict[str, Any], layout: str, what: str = "lemke") -> str:
    """The pivot element, named as the layout's tableau and ratio test name it.

    ``what``: ``lemke``, ``initial`` (the z0 column, ``d``) or ``principal`` (Murty's
    method: the diagonal entry ``M'_rr``; Murty's tableau holds ``-M'``)."""
    v, r = pe["value"], pe["row"]
    if what == "principal":
        name = (f"M'_rr = {fmt(v)}" if layout == "dictionary"
                else f"-M'_rr = {fmt(-v)} (M'_rr = {fmt(v)}; Murty's tableau holds -M')")
    elif what == "initial":
        name = f"d_{r} = {fmt(v)}" if layout == "dictionary" else f"-d_{r} = {fmt(-v)}"
    else:
        name = f"c_{r} = {fmt(v)}" if layout == "dictionary" else f"a_{r} = {fmt(-v)}"
    return f"pivot element {name}: row {r}, column {pe['column']} (marked above)"


# ------------------------------------------------------------------------------- Lemke
def ratio_grid(test: dict[str, Any], entering: str, layout: str, leaving_row: int | None,
               initial: bool = False, inline: bool = True) -> Grid:
    """Every row of a ratio test: its values and ratio, or why it cannot block.

    ``inline``: a detail of a step that shows its tableau (LaTeX writes it as a list)."""
    murty = layout == "murty"
    if initial:
        col = f"{ARTIFICIAL} column (-d_i)" if murty else "d_i"
        header = ["row", "BV" if murty else "basic", "q", col, "-q_i / d_i", ""]
    elif murty:
        header = ["row", "BV", "q", f"a_i ({entering} column)", "q_i / a_i", ""]
    else:
        header = ["row", "basic", "q'", f"c_i ({entering} column)", "q'_i / (-c_i)", ""]
    rows, marked = [], set()
    for k, x in enumerate(test["rows"]):
        c = x["column"]
        shown = -c if murty else c
        if x["ratio"] is None:
            note = x["why"] or "not eligible"
            ratio = "-"
        else:
            ratio = fmt(x["ratio"])
            note = "tie" if x.get("tied") else ""
            if x["why"]:
                note = (note + "; " if note else "") + x["why"]
        if leaving_row is not None and x["row"] == leaving_row:
            note = ("leaves" + ("; " + note if note else ""))
            marked.add((k, 3))
        rows.append([str(x["row"]), x["basic"], fmt(x["q"]), fmt(shown), ratio, note])
    return Grid(header, rows, ["r", "l", "r", "r", "r", "l"], "", marked, inline=inline)


def lex_blocks(lex: dict[str, Any], layout: str) -> list[Any]:
    """The rows of B^-1 compared in a lexicographic tie-break, and each comparison."""
    n = len(lex["rows"][0]["binv_row"])
    murty = layout == "murty"
    entry = "a_i" if murty else "-c_i"  # the same number: Murty's a_i is the dictionary's -c_i
    header = ["row", "BV" if murty else "basic", entry, *[f"w{k + 1}" for k in range(n)]]
    rows = [[str(r["row"]), r["basic"], fmt(r["pivot_entry"]), *[fmt(v) for v in r["key"]]]
            for r in lex["rows"]]
    title = (f"rows of B^-1 (the w columns of Murty's tableau) divided by {entry} (the "
             f"entering column's entry{'' if murty else ' with its sign flipped'}), compared "
             f"column by column; the smallest stays")
    items = []
    for c in lex["compared"]:
        keys = ", ".join(f"row {r}: {fmt(k)}" for r, k in zip(c["rows"], c["keys"], strict=True))
        if len(c["kept"]) == len(c["rows"]):
            what = "still tied"
        else:
            what = "kept " + ", ".join(f"row {r}" for r in c["kept"])
        items.append(f"column {c['variable']}: {keys} -> {what}")
    return [Para(f"Tie-break: {title}."),
            Grid(header, rows, ["r", "l", "r"] + ["r"] * n, inline=True), Items(items)]


def _decision(step: dict[str, Any], layout: str, has_tableau: bool = True) -> Page:
    """What happens from a state: who enters and why, the ratio test, who leaves and why."""
    out: Page = []
    entering = step["entering"]
    out.append(Para(f"Next: {step['entering_reason']}."))
    test = step.get("ratio_test")
    if test:
        formula = test.get("formula_murty") if layout == "murty" else test.get("formula")
        out.append(Para(f"Ratio test: {formula}."))
        out.append(ratio_grid(test, entering, layout, step.get("row"),
                              initial=step.get("rule") == "initial", inline=has_tableau))
    if step.get("lexicographic"):
        out.extend(lex_blocks(step["lexicographic"], layout))
    if step.get("leaving") is None:
        out.append(Para(step["reason"][:1].upper() + step["reason"][1:] + "."))
        return out
    what = "initial" if step.get("rule") == "initial" else "lemke"
    out.append(Para(f"{step['leaving']} leaves (row {step['row']}): {step['reason']}; "
                    f"{_pivot_text(step['pivot_element'], layout, what)}."))
    return out


def _state_heading(step: dict[str, Any], k: int) -> str:
    if k == 0:
        basis = "basis " + ", ".join(step["basis"]) if step["basis"] else EMPTY_BASIS
        return f"Step 0: initial tableau ({basis}; z = 0, {ARTIFICIAL} = 0)"
    return (f"Step {k}: after pivot {k}: {step['entering']} entered, {step['leaving']} left "
            f"(row {step['row']})")


#: The words for the basis of an n = 0 problem.
EMPTY_BASIS = "empty basis"


def _basis_values(step: dict[str, Any]) -> str:
    """``w1 = 3, z2 = 1``: the basic variables and their values (n = 0: ``empty basis``)."""
    return ", ".join(f"{b} = {fmt(v)}" for b, v in zip(step["basis"], step["q_prime"],
                                                       strict=True)) or EMPTY_BASIS


def lemke_pages(trace: list[dict[str, Any]], layout: str = "dictionary") -> list[Page]:
    """One page per state of a Lemke trace: the tableau with the next pivot element marked,
    then the next pivot (entering variable and why, ratio test, tie-break, leaving variable)."""
    pages: list[Page] = []
    states = [s for s in trace if s.get("rule") != "ray"]
    for k, st in enumerate(states):
        nxt = trace[k + 1] if k + 1 < len(trace) else None
        page: Page = [Heading(_state_heading(st, k))]
        view = tableau_view(st, layout, nxt.get("pivot_element") if nxt else None)
        if view is not None:
            page.append(Para(f"`{view.equation}`  ({layout} layout)"))
            page.append(view_grid(view))
        else:
            page.append(Para(f"basic variables: {_basis_values(st)}"))
        if nxt is not None:
            page.extend(_decision(nxt, layout, has_tableau=view is not None))
        elif k == 0:
            page.append(Para(st["reason"] + "."))
        elif st.get("leaving") == ARTIFICIAL:
            page.append(Para(f"{ARTIFICIAL} has left the basis: the basic variables solve the "
                             f"LCP ({_basis_values(st)}; all other variables are 0)."))
        else:
            page.append(Para("The pivot limit stops the method here."))
        pages.append(page)
    return pages


# ------------------------------------------------------------------------------- principal
def principal_pages(trace: list[dict[str, Any]], layout: str = "dictionary") -> list[Page]:
    """Murty's least-index method: one page per complementary basis, then a summary table."""
    pages: list[Page] = []
    states = [s for s in trace if s.get("rule") not in ("bad_pivot",)]
    for k, st in enumerate(states):
        nxt = trace[k + 1] if k + 1 < len(trace) else None
        head = ("Step 0: " + st["reason"] if k == 0 else
                f"Step {k}: after principal pivot {k}: {st['entering']} entered, "
                f"{st['leaving']} left (row {st['row']})")
        page: Page = [Heading(head), Para(_index_sets(st))]
        view = tableau_view(st, layout, nxt.get("pivot_element") if nxt else None)
        if view is not None:
            page.append(Para(f"`{view.equation}`  ({layout} layout)"))
            page.append(view_grid(view))
        else:
            page.append(Para(f"basic variables: {_basis_values(st)}"))
        if nxt is not None:
            page.append(Para(f"Next: {nxt['reason']}."))
            if nxt.get("pivot_element") and nxt.get("rule") != "bad_pivot":
                page.append(Para(_pivot_text(nxt["pivot_element"], layout, "principal") + "."))
        elif k == len(states) - 1:  # how the method ended: recorded by the replica
            if st.get("end") == "solved":
                page.append(Para(f"No basic variable is negative: this basis solves the LCP "
                                 f"({_basis_values(st)}; all other variables are 0)."))
            else:
                page.append(Para("The pivot limit stops the method here."))
        pages.append(page)
    glance: Page = [Heading("Principal pivots at a glance"), principal_table(trace)]
    glance += [Para(f"Not made: {st['reason']}.") for st in trace
               if st.get("rule") == "bad_pivot"]
    pages.append(glance)
    return pages


def _index_sets(st: dict[str, Any]) -> str:
    def s(xs: list[int]) -> str:
        return "{" + ", ".join(str(x) for x in xs) + "}"

    return (f"z basic: alpha = beta = {s(st['alpha'])}; w basic: alpha-bar = "
            f"{s(st['alpha_bar'])} (Dai & Drumwright's index sets; q' = -(M^{{alpha alpha}})^-1 "
            f"q^alpha on alpha)")


def principal_table(trace: list[dict[str, Any]]) -> Grid:
    """One line per principal pivot made: row, exchanged pair, pivot element, index set, q'
    (a pivot refused as not positive, ``bad_pivot``, is no line: it was not made)."""
    n = len(trace[0]["basis"]) if trace else 0
    header = ["pivot", "row", "enters", "leaves", "pivot element M'_rr", "alpha (z basic)",
              "q'" if n <= 8 else "min q'"]
    rows = []
    for st in trace:
        if st.get("rule") == "bad_pivot":
            continue
        pe = st.get("pivot_element")
        qcol = _vec(st["q_prime"]) if n <= 8 else fmt(min(st["q_prime"], default=0.0))
        rows.append([str(st["pivot"]), "-" if st.get("row") is None else str(st["row"]),
                     st.get("entering") or "-", st.get("leaving") or "-",
                     "-" if pe is None else fmt(pe["value"]),
                     "{" + ", ".join(str(x) for x in st["alpha"]) + "}", qcol])
    return Grid(header, rows, ["r", "r", "l", "l", "r", "l", "l"])


# ------------------------------------------------------------------------------- Dantzig
def dantzig_table(trace: list[dict[str, Any]]) -> Grid:
    """One line per event of Cottle-Dantzig's method."""
    header = ["step", "pivot", "index", "event", "enters", "leaves", "t", "clamped C", "z"]
    rows = []
    for k, st in enumerate(trace):
        z = "-" if st.get("z") is None else _vec(st["z"])
        rows.append([str(k), str(st["pivot"]), "-" if st["index"] is None else str(st["index"]),
                     st["event"], st.get("entering") or "-", st.get("leaving") or "-",
                     "-" if st.get("step") is None else fmt(st["step"]),
                     "{" + ", ".join(str(x) for x in st["sets"]["clamped"]) + "}", z])
    return Grid(header, rows, ["r", "r", "r", "l", "l", "l", "r", "l", "l"])


def dantzig_pages(trace: list[dict[str, Any]]) -> list[Page]:
    """One page per event (index sets, the exchanged pair, the values), then the table."""
    pages: list[Page] = []
    for k, st in enumerate(trace):
        sets = st["sets"]

        def s(xs: list[int]) -> str:
            return "{" + ", ".join(str(x) for x in xs) + "}"

        page: Page = [Heading(f"Step {k} (pivots so far: {st['pivot']}): {st['event']}"),
                      Para(st["reason"] + "."),
                      Para(f"clamped C (z basic, w = 0) = {s(sets['clamped'])}; at lower bound "
                           f"= {s(sets['at_lower'])}; at upper bound = {s(sets['at_upper'])}; "
                           f"not yet processed = {s(sets['unprocessed'])}")]
        if st.get("entering"):
            page.append(Para(f"{st['entering']} enters the basis, {st['leaving']} leaves it."))
        if st.get("z") is not None:
            n = len(st["z"])
            page.append(Grid(["", *[str(i + 1) for i in range(n)]],
                             [["z", *[fmt(v) for v in st["z"]]],
                              ["w", *["-" if v is None else fmt(v) for v in st["w"]]]]))
        pages.append(page)
    pages.append([Heading("Events at a glance"), dantzig_table(trace)])
    return pages


# ------------------------------------------------------------------------------- sweeps
def sweep_table(trace: list[dict[str, Any]]) -> Grid:
    """The recorded sweeps of PGS/PSOR: z, the largest change, the exact normwise error and
    whether the method made its exact check.  (The kernels' in-sweep estimate, ``estimate``
    in the JSON, is not shown: for PGS each row's update zeroes that row's own residual, so
    it is 0 on every sweep and says nothing; the normwise error is the measured quantity.)"""
    show_z = bool(trace) and trace[0].get("z") is not None
    header = ["sweep", *(["z"] if show_z else []), "max |change|", "normwise error",
              "checked"]
    rows = []
    last = None
    for st in trace:
        if last is not None and st["sweep"] > last + 1:
            rows.append(["...", *([""] if show_z else []), "", "", ""])
        last = st["sweep"]
        rows.append([str(st["sweep"]), *([_vec(st["z"])] if show_z else []),
                     "-" if st["change"] is None else f"{st['change']:.3e}",
                     f"{st['error']:.3e}", "yes" if st["checked"] else ""])
    omega = trace[0].get("omega", 1.0) if trace else 1.0
    title = (f"projected {'Gauss-Seidel' if omega == 1.0 else f'SOR (omega = {omega:g})'}: "
             f"the first sweeps and the last")
    return Grid(header, rows, ["r", *(["l"] if show_z else []), "r", "r", "l"], title)


def sweep_pages(trace: list[dict[str, Any]]) -> list[Page]:
    """One page per recorded sweep (``--pivot K``: sweep K) and the whole table last."""
    pages: list[Page] = []
    for st in trace:
        pages.append([Heading(f"Sweep {st['sweep']}"), sweep_table([st])])
    return pages


# ------------------------------------------------------------------------------- dispatch
def trace_kind(trace: list[dict[str, Any]]) -> str:
    """``lemke``, ``principal``, ``dantzig`` or ``sweep`` (the ``kind`` of the entries)."""
    return str(trace[0].get("kind", "lemke")) if trace else "lemke"


def trace_pages(trace: list[dict[str, Any]], layout: str = "dictionary") -> list[Page]:
    """The pages of any trace, one per step (``--pivot K`` shows page K, ``--step`` pages)."""
    kind = trace_kind(trace)
    if kind == "principal":
        return principal_pages(trace, layout)
    if kind == "dantzig":
        return dantzig_pages(trace)
    if kind == "sweep":
        return sweep_pages(trace)
    return lemke_pages(trace, layout)


def step_pages(trace: list[dict[str, Any]], layout: str = "dictionary") -> list[Page]:
    """Pages addressed by ``--pivot K`` / ``--step`` (the summary page of a kind left out)."""
    pages = trace_pages(trace, layout)
    if trace_kind(trace) in ("principal", "dantzig"):
        pages = pages[:-1]
    return pages


def full_pages(trace: list[dict[str, Any]], layout: str = "dictionary") -> list[Page]:
    """The whole trace for the terminal and the exports."""
    if trace_kind(trace) == "sweep":
        return [[sweep_table(trace)]]
    return trace_pages(trace, layout)


def _state_count(trace: list[dict[str, Any]]) -> int:
    """States of a pivoting trace (the last decision that made no pivot is not a state)."""
    return sum(1 for s in trace if s.get("rule") not in ("ray", "bad_pivot"))


def step_numbers(trace: list[dict[str, Any]]) -> list[int]:
    """The numbers ``--pivot K`` accepts, one per page of :func:`step_pages`."""
    kind = trace_kind(trace)
    if kind == "sweep":
        return [int(s["sweep"]) for s in trace]
    if kind == "dantzig":
        return list(range(len(trace)))
    return list(range(_state_count(trace)))


def step_entries(trace: list[dict[str, Any]], k: int) -> list[dict[str, Any]]:
    """``--pivot K`` with ``--json``: the trace entries of page ``K`` of :func:`step_pages`
    (the last state's page with the decision that made no pivot after it, a ray); exit 2 with
    the valid numbers otherwise, as for the printed trace."""
    from lcpcli.cli.stepper import pick

    numbers = step_numbers(trace)
    entries = pick(trace, k, numbers, "this trace")
    if trace_kind(trace) not in ("sweep", "dantzig") and k == numbers[-1]:
        entries += trace[k + 1:]
    return entries


def step_labels(trace: list[dict[str, Any]]) -> list[str]:
    """Names of the pages of :func:`step_pages` on the ``--step`` screen."""
    word = "sweep" if trace_kind(trace) == "sweep" else "step"
    return [f"{word} {k}" for k in step_numbers(trace)]


# ------------------------------------------------------------------------------- pivot
def _index_table(t: Any) -> Grid:
    def s(xs: list[int]) -> str:
        return "{" + ", ".join(str(x + 1) for x in xs) + "}"

    rows = [["alpha", s(t.alpha), "positions in w of the independent w's"],
            ["alpha'", s(t.alpha_prime), "their positions in z'"],
            ["beta", s(t.beta), f"positions in z of the dependent z's ({ARTIFICIAL} is "
                                f"position {t.n + 1})"],
            ["beta'", s(t.beta_prime), "their positions in w'"],
            ["alpha-bar", s(t.alpha_bar), "positions in w of the dependent w's"],
            ["alpha-bar'", s(t.alpha_bar_prime), "their positions in w'"],
            ["beta-bar", s(t.beta_bar), "positions in z of the independent z's"],
            ["beta-bar'", s(t.beta_bar_prime), "their positions in z'"]]
    return Grid(["set", "value", "meaning"], rows, ["l", "l", "l"],
                "index sets (1-based, as in Dai & Drumwright)")


def _matrix_text(title: str, A: Any) -> str:
    rows = ["[" + ", ".join(fmt(x) for x in row) + "]" for row in A]
    return f"{title} = [" + ", ".join(rows) + "]"


def pivot_pages(items: list[tuple[Any, dict[str, Any] | None]], M: Any, q: Any,
                source: str = "", layout: str = "dictionary") -> list[Page]:
    """One page per basis of ``lcpcli pivot``: the transform (index sets, blocks, q', the
    driving column, the pivoted tableau) and, with a driving variable, Lemke's ratio test."""
    n = len(q)
    pages: list[Page] = []
    start = {"basis": [f"w{i + 1}" for i in range(n)],
             "nonbasic": [*(f"z{j + 1}" for j in range(n)), ARTIFICIAL],
             "q_prime": list(q), "tableau": [list(row) for row in M]}
    for k, (t, step) in enumerate(items):
        page: Page = []
        if len(items) > 1:
            page.append(Heading(f"Basis {k + 1} of {len(items)}: w' = "
                                f"({', '.join(t.names(t.dependent))})"))
        if k == 0:
            view = tableau_view(start, layout)
            page.append(Para(f"original tableau `{view.equation}`  ({layout} layout)"))
            page.append(view_grid(view))
            if source:
                page.append(Para(f"artificial column {ARTIFICIAL} (position {n + 1} of z, "
                                 f"alias z{n + 1}): {source}"))
        page.append(Para(f"dependent   w' = ({', '.join(t.names(t.dependent))})"))
        page.append(Para(f"independent z' = ({', '.join(t.names(t.independent))})   m = {t.m}"))
        page.append(_index_table(t))
        page.append(Para(_matrix_text("M^{alpha beta}", t.M_ab)))
        page.append(Para(_matrix_text("M^{alpha-bar beta}", t.M_abar_b)))
        page.append(Para(f"q^alpha = {_vec(t.q_a)},  q^{{alpha-bar}} = {_vec(t.q_abar)}"))
        beta_p = set(t.beta_prime)
        page.append(Grid(["w'", "q'", "from"],
                         [[f"{i + 1}: {t.names((v,))[0]}", fmt(t.q_prime[i]),
                           "eq 2 (beta')" if i in beta_p else "eq 3 (alpha-bar')"]
                          for i, v in enumerate(t.dependent)],
                         ["l", "r", "l"], "q' (Dai & Drumwright, eqs 2 and 3), in w' order"))
        if t.driving is not None:
            page.extend(_driving_blocks(t, step, layout))
        elif t.solves:
            page.append(Para(f"{ARTIFICIAL} is independent (0) and q' >= 0: at z' = 0 this "
                             f"complementary basis solves the LCP (Lemke's answer)."))
        if t.full is not None:
            state = {"basis": t.names(t.dependent), "nonbasic": t.names(t.independent),
                     "q_prime": t.q_prime.tolist(), "tableau": t.full.tolist()}
            pe = step.get("pivot_element") if step else None
            view = tableau_view(state, layout, pe)
            marked = "; the pivot element of the next Lemke step is marked" if pe else ""
            page.append(Para(f"pivoted tableau `{view.equation}`  ({layout} layout{marked})"))
            page.append(view_grid(view))
        pages.append(page)
    return pages


def _driving_blocks(t: Any, step: dict[str, Any] | None, layout: str) -> Page:
    name = t.names((t.driving,))[0]
    out: Page = []
    if t.driving_case == "w":
        gamma = t.alpha.index(t.driving[1]) + 1
        out.append(Para(f"driving variable {name} is a w (Dai & Drumwright, section 2.2.1, eqs 5 "
                        f"and 6): gamma = {gamma}, M'_d^{{beta'}} = (M^{{alpha beta}})^-1 e_gamma"))
    else:
        out.append(Para(f"driving variable {name} is a z (Dai & Drumwright, section 2.2.2, eqs 7 "
                        f"and 8): zeta = "
                        f"{t.driving[1] + 1}, g^alpha = {_vec(t.g_alpha)}, "
                        f"g^{{alpha-bar}} = {_vec(t.g_alpha_bar)}"))
    rows = []
    for k, v in enumerate(t.dependent):
        c = t.driving_column[k]
        trend = "rises" if c > 0 else ("falls" if c < 0 else "unchanged")
        rows.append([f"{k + 1}: {t.names((v,))[0]}", fmt(c),
                     f"{trend}{' by ' + fmt(abs(c)) if c else ''}"])
    out.append(Grid(["w'", "M'_driving", f"as {name} rises"], rows, ["l", "r", "l"],
                    f"M'_driving for {name}, in w' order"))
    if step is None:
        return out
    if step.get("formula"):
        formula = step.get("formula_murty") if layout == "murty" else step["formula"]
        out.append(Para(f"Ratio test (Lemke's rule): {formula}."))
        out.append(ratio_grid(step, name, layout, step.get("row"),
                              initial=step.get("rule") == "initial"))
    if step.get("lexicographic"):
        out.extend(lex_blocks(step["lexicographic"], layout))
    if step.get("blocking"):
        out.append(Para(f"blocking variable: {step['blocking']} (row {step['row']} of w'). "
                        f"{step['reason']}."))
    else:
        out.append(Para(f"no blocking variable: {step['reason']}."))
    return out
