"""Parsers of method options (``-O KEY=VALUE``, ``--max-iter``, ``--z0``, ...).

Each parser takes what the user gave (a string from the command line, or a Python value from
the library) and returns the typed value, raising ``ValueError`` with a one-line reason; the
registry (:meth:`lcpcli.solvers.registry.Method.parse_options`) turns that into an ``OptionError``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lcpcli.core.limits import MAX_ITER


def vector_option(value: Any) -> np.ndarray | None:
    """A float vector from a list/array or a string ``'1,2 3'`` (None stays None)."""
    if value is None:
        return None
    if isinstance(value, str):
        value = [float(x) for x in value.replace(",", " ").split()]
    arr = np.asarray(value, dtype=np.float64).ravel()
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
    """A basis: booleans or 0/1 (True: z_i basic), as a sequence or as text (``"1,0,1"``, or
    the letters of ``--json``'s ``basis``, ``"FLF"``: F basic)."""
    if isinstance(value, str):
        text = value.strip()
        value = [c == "F" for c in text] if set(text) <= set("LF") and text else \
            [int(x) if x.strip() in ("0", "1") else -1 for x in text.split(",")]
    arr = np.asarray(value)
    if arr.ndim != 1 or arr.dtype.kind not in "bi" or not np.isin(arr, (0, 1)).all():
        raise ValueError("a basis is a list of booleans or 0/1 (True: z_i basic), '1,0,1', or "
                         "letters 'FLF' (F: z_i basic)")
    return arr.astype(bool)
