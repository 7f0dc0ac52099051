"""The typed rule for problem data: which values count as numbers (one definition).

Problem data (``M``, ``q``, ``lower``, ``upper``, the parts of a sparse ``M``, a warm start ``z0``)
must be **real numbers**: integer (signed or unsigned) or floating-point values, converted to
float64.  Everything else is refused with a one-line :class:`ProblemError`, never converted:

* booleans: ``true`` is not 1 in a matrix (usually a mask stored in the wrong place);
* complex numbers: numpy would drop the imaginary part with a warning;
* strings, even numeric text (``"1.5"`` is text, not a number);
* Python objects, structured records, dates and time spans.

Index arrays of sparse matrices must be integers (:data:`INDEX_KINDS`).  Readers check the
dtype from a file's header (NPZ, HDF5) before reading the data; JSON values are checked as
decoded.  ``lcpcli.solve(M, q)`` applies the same rule to arrays given from Python.

**Non-finite numbers in output** (one rule, :func:`json_text`): JSON has no Inf or NaN, so every
JSON that lcpcli writes (``--json`` on stdout, ``-o result.json``, the rows of ``.jsonl``
batch files and of HDF5 result files, ``enumerate``/``info``/``contact-matrix --json``) writes a
number that is not finite as ``null``; it never writes the non-standard tokens ``Infinity`` or
``NaN``, and never fails on them.  A ratio whose denominator is zero has no meaning and is
``null`` by the same rule (the relative forward error bound when ``z = 0``).  CSV cells of such
numbers are empty; binary result arrays (HDF5 datasets, NPZ) keep the IEEE value (Inf, or NaN
where the JSON row has ``null``).
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from lcpcli.core.errors import ProblemError

#: The optional C JSON codec (orjson, extra "fast"; every result means the same without it):
#: None until loaded.  A batch worker loads it up front (:func:`load_fast_json`, about 2 ms
#: once); a one-liner does not pay that import: below :data:`FAST_JSON_MIN_BYTES` of text the
#: standard library is as fast.
_orjson: Any = None
FAST_JSON_MIN_BYTES = 1 << 16


def load_fast_json() -> Any:
    """Import orjson (once) and return it; None when it is not installed."""
    global _orjson
    if _orjson is None:
        try:
            import orjson
        except ImportError:  # pragma: no cover - depends on the environment
            return None
        _orjson = orjson
    return _orjson


def fast_json(size: int = 0) -> Any:
    """orjson when it is loaded, or when a text of ``size`` bytes is worth loading it for;
    else None (the caller uses the standard library)."""
    if _orjson is None and size >= FAST_JSON_MIN_BYTES:
        return load_fast_json()
    return _orjson

#: numpy dtype kinds accepted as real numbers (signed int, unsigned int, float).
REAL_KINDS = "iuf"
#: numpy dtype kinds accepted for sparse index arrays.
INDEX_KINDS = "iu"
#: What the refused kinds are called in messages.
KIND_NAMES = {"b": "booleans", "c": "complex numbers", "U": "strings", "S": "byte strings",
              "O": "mixed or non-numeric values", "V": "structured records", "M": "dates",
              "m": "time spans", "T": "strings", "f": "floating-point numbers",
              "i": "integers", "u": "integers"}


def kind_name(kind: str) -> str:
    """A readable name for a numpy dtype kind (``"c"`` -> ``"complex numbers"``)."""
    return KIND_NAMES.get(kind, f"values of type {kind!r}")


def check_dtype(dtype: Any, label: str, *, kinds: str = REAL_KINDS) -> None:
    """ProblemError unless ``dtype`` is of one of ``kinds`` (default: real numbers)."""
    try:
        kind = np.dtype(dtype).kind
    except TypeError:
        raise ProblemError(f"{label} has an unsupported data type ({dtype})") from None
    if kind not in kinds:
        want = "integers" if kinds == INDEX_KINDS else "real numbers (integers or floats)"
        raise ProblemError(f"{label} holds {kind_name(kind)}; expected {want}")


def _python_kind(x: Any) -> str | None:
    """The refused kind of one Python scalar (None when it is a real number)."""
    if isinstance(x, (bool, np.bool_)):
        return "b"
    if isinstance(x, (int, float, np.integer, np.floating)):
        return None
    if isinstance(x, (complex, np.complexfloating)):
        return "c"
    if isinstance(x, (str, bytes)):
        return "U"
    return "O"


def scan_nested(value: Any, label: str, *, allow_none: bool = False) -> None:
    """Check every scalar of nested lists/tuples (iteratively: no recursion on deep data).

    ``allow_none`` accepts ``None`` (JSON ``null``: an infinite bound).  Used where numpy's
    inferred dtype cannot tell (``[True, 2.5]`` becomes a float array).
    """
    stack = [value]
    while stack:
        item = stack.pop()
        if isinstance(item, (list, tuple)):
            stack.extend(item)
            continue
        if item is None and allow_none:
            continue
        kind = _python_kind(item)
        if kind is not None:
            raise ProblemError(f"{label} holds {kind_name(kind)}; expected real numbers "
                               f"(integers or floats)")


def real_array(value: Any, label: str, *, scan: bool = True) -> np.ndarray:
    """``value`` as a float64 array under the rule above (ProblemError otherwise).

    ``scan`` checks the elements of Python lists one by one (booleans hide in float arrays);
    callers that already know the list holds no booleans pass ``scan=False``.
    """
    if type(value) is np.ndarray and value.dtype is _FLOAT64:
        return value  # native float64: real numbers already (the usual case, in one step)
    if isinstance(value, (list, tuple)) and scan:
        scan_nested(value, label)
    elif not isinstance(value, (list, tuple, np.ndarray)) and not hasattr(value, "dtype") \
            and _python_kind(value) is not None:
        raise ProblemError(f"{label} must be real numbers, got a {type(value).__name__}")
    try:
        arr = np.asarray(value)
    except (ValueError, TypeError) as exc:  # ragged nesting
        raise ProblemError(f"{label} is not a rectangular array of numbers "
                           f"({str(exc).splitlines()[0][:80]})") from None
    if arr.dtype.kind == "O" and isinstance(value, (list, tuple)):
        # Python ints beyond int64 land here: convert them, or say they overflow float64
        try:
            arr = np.asarray(value, dtype=np.float64)
        except OverflowError:
            raise ProblemError(f"{label} holds an integer too large for a float") from None
        except (ValueError, TypeError) as exc:
            raise ProblemError(f"{label} is not a rectangular array of numbers "
                               f"({str(exc).splitlines()[0][:80]})") from None
    check_dtype(arr.dtype, label)
    with np.errstate(over="ignore"):  # float128 beyond float64 becomes inf: refused later
        return np.asarray(arr, dtype=np.float64)


def float64_array(x: Any) -> np.ndarray:
    """``x`` as a float64 ndarray: ``x`` itself when it already is one (no call into numpy:
    this is on the small-solve path), else a converted copy."""
    if type(x) is np.ndarray and x.dtype is _FLOAT64:  # native float64 (`==` costs 0.1 us)
        return x
    return np.asarray(x, dtype=np.float64)


_FLOAT64 = np.dtype(np.float64)


def binary_exponents(x: Any) -> np.ndarray:
    """The exponents ``e`` of ``x = m 2^e`` with ``0.5 <= |m| < 1`` (``np.frexp``), int64; 0
    where ``x`` is 0 (or not finite).  Power-of-two scalings are built from them (exact)."""
    return np.frexp(x)[1].astype(np.int64)


def unit_rows(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of ``a`` (finite) as unit vectors, and their lengths (a zero row stays zero,
    length 0).  Each row is divided by its largest component first (any positive divisor keeps
    the direction): (1e308, 1e308, 0) has a length that overflows (reported as inf), yet a
    direction."""
    peak = np.max(np.abs(a), axis=1) if a.size else np.zeros(a.shape[0])
    scale = np.where(peak > 0, peak, 1.0)
    unit = a / scale[:, None]
    rel = np.linalg.norm(unit, axis=1)  # in [1, sqrt(columns)], 0 for a zero row
    with np.errstate(over="ignore"):
        return unit / np.where(rel > 0, rel, 1.0)[:, None], peak * rel


