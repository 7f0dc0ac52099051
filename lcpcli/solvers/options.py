"""Parsers of method options (``-O KEY=VALUE``, ``--max-iter``, ``--z0``, ...).

Each parser takes what the user gave (a string from the command line, or a Python value from
the library) and returns the typed value, raising ``ValueError`` with a one-line reason; the
registry (:meth:`lcpcli.solvers.registry.Method.parse_options`) turns that into an ``OptionError``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.core.certificate import AT_LOWER, AT_UPPER, BETWEEN
from lcpcli.core.errors import OptionError
from lcpcli.core.limits import MAX_ITER
from lcpcli.core.numeric import real_array
from lcpcli.core.result import BASIS_LETTERS, Result


def vector_option(value: Any) -> np.ndarray | None:
    """A float vector from a list/array (real numbers only: the data rule of
    :func:`lcpcli.core.numeric.real_array`, as for M and q) or a string ``'1,2 3'`` (None
    stays None)."""
    if value is None:
        return None
    if isinstance(value, str):
        value = [float(x) for x in value.replace(",", " ").split()]
    arr = real_array(value, "the vector").ravel()
    if not np.all(np.isfinite(arr)):
        raise ValueError("contains NaN or Inf")
    return arr


def positive_int(value: Any) -> int:
    """A positive integer option (``max_iter``), at most :data:`MAX_ITER`."""
    if isinstance(value, bool):
        raise ValueError(f"must be a positive integer, got {value!r}")
    if isinstance(value, float) and not value.is_integer():
        raise ValueError(f"must be a positive integer, got {value}")
    try:
        v = int(value)
    except OverflowError:
        raise ValueError(f"must be at most {MAX_ITER:,}, got {value}") from None
    if v < 1:
        raise ValueError("must be a positive integer")
    if v > MAX_ITER:
        raise ValueError(f"must be at most {MAX_ITER:,}, got {v:,}")
    return v


def bool_option(value: Any) -> bool:
    """A true/false option: bools, or the strings 1/0, true/false, yes/no, on/off."""
    if isinstance(value, bool):
        return value
    low = str(value).strip().lower()
    if low in ("1", "true", "yes", "on"):
        return True
    if low in ("0", "false", "no", "off", ""):
        return False
    raise ValueError(f"expected true/false, got {value!r}")


def omega_option(value: Any) -> float:
    """The relaxation parameter: finite, ``0 < omega < 2`` (outside, PSOR need not converge)."""
    v = float(value)
    if not (np.isfinite(v) and 0.0 < v < 2.0):
        raise ValueError(f"omega must satisfy 0 < omega < 2, got {value}")
    return v


def basis_option(value: Any) -> np.ndarray:
    """A complementary basis (an index set) as booleans, True: ``z_i`` basic (``w_i = 0``).

    Accepted: a previous :class:`~lcpcli.core.result.Result` (its :attr:`z_basic`); booleans or
    0/1, as a sequence or as text ``"1,0,1"``; the letters of ``--json``'s ``basis``
    (:data:`~lcpcli.core.result.BASIS_LETTERS`: ``"FLUF"``, F basic, L/U ``z_i`` at a bound);
    an ``int8`` array of pair-state codes (``Result.basis``, :mod:`lcpcli.core.certificate`:
    ``BETWEEN`` basic).  The set is invariant under diagonal scalings of the problem."""
    if isinstance(value, Result):
        if value.z_basic is None:
            raise ValueError("the result carries no basis")
        return value.z_basic.copy()
    if isinstance(value, np.ndarray) and value.dtype == np.int8:
        if value.ndim != 1 or (value.size and not AT_LOWER <= value.min() <= value.max()
                               <= BETWEEN):
            raise ValueError(f"an int8 basis holds the pair-state codes {AT_LOWER}, "
                             f"{AT_UPPER}, {BETWEEN} (Result.basis)")
        return value == BETWEEN
    if isinstance(value, str):
        text = value.strip()
        value = [c == "F" for c in text] if set(text) <= set(BASIS_LETTERS) and text else \
            [int(x) if x.strip() in ("0", "1") else -1 for x in text.split(",")]
    arr = np.asarray(value)
    if arr.ndim == 1 and arr.dtype.kind == "b":
        return arr.copy()
    if arr.ndim != 1 or arr.dtype.kind not in "bi" or not np.isin(arr, (0, 1)).all():
        raise ValueError("a basis is a list of booleans or 0/1 (True: z_i basic), '1,0,1', "
                         "letters 'FLUF' (F: z_i basic), or a Result or its basis")
    return arr.astype(bool)


def index_set(basis: Any, n: int) -> np.ndarray:
    """A method's parsed ``basis`` option (:func:`basis_option`) as the booleans of an index set
    of ``n`` pairs (True: ``z_i`` basic); OptionError when its length is not ``n``."""
    F = np.asarray(basis, dtype=bool).ravel()
    if F.shape[0] != n:
        raise OptionError(f"basis has length {F.shape[0]}, the problem has n = {n}")
    return F
