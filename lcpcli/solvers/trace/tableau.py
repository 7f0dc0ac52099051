"""The condensed pivoting tableau shared by the replicas, and its two display layouts.

A recorded *state* holds the basic variable of each row (``basis``), their values ``q_prime``,
the nonbasic variables (``nonbasic``, in the original variable order: ``w1..wn``, ``z1..zn``,
then ``z0``) and the tableau ``M'`` (rows as ``basis``, columns as ``nonbasic``) of the
dictionary ``x_B = q' + M' x_N`` (Dai & Drumwright's ``w' = q' + M' z'``, sign convention
``w = M z + q``).  Two layouts of the same state:

* ``dictionary``: columns ``q'`` and the nonbasic variables; the entries are ``M'``;
* ``murty``: the textbook tableau of ``w - M z - d z0 = q`` after the pivots (Murty,
  Cottle-Pang-Stone): one column per variable ``w1..wn, z1..zn, z0`` (a unit column for each
  basic variable, ``-M'`` for the nonbasic ones) and the right-hand side ``q`` (= ``q'``).

Columns keep the original variable order in both layouts: a pivot removes the entering
variable's column and adds the leaving one's in its own place (no slot swapping).

The arithmetic is generic over the number type: float arrays give the compiled kernels'
rounding, object arrays of :class:`fractions.Fraction` an exact trace (``--exact``); recorded
values keep their type (:func:`scalar`), and :func:`num` writes either (``4/3``, ``1.33333``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from lcpcli.analysis.pivoting import ARTIFICIAL, var_name

#: The layouts of :func:`tableau_view` (the first is the default).
LAYOUTS = ("dictionary", "murty")

_NAME = re.compile(r"^([wz])(\d+)$")


def scalar(x: Any) -> Any:
    """A recorded number: a :class:`~fractions.Fraction` stays exact, anything else is a float."""
    return x if isinstance(x, Fraction) else float(x)


def num(x: Any) -> str:
    """A number in a sentence: a fraction as ``p/q`` (``4/3``, ``-2``), a float to 6 digits."""
    return str(x) if isinstance(x, Fraction) else f"{float(x) + 0.0:.6g}"


def as_numbers(a: Any) -> np.ndarray:
    """An array of the trace's numbers: floats, or fractions kept exact (object arrays)."""
    arr = np.asarray(a)
    return arr if arr.dtype == object else arr.astype(np.float64)


def is_exact(a: Any) -> bool:
    """Whether an array (or list) holds exact fractions (an ``--exact`` trace)."""
    arr = np.asarray(a)
    return arr.dtype == object and any(isinstance(x, Fraction) for x in arr.flat)


def code_name(code: int, n: int) -> str:
    """1-based name of a kernel variable code: ``0..n-1`` = w, ``n..2n-1`` = z, ``2n`` = z0."""
    code = int(code)
    return var_name(("w", code) if code < n else ("z", code - n), n)


def canonical_key(name: str) -> tuple[int, int]:
    """Sort key of the original variable order: ``w1..wn``, ``z1..zn``, then ``z0``."""
    if name == ARTIFICIAL:
        return (2, 0)
    m = _NAME.match(name)
    if not m:
        raise ValueError(f"not a variable name: {name!r}")
    return (0 if m.group(1) == "w" else 1, int(m.group(2)))


def complement(name: str) -> str | None:
    """``w_i`` <-> ``z_i``; the artificial variable has no complement (``None``)."""
    if name == ARTIFICIAL:
        return None
    return ("z" if name[0] == "w" else "w") + name[1:]


def pivot_update(T: np.ndarray, qb: np.ndarray, r: int, c: int) -> None:
    """Pivot the dictionary ``x_B = qb + T x_N`` on ``(r, c)`` in place.

    The compiled kernels' operations in the same order (same rounding): the basic variable of
    row ``r`` and the nonbasic variable of column ``c`` exchange places.  An entry past the
    float64 range becomes inf or NaN without a warning, as in the kernels (the trace's verdict
    is the certificate's).
    """
    with np.errstate(all="ignore"):
        _pivot_update(T, qb, r, c)


