"""The solver registry: every method is one module of :mod:`lcpcli.solvers.methods`.

A method module defines ``METHODS``, a list of :class:`Method` records; :func:`methods` and
:func:`get_method` find them.  Adding a method = adding one module there; nothing else changes.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from lcpcli.core.errors import OptionError

#: A method that densifies M is refused on a sparse problem with more entries than this
#: (``n * n``; 1e8 entries are 0.8 GB as float64).
MAX_DENSIFY_ENTRIES = 10_000 ** 2
#: Names of the methods whose ``prepare`` hook already ran in this process.
_PREPARED: set[str] = set()


@dataclass(frozen=True)
class Option:
    """A method-specific option: its type, default and one-line help."""

    type: Callable[[Any], Any]
    default: Any
    help: str


@dataclass(frozen=True)
class Method:
    """A registered solver method.

    ``run(problem, tol=..., **options) -> Outcome`` does the work; the caller
    (:func:`lcpcli.api.solve`) times it and certifies its answer.
    """

    name: str
    run: Callable[..., Any]
    summary: str
    matrix_classes: str
    kinds: tuple[str, ...] = ("lcp",)
    options: Mapping[str, Option] = field(default_factory=dict)
    default_tol: float = 1e-8
    prepare: Callable[[], None] | None = None
    aliases: tuple[str, ...] = ()
    #: True when the method works on a scipy.sparse M without densifying it.
    sparse: bool = False

    def prepare_once(self) -> None:
        """Run the ``prepare`` hook (kernel compilation or loading) once per process."""
        if self.prepare is not None and self.name not in _PREPARED:
            self.prepare()
            _PREPARED.add(self.name)

    def densifies(self, problem: Any) -> bool:
        """True when running this method on ``problem`` would densify a sparse M larger than
        :data:`MAX_DENSIFY_ENTRIES` (the caller refuses or skips it)."""
        return bool(problem.sparse and not self.sparse
                    and problem.n * problem.n > MAX_DENSIFY_ENTRIES)

    def parse_options(self, given: Mapping[str, Any]) -> dict[str, Any]:
        """Defaults merged with ``given``; unknown names or bad values raise OptionError."""
        out = {k: opt.default for k, opt in self.options.items()}
        for key, value in given.items():
            key_norm = key.replace("-", "_")
            if key_norm not in self.options:
                known = ", ".join(sorted(self.options)) or "none"
                raise OptionError(f"method '{self.name}' has no option '{key}' "
                                  f"(its options: {known})")
            if value is None:
                continue
            try:
                out[key_norm] = self.options[key_norm].type(value)
            except (TypeError, ValueError) as exc:
                raise OptionError(f"option '{key}' of method '{self.name}': {exc}") from None
        return out


_REGISTRY: dict[str, Method] | None = None
_ALIASES: dict[str, str] = {}


def _load() -> dict[str, Method]:
    global _REGISTRY
    if _REGISTRY is None:
        registry: dict[str, Method] = {}
        package = importlib.import_module("lcpcli.solvers.methods")
        for info in pkgutil.iter_modules(package.__path__):
            if info.name.startswith("_"):
                continue
            module = importlib.import_module(f"{package.__name__}.{info.name}")
            for method in getattr(module, "METHODS", ()):
                if method.name in registry:
                    raise RuntimeError(f"solver method {method.name!r} registered twice")
                registry[method.name] = method
                for alias in method.aliases:
                    _ALIASES[alias] = method.name
        _REGISTRY = dict(sorted(registry.items()))
    return _REGISTRY


def methods() -> dict[str, Method]:
    """All registered methods by name (sorted)."""
    return dict(_load())


def resolve(name: str) -> str | None:
    """The registered name of ``name`` (a name or an alias, any case), or None if unknown."""
    registry = _load()
    key = name.strip().lower()
    key = _ALIASES.get(key, key)
    return key if key in registry else None


def get_method(name: str) -> Method:
    """The method called ``name`` (or one of its aliases); OptionError if unknown."""
    key = resolve(name)
    if key is None:
        raise OptionError(f"unknown method '{name}' (available: {', '.join(_load())})")
    return _load()[key]
