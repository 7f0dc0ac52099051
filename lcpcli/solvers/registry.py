"""The solver registry: every method is one module of :mod:`lcpcli.solvers.methods`.

A method module defines ``METHODS``, a list of :class:`Method` records; :func:`methods` and
:func:`get_method` find them.  Adding a method = adding one module there; nothing else changes:
the record's declared data (:class:`Guarantee` per matrix class, :class:`Requirement` to start,
``max_n``, :class:`Cost`, ``preference``, ``fallback``) is what ``auto``'s policy
(:mod:`lcpcli.solvers.policy`), ``lcpcli info`` and the table of docs/methods.md are made of.
"""

from __future__ import annotations

import enum
import importlib
import os
import pkgutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

from lcpcli.analysis.classify import PROPERTIES
from lcpcli.core.errors import OptionError
from lcpcli.core.limits import DENSE_N_BUDGET, DENSE_N_ENV, dense_n_budget
from lcpcli.core.text import option_name
from lcpcli.solvers.memo import OPTION_DEFAULTS

#: A method that densifies M is refused on a sparse problem with more entries than this
#: (``n * n``; 1e8 entries are 0.8 GB as float64): the dense-work budget of
#: :mod:`lcpcli.core.limits`, which ``LCPCLI_MAX_DENSE_N`` overrides.
MAX_DENSIFY_ENTRIES = DENSE_N_BUDGET ** 2
#: Names of the methods whose ``prepare`` hook already ran in this process.
_PREPARED: set[str] = set()


@dataclass(frozen=True)
class Option:
    """A method-specific option: its type, default and one-line help."""

    type: Callable[[Any], Any]
    default: Any
    help: str


@dataclass(frozen=True)
class Condition:
    """All of ``props`` hold (names of :data:`lcpcli.analysis.classify.PROPERTIES`, i.e.
    boolean fields of the class report); the empty condition holds for any M."""

    props: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        unknown = [p for p in self.props if p not in PROPERTIES]
        if unknown:
            raise ValueError(f"unknown matrix properties {unknown} (known: {list(PROPERTIES)})")

    def evaluate(self, value: Callable[[str], bool | None]) -> bool | None:
        """Three-valued AND of ``value(prop)``: False as soon as one is False, None if one is
        undecided, else True."""
        out: bool | None = True
        for prop in self.props:
            v = value(prop)
            if v is False:
                return False
            if v is None:
                out = None
        return out

    def __str__(self) -> str:
        return ", ".join(PROPERTIES[p] for p in self.props) if self.props else "any M"


def when(*props: str) -> Condition:
    """``when("symmetric", "psd")``: the condition that M is symmetric and PSD."""
    return Condition(tuple(props))


@dataclass(frozen=True)
class Guarantee:
    """What a method achieves on the matrices satisfying ``when`` (e.g. ``when("p_matrix")``,
    "finite, unique solution").  ``kinds`` limits it to some problem kinds (default: all the
    method handles); ``slow`` marks a guarantee that holds but may take long (auto then tries
    the method after the methods with a plain guarantee)."""

    when: Condition
    claim: str
    kinds: tuple[str, ...] | None = None
    slow: bool = False

    def applies_to(self, kind: str) -> bool:
        return self.kinds is None or kind in self.kinds


@dataclass(frozen=True)
class Requirement:
    """A condition without which the method cannot start (``why`` says what goes wrong)."""

    when: Condition
    why: str


@dataclass(frozen=True)
class BatchSpec:
    """A method's batched kernel: its ``kernel`` name in every backend, the method ``options``
    it understands (any other option given means: solve one problem at a time), and the
    problem ``kinds`` it handles.  Kernels live in :mod:`lcpcli.solvers.batched`'s backends."""

    kernel: str
    options: tuple[str, ...] = ()
    kinds: tuple[str, ...] = ("lcp",)
    #: The registered method whose algorithm the kernel runs, when it is not the method that
    #: declares it (results name it).
    runs_as: str | None = None
    #: ``params(n, options) -> dict``: the kernel's parameters for problems of size n from the
    #: method options (parsed, or some missing), the method's defaults filled in; defined beside
    #: the method, so that no backend names a method (:func:`lcpcli.solvers.batched.
    #: kernel_params`).  Every record declaring one kernel gives the same function.
    params: Callable[[int, Mapping[str, Any]], dict[str, Any]] | None = None