def _pivot_update(T: np.ndarray, qb: np.ndarray, r: int, c: int) -> None:
    p = T[r, c]
    inv = 1 / p  # 1.0 / p for floats (same rounding), exact for fractions
    rowr = -T[r, :] * inv
    rowr[c] = inv
    qr = -qb[r] * inv
    f = T[:, c].copy()
    rows = np.flatnonzero(f != 0)
    rows = rows[rows != r]
    fr = f[rows]
    qb[rows] += fr * qr
    T[rows, :] += fr[:, None] * rowr[None, :]
    T[rows, c] = fr * inv
    T[r, :] = rowr
    qb[r] = qr


def state_record(T: np.ndarray | None, qb: np.ndarray, basic: np.ndarray,
                 nonbasic: np.ndarray, n: int, max_n: int) -> dict[str, Any]:
    """``basis``, ``q_prime``, ``nonbasic`` (original order) and ``tableau`` (None if n > max_n)."""
    order = np.argsort(nonbasic, kind="stable")  # codes: w < z < z0 = the original order
    return {
        "basis": [code_name(b, n) for b in basic],
        "q_prime": qb.tolist(),
        "nonbasic": [code_name(nonbasic[j], n) for j in order],
        "tableau": T[:, order].tolist() if T is not None and n <= max_n else None,
    }


@dataclass
class TableauView:
    """A state laid out for display: rows named by their basic variable, numeric columns."""

    layout: str
    label: str  # header of the row-name column
    rows: list[str]
    columns: list[str]
    values: np.ndarray  # len(rows) x len(columns)
    pivot: tuple[int, int] | None  # (row, column) of the marked pivot element, 0-based
    equation: str


def tableau_view(state: dict[str, Any], layout: str = "dictionary",
                 pivot: dict[str, Any] | None = None) -> TableauView | None:
    """The ``layout`` view of a recorded state (``None`` when it holds no tableau).

    ``pivot`` is the ``pivot_element`` of the pivot made *from* this state (``row`` 1-based,
    ``column`` the entering variable's name); it is marked in the view.
    """
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
    if state.get("tableau") is None:
        return None
    basis, nonbasic = list(state["basis"]), list(state["nonbasic"])
    exact = is_exact(state["q_prime"]) or is_exact(state["tableau"])
    kind = object if exact else float
    qp = np.asarray(state["q_prime"], dtype=kind)
    T = np.asarray(state["tableau"], dtype=kind).reshape(len(basis), len(nonbasic))
    artificial = ARTIFICIAL in basis or ARTIFICIAL in nonbasic
    initial = all(b.startswith("w") for b in basis)
    where = None
    if layout == "dictionary":
        cols = ["q'", *nonbasic]
        values = np.column_stack([qp, T]) if basis else np.zeros((0, len(cols)), dtype=kind)
        if pivot is not None:
            where = (int(pivot["row"]) - 1, 1 + nonbasic.index(pivot["column"]))
        if initial:
            eq = "w = q + M z + d z0" if artificial else "w = q + M z"
        else:
            eq = "w' = q' + M' z'" if artificial else "x_B = q' + M' x_N"
        return TableauView(layout, "basic", basis, cols, values, where, eq)
    variables = sorted(basis + nonbasic, key=canonical_key)
    values = np.zeros((len(basis), len(variables) + 1), dtype=kind)  # object: int 0
    for r, b in enumerate(basis):
        values[r, variables.index(b)] = 1
    for j, v in enumerate(nonbasic):
        values[:, variables.index(v)] = -T[:, j] if exact else -T[:, j] + 0.0  # no -0
    values[:, -1] = qp
    if pivot is not None:
        where = (int(pivot["row"]) - 1, variables.index(pivot["column"]))
    eq = "w - M z - d z0 = q" if artificial else "w - M z = q"
    return TableauView(layout, "BV", basis, [*variables, "q"], values, where, eq)
