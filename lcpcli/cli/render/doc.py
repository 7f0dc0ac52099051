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
                "\\": r"\textbackslash{}", "<": r"\textless{}", ">": r"\textgreater{}",
                "|": r"\textbar{}"}
#: The tokens of the CLI's ASCII math.
_LEX = re.compile(
    r"(?P<space>\s+)"
    r"|(?P<word>\d+-[A-Za-z]+)"  # 1-based
    r"|(?P<num>-?\d+(?:\.\d+)?(?:e[-+]?\d+)?(?:/\d+)?(?![\w.]))"  # 3, -2, 0.5, 1e-09, 4/3
    r"|(?P<inv>B\^-1)"
    r"|(?P<word2>[A-Za-z][A-Za-z0-9_']*(?:-[A-Za-z][A-Za-z0-9_']*)*)"  # w1, q'_i, alpha-bar
    r"|(?P<dots>\.\.\.)"
    r"|(?P<op>>=|<=|->|!=|[=<>+\-*/|^])"
    r"|(?P<open>[(\[{])"
    r"|(?P<close>[)\]}])"
    r"|(?P<comma>,)"
    r"|(?P<other>.)")
_VAR = re.compile(r"^([A-Za-z])('?)(?:(\d+)|_([A-Za-z0-9]+))$")  # w1, q'_i, M'_rr, x_B
_PRIME = re.compile(r"^[qMwzxy]'$")  # q', M', w', z'
_GREEK = {"alpha": r"\alpha", "beta": r"\beta", "gamma": r"\gamma", "zeta": r"\zeta",
          "eps": r"\varepsilon", "omega": r"\omega", "mu": r"\mu"}
_FUNC = {"min": r"\min", "max": r"\max", "det": r"\det", "mid": r"\mathrm{mid}",
         "inf": r"\infty"}
_OPS = {">=": r"\ge", "<=": r"\le", "->": r"\to", "!=": r"\ne", "*": r"\cdot", "=": "=",
        "<": "<", ">": ">", "+": "+", "-": "-", "/": "/", "|": "|", "^": "^"}


def tex_escape(text: str) -> str:
    """Escape LaTeX's special characters in plain text."""
    return "".join(_TEX_SPECIAL.get(ch, ch) for ch in text)


def _lex(text: str) -> list[tuple[str, str]]:
    out = []
    for m in _LEX.finditer(text):
        kind = m.lastgroup or "other"
        out.append(("word" if kind == "word2" else kind, m.group(0)))
    return out


def _word_kind(word: str) -> str:
    """``math`` (a variable such as ``w1``), ``maybe`` (a letter, a Greek or function name:
    math beside an operator or a variable) or ``text``."""
    if _VAR.match(word) or _PRIME.match(word):
        return "math"
    base = word[:-4] if word.endswith("-bar") else word.rstrip("'")
    if len(word) == 1 or base in _GREEK or word in _FUNC:
        return "maybe"
    return "text"


def _classify(tokens: list[tuple[str, str]]) -> list[bool]:
    """Which tokens are math: variables, numbers, operators; ambiguous words (a single
    letter, ``alpha``, ``min``) when next to an operator or a variable."""
    kind = []
    for k, tok in tokens:
        if k == "word":
            kind.append(_word_kind(tok))
        elif k in ("num", "inv", "op", "dots"):
            kind.append("math")
        elif k in ("space", "open", "close", "comma"):
            kind.append("glue")
        else:
            kind.append("text")
    for i, (k, _) in enumerate(tokens):  # (0, 1, 3/2): a bracketed list of values is math
        if k != "open" or kind[i] == "math":
            continue
        depth, inner = 0, []
        for j in range(i, len(tokens)):
            depth += {"open": 1, "close": -1}.get(tokens[j][0], 0)
            if depth == 0:
                break
            inner.append(j)
        else:
            continue
        body = [kind[m] for m in inner[1:]]
        if body and all(x in ("math", "glue") for x in body) and "math" in body:
            for m in [*inner, j]:
                kind[m] = "math"
    changed = True
    while changed:
        changed = False
        for i, kd in enumerate(kind):
            if kd != "maybe":
                continue
            near = [j for j in (_neighbour(kind, i, -1), _neighbour(kind, i, 1)) if j is not None]
            if any(kind[j] == "math" for j in near):
                kind[i] = "math"
                changed = True
    return [kd == "math" for kd in kind]


def _neighbour(kind: list[str], i: int, step: int) -> int | None:
    j = i + step
    while 0 <= j < len(kind) and kind[j] == "glue":
        j += step
    return j if 0 <= j < len(kind) else None