class Cost(enum.Enum):
    """How a method's work grows: the policy orders methods by cost class per regime."""

    PIVOTING = "pivoting"      # finite pivoting on a dense matrix, O(n^2) per pivot
    FACTORING = "factoring"    # a few (dense or sparse) factorisations
    SWEEPING = "sweeping"      # many O(nnz) sweeps
    EXHAUSTIVE = "exhaustive"  # exponential in n (auto: last, small n only)


@dataclass(frozen=True)
class Method:
    """A registered solver method.

    ``run(problem, tol=..., **options) -> Outcome`` does the work, the method's one door: the
    dispatcher (:func:`lcpcli.solvers.pipeline.run_method`) calls it and certifies its
    answer.  The policy data:
    ``guarantees`` (per matrix class), ``needs`` (what it cannot start without), ``max_n``
    (the largest n it accepts), ``cost`` and ``preference`` (auto's order: lower first among
    methods of the same cost), ``fallback`` (why auto may try it outside its guarantees;
    None: never; ``fallback_preference`` orders that row), ``auto_max_iter`` (the
    iteration cap auto gives it when the user gave none, so that a fallback fails fast) and
    ``auto_max_n`` (the largest n auto tries it at; None: ``max_n``).
    ``planner`` marks ``auto`` itself.
    """

    name: str
    run: Callable[..., Any]
    summary: str
    kinds: tuple[str, ...] = ("lcp",)
    options: Mapping[str, Option] = field(default_factory=dict)
    default_tol: float = 1e-8
    prepare: Callable[[], None] | None = None
    #: ``preload(problem, options)``: the modules ``run`` imports for this problem and these
    #: parsed options (scipy.linalg for a dense factorisation, ...), imported by
    #: :func:`lcpcli.solvers.request.resolve` before the solve is timed, so that
    #: ``Result.seconds`` never counts an import; None: ``run`` imports nothing.
    preload: Callable[[Any, Mapping[str, Any]], None] | None = None
    aliases: tuple[str, ...] = ()
    #: True when the method works on a scipy.sparse M without densifying it.
    sparse: bool = False
    guarantees: tuple[Guarantee, ...] = ()
    needs: tuple[Requirement, ...] = ()
    max_n: int | None = None
    cost: Cost = Cost.FACTORING
    preference: int = 50
    fallback: str | None = None
    #: The preference of the fallback row (default: ``preference``).
    fallback_preference: int | None = None
    auto_max_iter: int | None = None
    auto_max_n: int | None = None
    #: Prose beyond the guarantees (shown after them in ``lcpcli methods``).
    notes: str = ""
    planner: bool = False
    #: How :mod:`lcpcli.solvers.pipeline` equilibrates the problem first: ``"auto"`` (``D M D``
    #: for a symmetric M, two-sided otherwise), ``"symmetric"`` (always ``D M D``) or ``"none"``.
    scaling: str = "none"
    #: True when ``run`` takes ``balance=`` (the thresholds :data:`lcpcli.analysis.scaling.BALANCE`)
    #: on a dense M: it then makes the equilibration's balance test inside its own compiled call
    #: and returns None, without solving, when the problem is not balanced (the dispatcher then
    #: equilibrates); otherwise the dispatcher calls :func:`~lcpcli.analysis.scaling.is_balanced`.
    balance_test: bool = False
    #: The batched kernel for stacks of problems (:class:`BatchSpec`),
    #: or None: :func:`lcpcli.solve_many` then solves the stack one problem at a time.
    batch: BatchSpec | None = None

    @property
    def matrix_classes(self) -> str:
        """The guarantees, requirements and limits in words (``lcpcli methods``, ``--help``)."""
        parts = [f"{g.when}: {g.claim}" + (f" ({'/'.join(k.upper() for k in g.kinds)})"
                                            if g.kinds else "") for g in self.guarantees]
        parts += [f"needs {r.when} ({r.why})" for r in self.needs]
        if self.max_n is not None:
            parts.append(f"n <= {self.max_n}")
        if self.notes:
            parts.append(self.notes)
        return "; ".join(parts) or "no guarantee"

    def prepare_once(self) -> None:
        """Run the ``prepare`` hook (kernel compilation or loading) once per process."""
        if self.prepare is not None and self.name not in _PREPARED:
            self.prepare()
            _PREPARED.add(self.name)

    def densifies(self, problem: Any) -> bool:
        """True when running this method on ``problem`` would densify a sparse M larger than
        :data:`MAX_DENSIFY_ENTRIES` (the caller refuses or skips it)."""
        if not problem.sparse or self.sparse:
            return False
        limit = dense_n_budget() ** 2 if DENSE_N_ENV in os.environ else MAX_DENSIFY_ENTRIES
        return problem.n * problem.n > limit

    def option_defaults(self) -> dict[str, Any]:
        """Each option's default, by name (memoised in :data:`lcpcli.solvers.memo.
        OPTION_DEFAULTS` for :meth:`parse_options`)."""
        return {k: opt.default for k, opt in self.options.items()}

    def parse_options(self, given: Mapping[str, Any]) -> dict[str, Any]:
        """Defaults merged with ``given``; unknown names or bad values raise OptionError."""
        defaults = OPTION_DEFAULTS.get(id(self))  # a frozen record cannot cache them itself
        if defaults is None or defaults[0] is not self:
            defaults = OPTION_DEFAULTS.put(id(self), (self, self.option_defaults()))
        out = dict(defaults[1])
        if not given:
            return out
        for key, value in given.items():
            key_norm = option_name(key)
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

    def given_options(self, parsed: Mapping[str, Any]) -> dict[str, Any]:
        """The options of ``parsed`` (:meth:`parse_options`' result) that are not their
        defaults: what the dispatcher passes to ``run``, whose keyword defaults are the options'
        defaults (``tests/solvers/test_memo.py`` checks it), so that a small solve binds no
        keyword it does not need."""
        options = self.options
        return {k: v for k, v in parsed.items() if v is not options[k].default}


