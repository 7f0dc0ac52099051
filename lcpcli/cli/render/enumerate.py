"""Rendering of an enumeration: the complementary-cone table, the solutions, the verdict, and
for n = 2 the classic picture of the four cones and the point q (terminal or matplotlib).

Variable names are 1-based (``w1``, ``z2``); the complementary matrix ``A_r`` has column
``I_j`` for ``w_j`` basic and ``-M_j`` for ``z_j`` basic (Murty, "Linear Complementarity, Linear and
Nonlinear Programming", chapter 1).
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Group
from rich.table import Table
from rich.text import Text

from lcpcli.analysis.enumeration import (
    CONTINUUM,
    FINITE,
    FOUND,
    INCOMPLETE,
    NONE,
    UNCERTIFIED,
    UNIQUE,
    UNKNOWN,
    Enumeration,
    complementary_matrix,
    cone_interiors_2d,
    degenerate_2d,
    direction_2d,
    generators_2d,
    length_2d,
)
from lcpcli.cli.render.common import fit, fmt
from lcpcli.cli.render.doc import Grid, Heading, Page, Para

#: The verdict of a search that found no cone but no proof either (a text key only).
UNPROVEN = "none, unproven"
#: Show the complementary matrix in the table up to this n.
MATRIX_MAX_N = 4
#: Show the basic values y in the table up to this n.
Y_MAX_N = 8
#: Rows of the cone and solution tables before truncation.
MAX_ROWS = 64

VERDICT_TEXT = {
    UNIQUE: ("unique solution", "bold green"),
    FINITE: ("finitely many solutions", "bold green"),
    CONTINUUM: ("a continuum of solutions (a singular cone holds more than one point)",
                "bold green"),
    NONE: ("no solution: no complementary cone contains q, and a Farkas vector y (in the JSON) "
           "proves that no z >= 0 has Mz + q >= 0", "bold yellow"),
    UNPROVEN: ("undecided: no complementary cone contains q in floating point, but no Farkas "
               "vector proves infeasibility (z >= 0 with Mz + q >= 0 may exist), so nothing "
               "is proven", "bold red"),
    UNCERTIFIED: ("undecided: cones contain q, but no point of them passes the certificate "
                  "in the problem's units (extreme data)", "bold red"),
    FOUND: ("a solution (stopped at the first one)", "bold green"),
    INCOMPLETE: ("solutions found; some singular cones containing q were not resolved "
                 "(LP limit), so there may be more", "bold green"),
    UNKNOWN: ("undecided: no solution found, but some singular cones containing q were not "
              "resolved (LP limit)", "bold red"),
}


def _verdict(res: Enumeration) -> str:
    """The key of :data:`VERDICT_TEXT` for ``res``: ``none`` only with its proof."""
    return UNPROVEN if res.verdict == NONE and res.proof is None else res.verdict


def _complementary(M: np.ndarray, cone: Any) -> np.ndarray:
    """``A_r`` of ``cone``, in fractions when the enumeration was made exact (``--exact``)."""
    if isinstance(cone.det, Fraction):
        from lcpcli.solvers.trace.exact import (
            FLAG_MAX_ABS,
            FLAG_MAX_DENOMINATOR,
            complementary,
            rational_array,
        )

        exact = rational_array(M, FLAG_MAX_DENOMINATOR, FLAG_MAX_ABS)
        if exact is not None:
            return complementary(exact, cone.code)
    return complementary_matrix(M, cone.code)


def _matrix_text(A: np.ndarray) -> str:
    cells = [[fmt(x) for x in row] for row in A]
    if not cells:  # n = 0: the empty matrix
        return "[]"
    width = max(len(c) for row in cells for c in row)
    return "\n".join("[" + " ".join(c.rjust(width) for c in row) + "]" for row in cells)


def _vec(v: np.ndarray | None) -> str:
    if v is None:
        return "-"
    return "(" + ", ".join(fmt(x) for x in v) + ")"


def cone_table(res: Enumeration, M: np.ndarray, all_cones: bool) -> Table:
    """One row per cone: basic variables, A_r (small n), det, rank, q in cone, y."""
    n = res.n
    what = "all" if all_cones else "feasible"
    table = Table(title=f"complementary cones ({what}: {len(res.cones)} of 2^{n} = "
                        f"{res.total:,})", title_justify="left", show_lines=n <= MATRIX_MAX_N)
    table.add_column("r", justify="right")
    small = n <= MATRIX_MAX_N
    if small:  # the y column names the basic variables
        table.add_column("A_r (I_j or -M_j)", no_wrap=True)
    else:
        table.add_column("basic y")
    table.add_column("det A_r, rank", justify="right", no_wrap=True)
    table.add_column("q in cone", no_wrap=True)
    if n <= Y_MAX_N:
        table.add_column("y (A_r y = q)", no_wrap=small)
    shown = res.cones[:MAX_ROWS]
    for c in shown:
        row: list[Any] = [str(c.r)]
        row.append(_matrix_text(_complementary(M, c)) if small
                   else " ".join(c.basis_names()))
        det = fmt(c.det) if c.det is not None else "-"
        rank = "-" if c.rank is None else str(c.rank)
        row.append(Text(f"{det}, {rank} singular", style="yellow") if c.singular
                   else f"{det}, {rank}")
        if c.feasible:
            row.append(Text("yes (continuum)" if c.continuum else "yes", style="green"))
        else:
            row.append(Text("no", style="dim"))
        if n <= Y_MAX_N:
            if c.y is None or (c.singular and not c.feasible):
                row.append("-")
            elif small:  # a column beside A_r
                row.append("\n".join(f"{name} = {fmt(v)}"
                                      for name, v in zip(c.basis_names(), c.y, strict=True)))
            else:
                row.append(_vec(c.y))
        table.add_row(*row)
    if len(res.cones) > len(shown):
        table.caption = f"{len(res.cones) - len(shown):,} more rows not shown: use --json"
    return table


def solutions_table(res: Enumeration) -> Table:
    """The distinct solutions (z, w) with the number of cones holding each."""
    table = Table(title=f"solutions ({len(res.solutions)} distinct)", title_justify="left")
    table.add_column("#", justify="right")
    table.add_column("z")
    table.add_column("w = Mz + q")
    table.add_column("cones", justify="right")
    table.add_column("error", justify="right")
    for k, s in enumerate(res.solutions[:MAX_ROWS], 1):
        mark = " (+ a continuum)" if s.continuum else ""
        table.add_row(str(k), _vec(s.z) + mark, _vec(s.w), str(len(s.cones)),
                      f"{s.certificate.error:.1e}")
    if len(res.solutions) > MAX_ROWS:
        table.caption = f"{len(res.solutions) - MAX_ROWS} more: use --json"
    return table


def render_enumeration(res: Enumeration, problem: Any, file: str | None, *,
                       all_cones: bool, covers: bool | None = None,
                       drawing: Text | None = None) -> Group:
    """The whole teaching display."""
    M = np.asarray(problem.dense_M(), dtype=float)
    head = Table.grid(padding=(0, 2))
    head.add_column(style="bold")
    head.add_column()
    head.add_row("problem", f"{file or ''}{' : ' + problem.name if problem.name else ''}")
    head.add_row("size", f"{problem.summary()}, 2^{res.n} = {res.total:,} complementary cones")
    head.add_row("cones", cone_counts_text(res, all_cones))
    head.add_row("time", f"{res.seconds * 1e3:.3f} ms")
    parts: list[Any] = [fit(head), Text("")]
    if res.cones or all_cones:
        parts.append(fit(cone_table(res, M, all_cones)))
    if res.solutions:
        parts.append(fit(solutions_table(res)))
    text, style = VERDICT_TEXT[_verdict(res)]
    parts.append(Text.assemble(("verdict: ", "bold"), (text, style)))
    if covers is not None:
        if covers:
            parts.append(Text("K(M) = R^2: the four complementary cones cover the plane, so "
                              "LCP(q, M) has a solution for every q."))
        else:
            parts.append(Text("K(M) != R^2: the complementary cones leave gaps, so LCP(q, M) "
                              "has no solution for q in the blank region."))
    if drawing is not None:
        parts += [Text(""), drawing]
    return Group(*parts)


# ---------------------------------------------------------------------------- exports
def _matrix_inline(A: np.ndarray) -> str:
    return "[" + "; ".join(" ".join(fmt(x) for x in row) for row in A) + "]"


def cone_counts_text(res: Enumeration, all_cones: bool) -> str:
    """The counts in words.  ``counts.singular`` counts the cones that were factorised (a cone
    excluded by the sign tests never is); with every cone listed (``all_cones``) the singular
    ones among all are counted from the list as well, so the line agrees with the table."""
    c = res.counts
    factorised = res.examined - c["pruned"]
    words = f"{c['feasible']:,} contain q"
    if c["pruned"]:
        words += f", {c['pruned']:,} excluded by sign tests"
    words += (f", {c['singular']:,} singular of the {factorised:,} factorised "
              f"({c['singular_with_q']:,} of them contain q)")
    if all_cones and len(res.cones) == res.total:
        words += f", {sum(1 for x in res.cones if x.singular):,} singular of all {res.total:,}"
    if c.get("singular_unresolved"):
        words += f", {c['singular_unresolved']:,} singular ones not resolved"
    return words


def enumeration_pages(res: Enumeration, problem: Any, file: str | None, *, all_cones: bool,
                      covers: bool | None = None) -> list[Page]:
    """The enumeration as one page of blocks for ``--format markdown|latex``."""
    M = np.asarray(problem.dense_M(), dtype=float)
    n = res.n
    name = Path(file).name if file and file != "-" else (problem.name or "the problem")
    page: Page = [Heading(f"Complementary cones of {name}"),
                  Para(f"{problem.summary()}, 2^{n} = {res.total:,} complementary cones; "
                       f"{cone_counts_text(res, all_cones)}.")]
    if res.cones or all_cones:
        small = n <= MATRIX_MAX_N
        header = ["r", "A_r (I_j or -M_j)" if small else "basic y", "det A_r", "rank",
                  "q in cone", *(["y (A_r y = q)"] if n <= Y_MAX_N else [])]
        rows = []
        for cone in res.cones[:MAX_ROWS]:
            row = [str(cone.r),
                   _matrix_inline(_complementary(M, cone)) if small
                   else " ".join(cone.basis_names()),
                   fmt(cone.det) if cone.det is not None else "-",
                   "-" if cone.rank is None else str(cone.rank) + (" (singular)"
                                                                  if cone.singular else ""),
                   ("yes (continuum)" if cone.continuum else "yes") if cone.feasible else "no"]
            if n <= Y_MAX_N:
                row.append("-" if cone.y is None or (cone.singular and not cone.feasible) else
                           ", ".join(f"{name} = {fmt(v)}"
                                     for name, v in zip(cone.basis_names(), cone.y,
                                                        strict=True)))
            rows.append(row)
        what = "all" if all_cones else "those containing q"
        page.append(Grid(header, rows, ["r", "l", "r", "l", "l", "l"][:len(header)],
                         f"complementary cones ({what})"))
    if res.solutions:
        page.append(Grid(["#", "z", "w = M z + q", "cones", "error"],
                         [[str(k), _vec(sol.z) + (" (+ a continuum)" if sol.continuum else ""),
                           _vec(sol.w), str(len(sol.cones)), f"{sol.certificate.error:.1e}"]
                          for k, sol in enumerate(res.solutions[:MAX_ROWS], 1)],
                         ["r", "l", "l", "r", "r"], "solutions"))
    page.append(Para(f"Verdict: {VERDICT_TEXT[_verdict(res)][0]}."))
    if covers is not None:
        page.append(Para("K(M) = R^2: the four cones cover the plane, so LCP(q, M) has a "
                         "solution for every q." if covers else
                         "K(M) != R^2: the cones leave gaps; LCP(q, M) has no solution for q "
                         "in them."))
    return [page]


# ---------------------------------------------------------------------------- n = 2 drawings
def _cone_number(code: int) -> int:
    """The number r of the 2 x 2 cone with code bits ``code`` (bit j = z_{j+1} basic), as the
    rigid-body collision article numbers them in its enumeration."""
    return 1 + sum(1 << (1 - b) for b in range(2) if (code >> b) & 1)


class _Canvas:
    """A character grid with styles and a record of cells that must not be overwritten."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.chars = [[" "] * width for _ in range(height)]
        self.styles = [[""] * width for _ in range(height)]
        self.fixed: set[tuple[int, int]] = set()

    def put(self, r: int, c: int, ch: str, style: str = "", fix: bool = False) -> None:
        if 0 <= r < self.height and 0 <= c < self.width and (r, c) not in self.fixed:
            self.chars[r][c] = ch
            self.styles[r][c] = style
            if fix:
                self.fixed.add((r, c))

    def place_label(self, r: int, c: int, text: str, style: str, right: bool) -> bool:
        """Write ``text`` at (r, c) (ending there if ``right``) with a blank cell each side,
        at the nearest place where it overlaps no fixed cell; False if none fits."""
        for dr, dc in ((0, 0), (-1, 0), (1, 0), (0, 2), (0, -2), (1, 2), (-1, 2), (1, -2),
                       (-1, -2), (-2, 0), (2, 0)):
            rr = r + dr
            c0 = (c - len(text) + 1 if right else c) + dc
            c0 = min(max(c0, 1), self.width - len(text) - 1)
            span = [(rr, cc) for cc in range(c0 - 1, c0 + len(text) + 1)]
            if not 0 <= rr < self.height or any(x in self.fixed for x in span):
                continue
            for cc in range(c0 - 1, c0 + len(text) + 1):
                self.put(rr, cc, " ", fix=True)
            for k, ch in enumerate(text):
                self.fixed.discard((rr, c0 + k))
                self.put(rr, c0 + k, ch, style, fix=True)
            return True
        return False

    def text(self) -> Text:
        out = Text()
        for row, srow in zip(self.chars, self.styles, strict=True):
            for ch, st in zip(row, srow, strict=True):
                out.append(ch, style=st or None)
            out.append("\n")
        return out


