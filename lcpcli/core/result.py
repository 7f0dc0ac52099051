"""What a solve returns: the raw :class:`Outcome` of a method and the certified :class:`Result`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from enum import Enum
from functools import partial
from typing import Any

import numpy as np

from lcpcli.core.certificate import BETWEEN, Certificate, check, scored
from lcpcli.core.numeric import without_negative_zero
from lcpcli.core.text import plural


class _StrEnum(str, Enum):
    """A str-valued enum: equal to, hashed, formatted and JSON-encoded as its value, so that
    ``status == "solved"``, ``f"{status}"`` and ``json.dumps(status)`` read as the plain string."""

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, spec: str) -> str:
        return format(str(self.value), spec)


class Status(_StrEnum):
    """The verdict of a solve (:attr:`Result.status`), and the status of a batch/bench row."""

    SOLVED = "solved"            # the certificate passed
    NO_SOLUTION = "no_solution"  # proven: a checked Farkas vector (``info["farkas_y"]``)
    UNSOLVED = "unsolved"        # the method gave up or its answer failed the certificate
    ERROR = "error"              # batch/bench rows only: no verdict (unreadable input, a crash)
    TIMEOUT = "timeout"          # bench rows only: the isolated run was killed at its limit


class Termination(_StrEnum):
    """Why a method stopped (:attr:`Outcome.termination`)."""

    CONVERGED = "converged"
    RAY = "ray_termination"
    ITERATION_LIMIT = "iteration_limit"
    SINGULAR = "singular_basis"
    INFEASIBLE = "infeasible"  # proven: the method's theory shows no solution exists
    NUMERICAL = "numerical_failure"
    STALLED = "stalled"  # an iterative method made no progress in its merit over a window
    NOT_APPLICABLE = "not_applicable"  # the method cannot start on this M (e.g. zero diagonal)
    TIMEOUT = "timeout"  # batch rows: stopped by --timeout
    ERROR = "error"  # batch rows of inputs that could not be read or solved at all


SOLVED = Status.SOLVED
NO_SOLUTION = Status.NO_SOLUTION
UNSOLVED = Status.UNSOLVED
#: The three verdicts a solve can return.
STATUSES = (SOLVED, NO_SOLUTION, UNSOLVED)

#: The integer code of each status in stacked results (``StackResult.status``, the ``status``
#: dataset of a stacked result file); -1 in a result file: not solved yet.
STATUS_CODES: dict[Status, int] = {Status.SOLVED: 0, Status.UNSOLVED: 1,
                                   Status.NO_SOLUTION: 2, Status.ERROR: 3}
#: Code -> status (the inverse of :data:`STATUS_CODES`).
STATUS_OF_CODE: dict[int, Status] = {v: k for k, v in STATUS_CODES.items()}
#: The code of a problem not solved yet (result files written chunk by chunk).
NOT_DONE = -1

CONVERGED = Termination.CONVERGED
RAY = Termination.RAY
ITERATION_LIMIT = Termination.ITERATION_LIMIT
SINGULAR = Termination.SINGULAR
INFEASIBLE = Termination.INFEASIBLE
NUMERICAL = Termination.NUMERICAL
STALLED = Termination.STALLED
NOT_APPLICABLE = Termination.NOT_APPLICABLE


class LazyInfo(partial):
    """An ``info`` dict not built yet: the call that builds it (a :func:`functools.partial`
    whose arguments are values fixed when it was made, never the problem's mutable arrays).

    ``auto`` hands its ``info`` on so when its first attempt solved (on a 4 us solve at
    n = 10, building the attempt record and the class report up front cost about a tenth of
    the call, and most callers never read them).  :meth:`Outcome.details` builds it;
    :meth:`Result.certified` hands it on unbuilt to a :class:`LazyResult`, whose ``info``
    builds it on first read, once: every reader of ``Result.info`` gets a plain ``dict``, the
    one the same call gives at any time."""

    __slots__ = ()


@dataclass(slots=True)
class Outcome:
    """What a solver method hands back before certification.

    ``proven_infeasible`` is a method's claim that no solution exists, with its Farkas vector in
    ``info["farkas_y"]`` when it has one; the verdict is ``no_solution`` only when a vector
    passes :func:`lcpcli.analysis.proof.check_farkas` on the user's data (see ``confirm``).
    ``checked`` is ``(certificate, w)`` when the method already certified ``z`` itself (``auto``
    does, to decide whether to fall back): the caller reuses it instead of checking twice.
    ``info`` is a dict, or (``auto``'s first attempt that solved) a :class:`LazyInfo` not built
    yet: code that reads or changes it reads :meth:`details`.
    """

    z: np.ndarray
    iterations: int
    termination: Termination
    message: str = ""
    proven_infeasible: bool = False
    trace: list[dict[str, Any]] | None = None
    info: dict[str, Any] = field(default_factory=dict)
    checked: tuple[Certificate, np.ndarray] | None = None
    #: Seconds the run spent importing modules it could not know it needed before it started
    #: (a planner's fallback: ``auto`` loads scipy.linalg only when its first attempt fails);
    #: :func:`lcpcli.api.certify_outcome` leaves them out of ``Result.seconds``.
    import_seconds: float = 0.0

    @classmethod
    def converged(cls, z: np.ndarray, iterations: int, message: str,
                  info: dict[str, Any] | None = None,
                  checked: tuple[Certificate, np.ndarray] | None = None,
                  import_seconds: float = 0.0) -> Outcome:
        """A run that says it converged (no claim of infeasibility, no trace); the small-solve
        paths build it here, positionally, without binding keywords."""
        return cls(z, iterations, CONVERGED, message, False, None, {} if info is None else info,
                   checked, import_seconds)

    def details(self) -> dict[str, Any]:
        """``info`` as a dict (a :class:`LazyInfo` is built now, and kept)."""
        info = self.info
        if type(info) is LazyInfo:
            info = self.info = info()
        return info


@dataclass(slots=True)
class Result:
    """A certified solve: the verdict, the solution and its certificate.

    ``status`` is ``solved`` (certificate passed), ``no_solution`` (proven, see ``message``) or
    ``unsolved`` (the method gave up or its answer failed the certificate; ``message`` says why).
    ``seconds`` is the method's own wall time (no process start-up, no file reading).
    ``info`` is a dict of the method's details (``auto``'s, when its first attempt solved, is
    built on first read: the Result is then a :class:`LazyResult`).
    """

    status: Status
    method: str
    z: np.ndarray
    w: np.ndarray
    iterations: int
    seconds: float
    certificate: Certificate
    message: str
    termination: Termination
    problem_name: str = ""
    trace: list[dict[str, Any]] | None = None
    info: dict[str, Any] = field(default_factory=dict)
    #: The final basis once known (see :attr:`basis`).
    known_basis: np.ndarray | None = field(default=None, repr=False)
    #: The factors of the final basis block kept by a warm-started solve (an object of
    #: :mod:`lcpcli.solvers.methods.bpp`): the next warm start on the same M reuses them.
    factors: Any = field(default=None, repr=False, compare=False)
    #: The problem, until :attr:`basis` is first asked for (then dropped).
    basis_source: Any = field(default=None, repr=False, compare=False)

    @classmethod
    def certified(cls, status: Status, method: str, z: np.ndarray, w: np.ndarray,
                  outcome: Outcome, seconds: float, certificate: Certificate, message: str,
                  problem: Any, known_basis: np.ndarray | None = None) -> Result:
        """The Result of ``outcome`` certified on ``problem`` (what
        :func:`lcpcli.api.certify_outcome` builds); without ``known_basis`` the basis is
        computed from ``problem`` on first use."""
        info = outcome.info
        lazy = type(info) is LazyInfo
        source = None if known_basis is not None else problem
        if known_basis is not None:  # None when no pair was scored: no basis, none to compute
            known_basis = scored(known_basis)
        res = cls(status, method, z, w, outcome.iterations, seconds, certificate, message,
                  outcome.termination, problem.name, outcome.trace,
                  info if lazy else dict(info), known_basis, None, source)
        if lazy:  # not built yet: the Result builds it on first read (the same layout, so
            # every other Result keeps a plain slot and one type on the small path)
            res.__class__ = LazyResult
        return res

    @property
    def basis(self) -> np.ndarray | None:
        """The final basis: each pair's state as the certificate scores ``z`` (int8 codes of
        :mod:`lcpcli.core.certificate`: 0 ``z_i`` at its lower bound and ``w_i`` basic, 1 at
        its upper bound, 2 ``z_i`` basic with ``w_i = 0``); see :mod:`lcpcli.solvers.warm`.
        Computed on first use (one certificate pass), so that solves that never ask pay
        nothing; None when the Result has neither, or when ``z`` or ``w`` is not finite (no
        pair has a state)."""
        if self.known_basis is None and self.basis_source is not None:
            states = np.empty(self.n, dtype=np.int8)
            check(self.basis_source, self.z, self.certificate.tol, state=states)
            self.known_basis, self.basis_source = scored(states), None
        return self.known_basis

    def __getstate__(self) -> list[Any]:
        """Pickled (process pools) with its basis computed and without the problem or the
        factors (which hold the matrix and closures)."""
        self.basis  # noqa: B018
        return [getattr(self, f.name) if f.name not in ("factors", "basis_source") else None
                for f in fields(self)]

    def __setstate__(self, state: list[Any]) -> None:
        for f, value in zip(fields(self), state, strict=True):
            object.__setattr__(self, f.name, value)

    @property
    def solved(self) -> bool:
        return self.status == SOLVED

    @property
    def z_basic(self) -> np.ndarray | None:
        """Booleans: ``z_i`` basic (``w_i = 0``) in the final basis; None without one."""
        return None if self.basis is None else self.basis == BETWEEN

    @property
    def residual(self) -> float:
        return self.certificate.residual

    @property
    def error(self) -> float:
        return self.certificate.error

    @property
    def n(self) -> int:
        return int(self.z.shape[0])

    def to_dict(self, file: str | None = None) -> dict[str, Any]:
        """The JSON schema of ``lcpcli solve --json`` (plus ``certificate`` details)."""
        out: dict[str, Any] = {
            "file": file,
            "status": self.status,
            "method": self.method,
            "n": self.n,
            "z": _floats(self.z),
            "w": _floats(self.w),
            "iterations": int(self.iterations),
            "seconds": float(self.seconds),
            "residual": _float(self.certificate.residual),
            "error": _float(self.certificate.error),
            "message": self.message,
            "problem": self.problem_name,
            "termination": self.termination,
            "certificate": {k: _float(v) if isinstance(v, float) else v
                            for k, v in self.certificate.as_dict().items()},
        }
        out["basis"] = None if self.basis is None else basis_text(self.basis)
        if self.trace is not None:
            out["trace"] = without_negative_zero(self.trace)
        return out

    def __repr__(self) -> str:
        """One short line (z and w are in ``str()`` and ``to_dict()``, not here)."""
        return (f"Result(status={str(self.status)!r}, method={self.method!r}, n={self.n}, "
                f"error={float(self.certificate.error):.3g}, iterations={self.iterations})")

    def __str__(self) -> str:
        """A few lines: verdict, message, certificate and the head of z and w."""
        head = 6
        with np.printoptions(precision=6, threshold=2 * head, edgeitems=head // 2):
            z, w = np.array2string(self.z), np.array2string(self.w)
        return "\n".join([
            f"{self.status} by {self.method} ({self.termination}), n = {self.n}, "
            f"{plural(self.iterations, 'iteration')}, {self.seconds * 1e3:.3f} ms",
            f"  message:  {self.message}",
            f"  residual: {float(self.certificate.residual):.3e}   "
            f"error: {float(self.certificate.error):.3e} (tol {float(self.certificate.tol):.1e})",
            f"  z = {z}",
            f"  w = {w}"])


class LazyResult(Result):
    """A :class:`Result` whose ``info`` slot may hold a :class:`LazyInfo`: the ``info``
    property builds it on first read and keeps the dict (:meth:`Result.certified` makes one
    from an Outcome whose info was not built)."""

    __slots__ = ()

    @property  # type: ignore[override]
    def info(self) -> dict[str, Any]:
        info = _RESULT_INFO.__get__(self, Result)
        if type(info) is LazyInfo:
            info = info()
            _RESULT_INFO.__set__(self, info)
        return info

    @info.setter
    def info(self, value: dict[str, Any]) -> None:
        _RESULT_INFO.__set__(self, value)


#: ``Result``'s ``info`` slot (its member descriptor), which :class:`LazyResult` reads as it is.
_RESULT_INFO = Result.__dict__["info"]


#: The letter of each basis state code in ``--json`` (``"basis"``): ``L`` z_i at its lower
#: bound (LCP: z_i = 0, w_i basic), ``U`` at its upper bound, ``F`` z_i basic (w_i = 0).
BASIS_LETTERS = "LUF"


#: Byte -> letter of the codes 0, 1, 2 of a one-byte basis array; "?" for every other byte.
_BASIS_BYTES = bytes(ord(BASIS_LETTERS[b]) if b < len(BASIS_LETTERS) else ord("?")
                     for b in range(256))


def basis_text(codes: np.ndarray) -> str:
    """A basis as one letter per pair (:data:`BASIS_LETTERS`), e.g. ``"FLLF"``.  A one-byte
    array of valid codes (the usual int8 basis) goes through ``bytes.translate`` (a third of
    the time of numpy's indexing on a row)."""
    if type(codes) is np.ndarray and codes.dtype.itemsize == 1 and codes.dtype.kind in "iu":
        text = codes.tobytes().translate(_BASIS_BYTES)
        if b"?" not in text:
            return text.decode("ascii")
    return np.frombuffer(BASIS_LETTERS.encode(), dtype=np.uint8)[np.asarray(codes, dtype=np.intp)] \
        .tobytes().decode("ascii")


def _float(x: float) -> float | None:
    """JSON has no inf/nan: map them to None (``math.isfinite``: 20x numpy's on a scalar)."""
    x = float(x)
    return x if math.isfinite(x) else None


def _floats(v: np.ndarray) -> list[float | None]:
    """``v`` as a list of floats, inf/nan as None.  All are finite when their sum is (an inf
    or a NaN makes it inf or NaN; a sum that overflows only sends finite values through the
    check one by one): one C loop, a quarter of numpy's ``isfinite(a).all()`` on a row."""
    out = np.asarray(v, dtype=np.float64).ravel().tolist()
    if not math.isfinite(sum(out)):
        out = [x if math.isfinite(x) else None for x in out]
    return out


@dataclass
class StackResult:
    """The certified results of a stack of K problems of size n (:func:`lcpcli.solve_many`).

    Arrays, indexed by the 0-based problem index k: ``z`` and ``w = M z + q`` (K, n),
    ``status`` (K,) int8 codes of :data:`STATUS_CODES` (``solved`` only when the certificate
    passed, ``no_solution`` only with a proof, as :func:`lcpcli.solve`), ``iterations`` (K,)
    (pivots or sweeps), ``error`` (K,) the certified error (inf where none could be computed,
    e.g. for an ``error`` row), ``residual`` (K,) ``||mid(z - l, z - u, w)||_inf``.
    ``method`` is the method that ran on the stack (``auto``: the one its sample chose;
    ``batched`` False: no batched kernel applied and every problem was solved on its own);
    ``retried`` marks the problems the batched kernel handed to the full one-problem
    pipeline, whose ``messages`` and ``methods`` (k -> text) say what happened; ``seconds``
    is wall time.
    """

    z: np.ndarray
    w: np.ndarray
    status: np.ndarray
    iterations: np.ndarray
    error: np.ndarray
    residual: np.ndarray
    method: str
    tol: float
    seconds: float = 0.0
    retried: np.ndarray | None = None
    messages: dict[int, str] = field(default_factory=dict)
    methods: dict[int, str] = field(default_factory=dict)
    batched: bool = True
    #: The :class:`Result` of each problem solved on its own (retried, or no batched kernel).
    results: dict[int, Result] = field(default_factory=dict)
    #: (K, n) int8: each solved problem's final basis (codes of :data:`BASIS_LETTERS`), for a
    #: warm-started next stack (``solve_many(..., warm=this)``); None when not recorded.
    basis: np.ndarray | None = None
    #: (K,) bool: the problems a warm start answered (:mod:`lcpcli.solvers.warm_stack`, by
    #: block principal pivoting from the previous basis); None without a warm start.
    warmed: np.ndarray | None = None
    #: (K, 9) float64: each kernel-certified answer's whole certificate, one row each
    #: (:func:`lcpcli.core.certificate.from_row`; NaN rows: not certified by the kernel, e.g.
    #: the ``results`` solved on their own), when ``solve_many(certificates=True)`` ran a
    #: CPU kernel that records them; None otherwise.
    certificates: np.ndarray | None = None
    #: (K, n) int8: each kernel-certified answer's complementary basis from the pivoting (1: z_i
    #: basic, 0: w_i basic; -1 rows: none recorded), when ``solve_many(pivot_basis=True)`` ran
    #: Lemke's CPU kernel; None otherwise.  It differs from :attr:`basis` (the certificate's
    #: pair states) on degenerate pairs (``z_i = w_i = 0``), where it says which of the two the
    #: pivoting kept basic: the better start for the next step (contact LCPs).
    pivot_basis: np.ndarray | None = None

    def method_of(self, k: int) -> str:
        """The method that produced problem k's answer."""
        if self.warmed is not None and self.warmed[k] and k not in self.methods:
            return "bpp"
        return self.methods.get(k, self.method)

    def __len__(self) -> int:
        return int(self.status.shape[0])

    @property
    def solved(self) -> np.ndarray:
        """Boolean mask of the certified answers."""
        return self.status == STATUS_CODES[Status.SOLVED]

    def statuses(self) -> list[Status]:
        """The status of every problem, as :class:`Status` values."""
        return [STATUS_OF_CODE[int(c)] for c in self.status.tolist()]

    def counts(self) -> dict[str, int]:
        """How many problems have each status (only the statuses that occur)."""
        return status_counts(self.status)

    def message(self, k: int) -> str:
        """Problem k's message (the kernel's summary unless it was retried)."""
        if k in self.messages:
            return self.messages[k]
        if self.status[k] == STATUS_CODES[Status.SOLVED]:
            return f"{self.method} (batched): certified error {float(self.error[k]):.2e}"
        return f"{self.method} (batched): not certified"

    def __repr__(self) -> str:
        n = self.z.shape[1] if self.z.ndim == 2 else 0
        return (f"StackResult(K={len(self)}, n={n}, method={self.method!r}, "
                f"counts={self.counts()}, seconds={self.seconds:.3g})")


def status_counts(codes: np.ndarray) -> dict[str, int]:
    """How many entries of an array of :data:`STATUS_CODES` have each status (the statuses
    that occur; :data:`NOT_DONE` entries are not counted)."""
    found, numbers = np.unique(codes[codes != NOT_DONE], return_counts=True)
    return {str(STATUS_OF_CODE[int(c)]): int(k) for c, k in zip(found, numbers, strict=True)}