_REGISTRY: dict[str, Method] | None = None
_ALIASES: dict[str, str] = {}
_VERSION = [0]


def version() -> tuple[int, int]:
    """Changes whenever the registry does (loading, :func:`register`, a replaced registry):
    a cache key for tables derived from it."""
    return (id(_REGISTRY if _REGISTRY is not None else _load()), _VERSION[0])


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


def register(method: Method) -> None:
    """Add ``method`` to the registry (e.g. from a plugin or a test); RuntimeError if its name
    or an alias is taken."""
    registry = _load()
    taken = {method.name, *method.aliases} & (set(registry) | set(_ALIASES))
    if taken:
        raise RuntimeError(f"solver method name(s) {sorted(taken)} registered twice")
    registry[method.name] = method
    for alias in method.aliases:
        _ALIASES[alias] = method.name
    ordered = sorted(registry.items())
    registry.clear()
    registry.update(ordered)
    _VERSION[0] += 1


def unregister(name: str) -> None:
    """Remove the method called ``name`` (and its aliases) from the registry; KeyError if it
    is not registered."""
    registry = _load()
    method = registry.pop(name)
    for alias in method.aliases:
        _ALIASES.pop(alias, None)
    _VERSION[0] += 1


def methods() -> Mapping[str, Method]:
    """All registered methods by name (sorted; a read-only view, no copy)."""
    return MappingProxyType(_load())


def resolve(name: str) -> str | None:
    """The registered name of ``name`` (a name or an alias, any case), or None if unknown."""
    registry = _load()
    key = name.strip().lower()
    key = _ALIASES.get(key, key)
    return key if key in registry else None


def get_method(name: str) -> Method:
    """The method called ``name`` (or one of its aliases); OptionError if unknown."""
    if _REGISTRY is not None:  # a registered name or alias as given: one lookup or two
        found = _REGISTRY.get(name) or _REGISTRY.get(_ALIASES.get(name, ""))
        if found is not None:
            return found
    key = resolve(name)
    if key is None:
        raise OptionError(f"unknown method '{name}' (available: {', '.join(_load())})")
    return _load()[key]