#: Half-width of the square that the character drawing shows (generators have unit length).
TEXT_EXTENT = 1.15


def text_grid(width: int, height: int) -> np.ndarray:
    """The points (2, height * width) of the character cells, row by row from the top left."""
    X, Y = np.meshgrid(np.linspace(-TEXT_EXTENT, TEXT_EXTENT, width),
                       np.linspace(TEXT_EXTENT, -TEXT_EXTENT, height))
    return np.vstack([X.ravel(), Y.ravel()])




def draw_cones_text(M: Any, q: Any, width: int = 49, height: int = 21,
                    path: list[dict[str, Any]] | None = None) -> Text:
    """Character drawing of the four complementary cones and q (directions only).

    Each region shows the number r of the one cone holding it (``▒``: 2+ cones, blank: none);
    the generators ``I_j`` (labelled ``w_j``) and ``-M_j`` (``z_j``) are rays of unit length;
    labels never overlap a ray, another label or a region digit (one blank cell each side).
    ``path`` (from :func:`lcpcli.solvers.trace.lemke.path_points`): Lemke's path
    ``q + z0 d``, drawn at its directions as ``*``.  An output stream without these characters
    gets ASCII stand-ins (:data:`lcpcli.cli.common.ASCII_STAND_INS`).
    """
    M = np.asarray(M, dtype=float)
    q = np.asarray(q, dtype=float)
    R = TEXT_EXTENT
    member = cone_interiors_2d(M, text_grid(width, height))  # decided by the analysis
    cover = member.sum(axis=0).reshape(height, width)
    which = np.argmax(member, axis=0).reshape(height, width)
    canvas = _Canvas(width, height)
    for i in range(height):
        for j in range(width):
            if cover[i, j] >= 2:
                canvas.put(i, j, "▒", "yellow")
            elif cover[i, j] == 1 and j % 2 == 0:
                canvas.put(i, j, str(_cone_number(int(which[i, j]))), "dim")

    def cell(x: float, y: float) -> tuple[int, int]:
        return (int(round((R - y) / (2 * R) * (height - 1))),
                int(round((x + R) / (2 * R) * (width - 1))))

    gens = [(name, u) for name, u in ((k, direction_2d(v)) for k, v in generators_2d(M).items())
            if u is not None]
    for name, u in gens:  # all rays first, then every label on top of a clear margin
        style = "bold cyan" if name.startswith("w") else "bold magenta"
        ang = float(np.degrees(np.arctan2(u[1], u[0]))) % 180.0
        ray = "─" if ang < 22.5 or ang >= 157.5 else "│" if 67.5 <= ang < 112.5 else (
            "╱" if ang < 90 else "╲")
        for t in np.linspace(0.08, 0.92, 40):
            canvas.put(*cell(*(t * u)), ray, style, fix=True)
    canvas.put(*cell(0.0, 0.0), "+", fix=True)
    qu = direction_2d(q)
    if path:
        for a, b in zip(path[:-1], path[1:], strict=True):
            pa, pb = np.asarray(a["point"]), np.asarray(b["point"])
            for s_ in np.linspace(0.0, 1.0, 60):
                with np.errstate(over="ignore", invalid="ignore"):
                    ux = direction_2d((1 - s_) * pa + s_ * pb)
                if ux is not None:
                    canvas.put(*cell(*(0.62 * ux)), "*", "bold red", fix=True)
    for name, u in gens:
        style = "bold cyan" if name.startswith("w") else "bold magenta"
        r, c = cell(*(1.0 * u))
        canvas.place_label(r, c, name, style, right=u[0] < -0.3)
    r, c = cell(*((0.75 * qu) if qu is not None else np.zeros(2)))
    canvas.place_label(r, c, "q", "bold red", right=False)
    text = canvas.text()
    text.append("1-4: the one cone r holding the region   ", style="dim")
    text.append("▒", style="yellow")
    text.append(" 2+ cones   blank: no cone   ", style="dim")
    text.append("w1 w2", style="bold cyan")
    text.append(" = I_j,  ", style="dim")
    text.append("z1 z2", style="bold magenta")
    text.append(" = -M_j (unit length);  ", style="dim")
    text.append("q", style="bold red")
    text.append(f" = ({fmt(q[0])}, {fmt(q[1])}) drawn at its direction", style="dim")
    if path:
        text.append(";  ", style="dim")
        text.append("*", style="bold red")
        top = max(float(p["z0"]) for p in path)
        text.append(f" Lemke's path q + z0 d (directions), z0 from {fmt(top)} back to "
                    f"{fmt(path[-1]['z0'])}", style="dim")
    return text