def ldexp_exact(x: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``x 2^e`` in two steps, each exact: ``2^1074`` is not a double, while a subnormal times
    it is (one ``np.ldexp`` takes the exponent whole, and so does each step here)."""
    half = e // 2
    return np.ldexp(np.ldexp(x, half.astype(np.int32)), (e - half).astype(np.int32))


def json_text(obj: Any) -> str:
    """``obj`` as strict JSON text (no newline), every non-finite float written as ``null``
    (the output rule in the module docstring; the one encoder of every JSON that lcpcli
    writes).  Finite data costs one ``json.dumps``; only output holding Inf/NaN is walked.

    With orjson installed, it writes the text when it can (about 5x faster): compact
    separators and shortest round-trip floats (``1e-05`` as ``0.00001``), Inf/NaN as ``null``
    natively, so ``json.loads`` of either text gives the same value.  What orjson refuses or
    writes differently goes to ``json.dumps``: numpy scalars, non-string keys, integers beyond
    64 bits, lone surrogates, and any text that is not ASCII (``json.dumps`` escapes it, so the
    output stays ASCII on any terminal)."""
    codec = _orjson  # only when loaded (a batch worker): one row is not worth the import
    if codec is not None:
        try:
            text = codec.dumps(obj).decode("ascii")
        except (TypeError, ValueError):  # JSONEncodeError is a TypeError; decode a ValueError
            pass
        else:
            return text
    try:
        return json.dumps(obj, allow_nan=False)
    except ValueError:
        return json.dumps(finite_or_null(obj), allow_nan=False)


def finite_or_null(obj: Any) -> Any:
    """A copy of nested dicts/lists/tuples with every non-finite float replaced by None
    (iterative: deep output cannot exhaust the recursion limit)."""
    return _map_floats(obj, lambda x: x if math.isfinite(x) else None)


def without_negative_zero(obj: Any) -> Any:
    """A copy of nested dicts/lists/tuples with every ``-0.0`` written ``0.0`` (a trace's
    ``-1 * 0`` is no sign a reader should see)."""
    return _map_floats(obj, lambda x: x + 0.0 if x == 0 else x)


def _map_floats(obj: Any, change: Any) -> Any:
    """A copy of nested dicts/lists/tuples (lists) with ``change(x)`` for every float ``x``
    (iterative: deep output cannot exhaust the recursion limit)."""
    root: list[Any] = [obj]
    stack: list[tuple[Any, Any, Any]] = [(root, 0, obj)]
    while stack:
        parent, key, item = stack.pop()
        if isinstance(item, dict):
            copy: Any = dict(item)
            stack.extend((copy, k, v) for k, v in copy.items())
        elif isinstance(item, (list, tuple)):
            copy = list(item)
            stack.extend((copy, i, v) for i, v in enumerate(copy))
        elif isinstance(item, (float, np.floating)):
            copy = change(item)
        else:
            continue
        parent[key] = copy
    return root[0]
