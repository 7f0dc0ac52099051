"""What a solve returns: the raw :class:`Outcome` of a method and the certified :class:`Result`."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lcpcli.core.certificate import Certificate

SOLVED = "solved"
NO_SOLUTION = "no_solution"
UNSOLVED = "unsolved"
STATUSES = (SOLVED, NO_SOLUTION, UNSOLVED)

# Why a method stopped (``Outcome.termination``).
CONVERGED = "converged"
RAY = "ray_termination"
ITERATION_LIMIT = "iteration_limit"
SINGULAR = "singular_basis"
INFEASIBLE = "infeasible"  # proven: the method's theory shows no solution exists
NUMERICAL = "numerical_failure"


@dataclass
class Outcome:
    """What a solver method hands back before certification.

    ``proven_infeasible`` may be set only when the method's theory proves that no solution
    exists (e.g. Lemke's secondary ray on a copositive-plus matrix); ``message`` says how.
    """

    z: np.ndarray
    iterations: int
    termination: str
    message: str = ""
    proven_infeasible: bool = False
    trace: list[dict[str, Any]] | None = None
    info: dict[str, Any] = field(default_factory=dict)


@dataclass
class Result:
    """A certified solve: the verdict, the solution and its certificate.

    ``status`` is ``solved`` (certificate passed), ``no_solution`` (proven, see ``message``) or
    ``unsolved`` (the method gave up or its answer failed the certificate; ``message`` says why).
    ``seconds`` is the method's own wall time (no process start-up, no file reading).
    """

    status: str
    method: str
    z: np.ndarray
    w: np.ndarray
    iterations: int
    seconds: float
    certificate: Certificate
    message: str
    termination: str
    problem_name: str = ""
    trace: list[dict[str, Any]] | None = None
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def solved(self) -> bool:
        return self.status == SOLVED

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
        if self.trace is not None:
            out["trace"] = self.trace
        return out

    def __repr__(self) -> str:
        """One short line (z and w are in ``str()`` and ``to_dict()``, not here)."""
        return (f"Result(status={self.status!r}, method={self.method!r}, n={self.n}, "
                f"error={float(self.certificate.error):.3g}, iterations={self.iterations})")

    def __str__(self) -> str:
        """A few lines: verdict, message, certificate and the head of z and w."""
        head = 6
        with np.printoptions(precision=6, threshold=2 * head, edgeitems=head // 2):
            z, w = np.array2string(self.z), np.array2string(self.w)
        return "\n".join([
            f"{self.status} by {self.method} ({self.termination}), n = {self.n}, "
            f"{self.iterations} iterations, {self.seconds * 1e3:.3f} ms",
            f"  message:  {self.message}",
            f"  residual: {float(self.certificate.residual):.3e}   "
            f"error: {float(self.certificate.error):.3e} (tol {float(self.certificate.tol):.1e})",
            f"  z = {z}",
            f"  w = {w}"])


def _float(x: float) -> float | None:
    """JSON has no inf/nan: map them to None."""
    x = float(x)
    return x if np.isfinite(x) else None


def _floats(v: np.ndarray) -> list[float | None]:
    return [_float(x) for x in np.asarray(v, dtype=float)]