def plot_cones(M: Any, q: Any, target: Path, title: str = "",
               path: list[dict[str, Any]] | None = None) -> None:
    """Write the picture of :func:`cones_figure` with matplotlib (atomically).

    The format follows the file suffix (png by default).  Raises ImportError without
    matplotlib.
    """
    import matplotlib.pyplot as plt  # matplotlib is optional and slow to import: only here

    from lcpcli.io import atomic_path

    fig = cones_figure(M, q, title, path)
    fmt_name = (target.suffix.lstrip(".") or "png").lower()
    with atomic_path(target) as tmp:
        fig.savefig(tmp, format=fmt_name, dpi=120, bbox_inches="tight")
    plt.close(fig)


def cones_figure(M: Any, q: Any, title: str = "",
                 path: list[dict[str, Any]] | None = None) -> Any:
    """The matplotlib figure of the four complementary cones and q (n = 2).

    The legend names each cone by its number r and generators, below the axes so that it
    hides nothing; the generator labels sit inside the axes.  ``path``: Lemke's path
    ``q + z0 d`` (:func:`lcpcli.solvers.trace.lemke.path_points`), each state's point numbered.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    M = np.asarray(M, dtype=float)
    q = np.asarray(q, dtype=float)
    gens = generators_2d(M)
    extent = length_2d(q)
    if path:
        extent = max([extent] + [length_2d(p["point"]) for p in path])
    R = max(1.0, extent) * 1.25
    fig, ax = plt.subplots(figsize=(6.4, 7.2))
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:red"]
    for code in sorted(range(4), key=_cone_number):
        cols = [gens[f"z{j + 1}"] if (code >> j) & 1 else gens[f"w{j + 1}"] for j in range(2)]
        A = np.column_stack(cols)
        label = f"r = {_cone_number(code)}: Pos(" + ", ".join(
            (f"-M{j + 1}" if (code >> j) & 1 else f"I{j + 1}") for j in range(2)) + ")"
        if degenerate_2d(A):
            ax.plot([], [], color=colours[code], label=label + " (degenerate)")
            continue
        a0, a1 = (np.arctan2(c[1], c[0]) for c in cols)
        d = (a1 - a0) % (2 * np.pi)
        if d > np.pi:
            a0, d = a1, 2 * np.pi - d
        t = np.linspace(a0, a0 + d, 90)
        poly = np.vstack([[0, 0], np.column_stack([np.cos(t), np.sin(t)]) * R * 2.0, [0, 0]])
        ax.fill(poly[:, 0], poly[:, 1], color=colours[code], alpha=0.22, label=label)
    box = {"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8}
    for name, v in gens.items():
        u = direction_2d(v)
        if u is None:
            continue
        u = u * R * 0.8
        ax.annotate("", xy=u, xytext=(0, 0),
                    arrowprops={"arrowstyle": "->", "color": "black", "lw": 1.2})
        tex = f"$I_{name[1]}$" if name[0] == "w" else f"$-M_{name[1]}$"
        ax.text(*(u * 1.1), tex, ha="center", va="center", bbox=box)
    if path:
        pts = np.array([p["point"] for p in path])
        ax.plot(pts[:, 0], pts[:, 1], "--", color="crimson", lw=1.2,
                label="Lemke's path q + z0 d")
        for p in path[1:]:
            if p["z0"] == 0.0:  # back at q: named in q's label
                continue
            x, y = p["point"]
            ax.plot([x], [y], "s", color="crimson", ms=4)
            ax.annotate(f"{p['step']}: z0 = {fmt(p['z0'])}", (x, y), textcoords="offset points",
                        xytext=(6, -10), fontsize=8, color="crimson", bbox=box)
    ends = [str(p["step"]) for p in (path or [])[1:] if p["z0"] == 0.0]
    ax.plot([q[0]], [q[1]], "o", color="crimson", ms=7)
    ax.annotate(f"q = ({fmt(q[0])}, {fmt(q[1])})" + (f"  (step {', '.join(ends)}: z0 = 0)"
                                                       if ends else ""),
                (q[0], q[1]), textcoords="offset points", xytext=(8, 6), color="crimson",
                bbox=box)
    ax.axhline(0, color="grey", lw=0.5)
    ax.axvline(0, color="grey", lw=0.5)
    ax.set_xlim(-R, R)
    ax.set_ylim(-R, R)
    ax.set_aspect("equal")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.06), ncol=2, fontsize=8,
              frameon=False)
    ax.set_title(title or "complementary cones of M and the point q")
    return fig
