"""A tiny document model for teaching output, written as rich, Markdown or LaTeX.

Renderers of traces, transforms and cone tables build a list of *pages* (one per step), each
a list of blocks: :class:`Heading`, :class:`Para`, :class:`Grid` (a table whose marked cells
are the pivot element) and :class:`Items`.  The same pages then go to the terminal
(:func:`to_rich`), to Markdown (:func:`to_markdown`: headings, pipe tables, the pivot element
in bold brackets) or to LaTeX (:func:`to_latex`: a fragment for ``\\input{}``, one ``tabular``
per table, detail tables such as a ratio test as lists, the pivot element in ``\\fbox{}``, no
package needed).

Text is plain ASCII math as elsewhere in the CLI (``w1``, ``q'_i``, ``B^-1``, ``>=``); the LaTeX
writer turns those tokens into math (``$w_{1}$``, ``$q'_{i}$``, ``$B^{-1}$``, ``$\\ge$``) and
escapes the rest; a span in backticks is a whole formula (LaTeX math, Markdown code, plain on
the terminal).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from rich.console import Group
from rich.table import Table
from rich.text import Text

from lcpcli.cli.render.common import fit

#: Formats of :func:`write` (``text`` is the terminal rendering).
FORMATS = ("text", "markdown", "latex")


@dataclass
class Heading:
    text: str
    level: int = 2


@dataclass
class Para:
    text: str
    style: str = ""


@dataclass
class Items:
    items: list[str]


@dataclass
class Grid:
    """A table: ``header``, string ``rows``, ``align`` per column (``l``/``r``), marked cells."""

    header: list[str]
    rows: list[list[str]]
    align: list[str] | None = None
    title: str = ""
    marked: set[tuple[int, int]] = field(default_factory=set)
    #: Column index after which a vertical rule separates groups (LaTeX), e.g. the row names.
    rules: tuple[int, ...] = ()
    #: A detail table (a ratio test): LaTeX writes it as a list, so that a step's only
    #: ``tabular`` is its tableau.
    inline: bool = False

    def alignment(self) -> list[str]:
        return self.align or ["l"] + ["r"] * (len(self.header) - 1)


Block = Heading | Para | Items | Grid
Page = list[Block]


# ------------------------------------------------------------------------------- rich
def to_rich(pages: list[Page]) -> Group:
    """Terminal rendering (colour only where the console allows it)."""
    out: list[object] = []
    for k, page in enumerate(pages):
        if k:
            out.append(Text(""))
        for block in page:
            out.append(_rich_block(block))
    return Group(*out)


def _rich_block(block: Block) -> object:
    if isinstance(block, Heading):
        return Text(block.text, style="bold")
    if isinstance(block, Para):
        return Text(block.text.replace("`", ""), style=block.style or "")
    if isinstance(block, Items):
        return Text("\n".join(f"  - {x}" for x in block.items))
    table = Table(title=block.title or None, title_justify="left")
    for name, a in zip(block.header, block.alignment(), strict=True):
        table.add_column(name, justify="right" if a == "r" else "left")
    for i, row in enumerate(block.rows):
        cells = []
        for j, c in enumerate(row):
            if (i, j) in block.marked:
                cells.append(Text(f"[{c}]", style="bold reverse"))
            else:
                cells.append(Text(c))
        table.add_row(*cells)
    return fit(table)


# ------------------------------------------------------------------------------- markdown
def to_markdown(pages: list[Page]) -> str:
    """GitHub-flavoured Markdown: ``##`` headings, pipe tables, ``**[p]**`` pivot elements."""
    parts: list[str] = []
    for page in pages:
        for block in page:
            parts.append(_md_block(block))
    return "\n\n".join(p for p in parts if p) + "\n"


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _md_block(block: Block) -> str:
    if isinstance(block, Heading):
        return "#" * (block.level + 1) + " " + block.text
    if isinstance(block, Para):
        parts = block.text.split("`")  # backtick spans are code: no escaping inside
        return "".join(f"`{p}`" if k % 2 else p.replace("*", "\\*").replace("_", "\\_")
                       for k, p in enumerate(parts))
    if isinstance(block, Items):
        return "\n".join("- " + x.replace("*", "\\*").replace("_", "\\_") for x in block.items)
    lines = []
    if block.title:
        lines.append(f"*{block.title}*")
        lines.append("")
    lines.append("| " + " | ".join(_md_cell(h) for h in block.header) + " |")
    lines.append("| " + " | ".join("---:" if a == "r" else "---"
                                   for a in block.alignment()) + " |")
    for i, row in enumerate(block.rows):
        cells = [f"**[{_md_cell(c)}]**" if (i, j) in block.marked else _md_cell(c)
                 for j, c in enumerate(row)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


# ------------------------------------------------------------------------------- LaTeX
_TEX_SPECIAL = {"&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_", "{": r"\{",
                "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}",
                "\\": r"\textbackslash{}"}
_TOKEN = re.compile(
    r"(?P<var>(?<![\w\\])[wzqdcgMByaex]'?(?:\d+|_[a-zA-Z0-9]+)(?![\w']))"  # w1, q'_i, x_B
    r"|(?P<prime>(?<![\w\\])[qMwz]'(?![\w]))"  # q', M', w', z'
    r"|(?P<inv>B\^-1)"
    r"|(?P<rel>>=|<=|->|!=|<|>|\|)"
    r"|(?P<num>(?<![\w.])-?\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w.]))"
)
_REL = {">=": r"\ge", "<=": r"\le", "->": r"\to", "!=": r"\ne", "<": "<", ">": ">",
        "|": "|"}


def tex_escape(text: str) -> str:
    """Escape LaTeX's special characters in plain text."""
    return "".join(_TEX_SPECIAL.get(ch, ch) for ch in text)


def _tex_math(token: str, kind: str) -> str:
    if kind == "inv":
        return "B^{-1}"
    if kind == "rel":
        return _REL[token]
    if kind == "num":
        mant, _, exp = token.partition("e")
        if not exp:
            return token
        power = f"10^{{{int(exp)}}}"
        if mant.lstrip("-") in ("1", "1.0"):
            return ("-" if mant.startswith("-") else "") + power
        return f"{mant} \\cdot {power}"
    m = re.match(r"^([A-Za-z])('?)(?:(\d+)|_([A-Za-z0-9]+))?$", token)
    if not m:
        return tex_escape(token)
    base, prime, num, sub = m.groups()
    idx = num if num is not None else sub
    return f"{base}{prime}" + (f"_{{{idx}}}" if idx else "")


def _tex_plain(text: str) -> str:
    out = []
    pos = 0
    for m in _TOKEN.finditer(text):
        out.append(tex_escape(text[pos:m.start()]))
        out.append(f"${_tex_math(m.group(0), m.lastgroup or '')}$")
        pos = m.end()
    out.append(tex_escape(text[pos:]))
    return "".join(out)


def _tex_formula(text: str) -> str:
    """A whole ASCII formula (a backtick span) as one math expression."""
    out = []
    pos = 0
    for m in _TOKEN.finditer(text):
        out.append(text[pos:m.start()])
        out.append(_tex_math(m.group(0), m.lastgroup or ""))
        pos = m.end()
    out.append(text[pos:])
    return "$" + "".join(out) + "$"


def tex_text(text: str) -> str:
    """Plain text with the CLI's ASCII math (``w1``, ``q'_i``, ``>=``) turned into LaTeX;
    a span in backticks is one formula."""
    parts = text.split("`")
    return "".join(_tex_formula(p) if k % 2 else _tex_plain(p) for k, p in enumerate(parts))


def _tex_block(block: Block) -> str:
    if isinstance(block, Heading):
        cmd = {1: "section*", 2: "subsection*"}.get(block.level, "paragraph")
        return f"\\{cmd}{{{tex_text(block.text)}}}"
    if isinstance(block, Para):
        return tex_text(block.text) + "\n"
    if isinstance(block, Items):
        items = "\n".join(f"  \\item {tex_text(x)}" for x in block.items)
        return "\\begin{itemize}\n" + items + "\n\\end{itemize}"
    if block.inline:
        return _tex_items(block)
    spec = ""
    for j, a in enumerate(block.alignment()):
        spec += a
        if j in block.rules:
            spec += "|"
    lines = []
    if block.title:
        lines.append(f"\\noindent {tex_text(block.title)}\\\\[2pt]")
    lines.append(f"\\begin{{tabular}}{{{spec}}}")
    lines.append("\\hline")
    lines.append(" & ".join(tex_text(h) for h in block.header) + " \\\\")
    lines.append("\\hline")
    for i, row in enumerate(block.rows):
        cells = []
        for j, c in enumerate(row):
            cell = tex_text(c)
            cells.append(f"\\fbox{{{cell}}}" if (i, j) in block.marked else cell)
        lines.append(" & ".join(cells) + " \\\\")
    lines.append("\\hline")
    lines.append("\\end{tabular}")
    return "\n".join(lines) + "\n"


def _tex_items(block: Grid) -> str:
    """A detail table as a list: one item per row, ``header: value`` pairs."""
    lines = []
    if block.title:
        lines.append(f"\\noindent {tex_text(block.title)}")
    lines.append("\\begin{itemize}")
    for i, row in enumerate(block.rows):
        parts = []
        for j, (h, c) in enumerate(zip(block.header, row, strict=True)):
            if not c:
                continue
            cell = tex_text(c)
            if (i, j) in block.marked:
                cell = f"\\fbox{{{cell}}}"
            parts.append(f"{tex_text(h)}: {cell}" if h else cell)
        lines.append("  \\item " + "; ".join(parts))
    lines.append("\\end{itemize}")
    return "\n".join(lines)


def to_latex(pages: list[Page], title: str = "") -> str:
    """A LaTeX fragment for ``\\input{}``: text, one ``tabular`` per table, ``\\fbox`` pivots."""
    parts = ["% generated by lcpcli; \\input{} it into a document (no package needed: the",
             "% pivot element is boxed with \\fbox)"]
    if title:
        parts.append(f"% {title}")
    for page in pages:
        parts.append("")
        for block in page:
            parts.append(_tex_block(block))
    return "\n".join(parts).rstrip() + "\n"


def write(pages: list[Page], fmt: str, title: str = "") -> str:
    """``markdown`` or ``latex`` text of ``pages``."""
    if fmt == "markdown":
        return to_markdown(pages)
    if fmt == "latex":
        return to_latex(pages, title)
    raise ValueError(f"format must be markdown or latex, got {fmt!r}")
