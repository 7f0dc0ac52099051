"""Plain coercion of simple command-line values, so that a command line imports no pydantic.

typer >= 0.2x coerces every non-bool parameter through a pydantic ``TypeAdapter``, built on
first use: ``lcpcli solve FILE`` then imports pydantic and pydantic_core (about 60 ms and
200 modules, more at interpreter shutdown) to turn a string into a string.  :func:`install`
gives typer's parameters a cheaper coercion for the annotations this CLI uses (``str``,
``bool``, ``int``, ``float``, ``pathlib.Path``, ``list[str]``) and keeps typer's own for
everything else: any other annotation, a ``parser``, a clamped range, and any value the plain
conversion does not accept or that is outside a ``min``/``max`` range (so error messages stay
typer's, built by pydantic only then).

typer releases without ``typer._coercion`` (click does the coercion, no pydantic) are left
alone.  The start-up budget is checked by ``tests/cli/test_startup.py``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import typer.core

_INT = re.compile(r"[+-]?\d+\Z")
_FLOAT = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\Z")


def _plain(annotation: Any, info: Any, value: Any) -> tuple[bool, Any]:
    """(True, converted) when ``value`` converts plainly, else (False, None)."""
    if annotation is str:
        return (True, value) if isinstance(value, str) else (False, None)
    if annotation is bool:
        return (True, value) if isinstance(value, bool) else (False, None)
    if annotation in (int, float):
        if isinstance(value, str) and (_INT if annotation is int else _FLOAT).match(
                value.strip()):
            out = annotation(value)
            lo, hi = getattr(info, "min", None), getattr(info, "max", None)
            if (lo is None or out >= lo) and (hi is None or out <= hi):
                return True, out
        return False, None
    if annotation is Path:
        if isinstance(value, str):
            from typer._param_types import coerce_cli_path

            # typer's own checks (exists, file_okay, ...) on a Path: no pydantic needed
            return True, coerce_cli_path(Path(value), info, path_type=Path)
        return False, None
    if getattr(annotation, "__origin__", None) is list and annotation.__args__ == (str,):
        if isinstance(value, (list, tuple)) and all(isinstance(v, str) for v in value):
            return True, list(value)
        return False, None
    return False, None


def _simple(descriptor: Any) -> bool:
    """Whether the plain coercion applies to this parameter at all."""
    info = descriptor.parameter_info
    if descriptor.file_annotation is not None or getattr(info, "parser", None) is not None:
        return False
    if getattr(info, "clamp", False):
        return False
    ann = descriptor.annotation
    return ann in (str, bool, int, float, Path) or (
        getattr(ann, "__origin__", None) is list and getattr(ann, "__args__", ()) == (str,))


def install() -> None:
    """Make typer's parameters try the plain coercion first (idempotent; no-op if the typer
    release has no pydantic-based coercion)."""
    try:
        from typer import _coercion
    except ImportError:
        return
    _TyperParameter = getattr(typer.core, "_TyperParameter", None)
    if _TyperParameter is None:
        return
    if getattr(_TyperParameter, "_lcpcli_plain", False) or not hasattr(
            _TyperParameter, "get_runtime_param"):
        return
    original = _TyperParameter.get_runtime_param

    @dataclass(frozen=True)
    class PlainRuntimeParam(_coercion.RuntimeParam):
        """Plain conversion; typer's pydantic coercion only for values it does not take."""

        descriptor: Any

        def _coerce_value(self, value: Any, param: Any, ctx: Any) -> Any:
            ok, out = _plain(self.annotation, self.parameter_info, value)
            if ok:
                return out
            return _coercion.build_runtime_param(self.descriptor)._coerce_value(
                value, param=param, ctx=ctx)

    def get_runtime_param(self: Any) -> Any:
        if self._runtime_param is None:
            desc = self.type_descriptor
            if _simple(desc):
                self._runtime_param = PlainRuntimeParam(
                    parameter_info=desc.parameter_info, annotation=desc.annotation,
                    descriptor=desc)
            else:
                return original(self)
        return self._runtime_param

    _TyperParameter.get_runtime_param = get_runtime_param
    _TyperParameter._lcpcli_plain = True