def _runs(tokens: list[tuple[str, str]]) -> list[tuple[bool, list[tuple[str, str]]]]:
    """Split the tokens into text spans and maximal formulas: a formula runs over math tokens
    and the spaces, brackets and (bracketed) commas between them; a comma or two spaces
    outside brackets end it, so ``z0 = 1, w2 = 5`` and ``z0 = 1   m = 2`` are two formulas."""
    math = _classify(tokens)
    out: list[tuple[bool, list[tuple[str, str]]]] = []
    i, n = 0, len(tokens)
    while i < n:
        if not math[i]:
            j = i
            while j < n and not math[j]:
                j += 1
            out.append((False, tokens[i:j]))
            i = j
            continue
        j, depth, last = i, 0, i
        while j < n:
            k, tok = tokens[j]
            if k == "open":
                depth += 1
            elif k == "close":
                if depth == 0:
                    break
                depth -= 1
                last = j
            elif k in ("comma", "space") and depth == 0 and (k == "comma" or len(tok) > 1):
                break  # a comma or a wider space outside brackets separates two formulas
            elif math[j]:
                last = j
            elif k not in ("space", "comma"):
                break
            j += 1
        # a bracket opened in the formula and closed after it stays out of it (text)
        depth, first_open = 0, None
        for k in range(i, last + 1):
            if tokens[k][0] == "open":
                depth += 1
                first_open = k if depth == 1 else first_open
            elif tokens[k][0] == "close":
                depth -= 1
        if depth > 0 and first_open is not None and first_open > i:
            last = first_open - 1
            while last > i and tokens[last][0] == "space":
                last -= 1
        # an opening bracket just before the formula belongs to it when it closes inside
        run = tokens[i:last + 1]
        if out and not out[-1][0] and out[-1][1] and out[-1][1][-1][0] == "open":
            opened = sum(1 for k, _ in run if k == "open") - sum(1 for k, _ in run if k == "close")
            if opened < 0:
                run = [out[-1][1].pop(), *run]
        while run and run[-1][0] == "close" and (
                sum(1 for k, _ in run if k == "close") > sum(1 for k, _ in run if k == "open")):
            run.pop()
            last -= 1
        out.append((True, run))
        i = last + 1
    return out


def _tex_token(kind: str, tok: str) -> str:
    if kind == "space":
        return " "
    if kind == "inv":
        return "B^{-1}"
    if kind == "dots":
        return r"\dots"
    if kind == "op":
        return _OPS[tok]
    if kind == "comma":
        return r",\allowbreak "
    if kind in ("open", "close"):
        return {"{": r"\{", "}": r"\}"}.get(tok, tok)
    if kind == "num":
        mant, _, exp = tok.partition("e")
        if not exp:
            return tok
        power = f"10^{{{int(exp)}}}"
        if mant.lstrip("-") in ("1", "1.0"):
            return ("-" if mant.startswith("-") else "") + power
        return f"{mant} \\cdot {power}"
    m = _VAR.match(tok)
    if m:
        base, prime, num, sub = m.groups()
        idx = num if num is not None else _GREEK.get(str(sub), sub)
        return f"{base}{prime}" + (f"_{{{idx}}}" if idx else "")
    if tok.endswith("-bar") and tok[:-4] in _GREEK:
        return rf"\bar{{{_GREEK[tok[:-4]]}}}"
    base = tok.rstrip("'")
    if base in _GREEK:
        return _GREEK[base] + tok[len(base):]
    if tok in _FUNC:
        return _FUNC[tok] + " "
    return tok if re.fullmatch(r"[A-Za-z]'?", tok) else rf"\mathrm{{{tex_escape(tok)}}}"


def _tex_math(tokens: list[tuple[str, str]]) -> str:
    """One formula: the tokens in math mode (a superscript's token braced).  Numbers side by
    side (a matrix row ``1 -2 0``) keep a visible space, ``1\\ {-2}\\ 0``: TeX drops the
    spaces of math mode (``$-2 0$`` would read -20), and the brace keeps a minus unary."""
    out = []
    k = 0
    while k < len(tokens):
        kind, tok = tokens[k]
        if kind == "num" and k >= 2 and tokens[k - 1][0] == "space" \
                and tokens[k - 2][0] == "num":
            out[-1] = "\\ "
            out.append("{" + _tex_token(kind, tok) + "}" if tok.startswith("-")
                       else _tex_token(kind, tok))
            k += 1
            continue
        if kind == "op" and tok == "^" and k + 1 < len(tokens):
            if out and "'" in out[-1]:  # M'_d^x: the prime is a superscript already
                out[-1] = "{" + out[-1] + "}"
            if tokens[k + 1] == ("open", "{"):  # ^{beta'}: the group is the superscript
                depth, end = 0, k + 1
                for end in range(k + 1, len(tokens)):
                    depth += {"{": 1, "}": -1}.get(tokens[end][1], 0)
                    if depth == 0:
                        break
                out.append("^{" + _tex_math(tokens[k + 2:end]) + "}")
                k = end + 1
                continue
            out.append("^{" + _tex_token(*tokens[k + 1]) + "}")
            k += 2
            continue
        out.append(_tex_token(kind, tok))
        k += 1
    return "".join(out).strip()


def _is_plain_number(tokens: list[tuple[str, str]]) -> bool:
    """A lone nonnegative number with no exponent (``Step 3``): plain digits in text."""
    return (len(tokens) == 1 and tokens[0][0] == "num" and not tokens[0][1].startswith("-")
            and "e" not in tokens[0][1] and "/" not in tokens[0][1])


def _tex_plain(text: str, numbers: bool = False) -> str:
    """Text with its formulas (maximal runs of ASCII math) each as one ``$...$``; ``numbers``:
    a lone number is a formula too (a table cell)."""
    out = []
    for is_math, toks in _runs(_lex(text)):
        has_value = any(k in ("num", "inv", "word") for k, _ in toks)
        if is_math and has_value and (numbers or not _is_plain_number(toks)):
            out.append(f"${_tex_math(toks)}$")
        else:  # a path or a long name may break after / and _; a wide space stays wide
            out.append(re.sub(r"  +", r"\\quad ", tex_escape("".join(t for _, t in toks)))
                       .replace("/", "/\\allowbreak{}").replace("\\_", "\\_\\allowbreak{}"))
    return "".join(out)


def _tex_formula(text: str) -> str:
    """A whole ASCII formula (a backtick span) as one math expression."""
    return "$" + _tex_math(_lex(text)) + "$"


def tex_text(text: str, numbers: bool = False) -> str:
    """Plain text with the CLI's ASCII math (``w1``, ``q'_i``, ``>=``, ``-2``) turned into
    LaTeX, one math environment per formula (``$-q_{i} / d_{i}$``, never ``-$q_{i}$``); a span
    in backticks is one formula."""
    parts = text.split("`")
    return "".join(_tex_formula(p) if k % 2 else _tex_plain(p, numbers)
                   for k, p in enumerate(parts))


#: Width available to a table on a portrait page (article, 10 pt: a 345 pt text width).
TEX_TEXT_WIDTH = 340.0
#: Estimated width of one character of a cell, and of the padding of a column (2 x 4 pt).
TEX_CHAR = 5.4
TEX_PAD = 8.0


def _tex_width(text: str) -> float:
    """A rough width in points of a cell as typeset (subscripts narrower than letters)."""
    plain = re.sub(r"_\w+", lambda m: "x" * max(1, (len(m.group(0)) - 1) * 2 // 3), text)
    return len(plain) * TEX_CHAR


def _tex_blocks(block: Grid) -> list[list[int]]:
    """Column blocks of a table that fit a portrait page, each repeating column 0."""
    cols = range(len(block.header))
    width = [max([_tex_width(block.header[j])] + [_tex_width(r[j]) for r in block.rows]) + TEX_PAD
             for j in cols]
    if sum(width) <= TEX_TEXT_WIDTH or len(width) < 3:
        return [list(cols)]
    blocks, current, used = [], [0], width[0]
    for j in cols[1:]:
        if len(current) > 1 and used + width[j] > TEX_TEXT_WIDTH:
            blocks.append(current)
            current, used = [0], width[0]
        current.append(j)
        used += width[j]
    blocks.append(current)
    return blocks


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
    blocks = _tex_blocks(block)
    lines = []
    if block.title:
        lines.append(f"\\noindent {tex_text(block.title)}\\\\[2pt]")
    if len(blocks) > 1:
        lines.append(f"\\noindent (The table is split into {len(blocks)} column blocks to fit "
                     f"the page; each repeats the first column.)\\\\[2pt]")
    for k, picks in enumerate(blocks):
        spec = ""
        for j in picks:
            spec += block.alignment()[j]
            if j in block.rules and j != picks[-1]:
                spec += "|"
        if k:
            lines.append("\\\\[4pt]")
        lines.append("\\noindent{\\setlength{\\tabcolsep}{4pt}%")
        lines.append(f"\\begin{{tabular}}{{{spec}}}")
        lines.append("\\hline")
        lines.append(" & ".join(tex_text(block.header[j]) for j in picks) + " \\\\")
        lines.append("\\hline")
        for i, row in enumerate(block.rows):
            cells = []
            for j in picks:
                cell = tex_text(row[j], numbers=True)
                cells.append(f"\\fbox{{{cell}}}" if (i, j) in block.marked else cell)
            lines.append(" & ".join(cells) + " \\\\")
        lines.append("\\hline")
        lines.append("\\end{tabular}}")
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
            cell = tex_text(c, numbers=True)
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
    for page in pages:  # \sloppy: a long formula moves to the next line, never into the margin
        parts.append("")
        parts.append("\\begingroup\\sloppy")
        for block in page:
            parts.append(_tex_block(block))
        parts.append("\\par\\endgroup")
    return "\n".join(parts).rstrip() + "\n"


def write(pages: list[Page], fmt: str, title: str = "") -> str:
    """``markdown`` or ``latex`` text of ``pages``."""
    if fmt == "markdown":
        return to_markdown(pages)
    if fmt == "latex":
        return to_latex(pages, title)
    raise ValueError(f"format must be markdown or latex, got {fmt!r}")
