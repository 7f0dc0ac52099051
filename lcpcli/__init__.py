"""lcpcli: linear complementarity problems from the shell and from Python.

Conventions used everywhere in the package:

* The LCP(q, M) asks for z with ``z >= 0``, ``w = M z + q >= 0`` and ``z^T w = 0``
  (q enters with a plus sign; ``w`` is the slack side).
* Indices are 0-based in the library; the CLI shows 1-based names (``w1``, ``z1``).
* An MLCP (Siconos form) has its first ``n_eq`` variables free with equality rows;
  a box LCP has bounds ``lower <= z <= upper`` with ``-w`` in the normal cone of the box.

The public API is loaded lazily so that ``import lcpcli`` (and ``lcpcli --help``)
stays cheap::

    import lcpcli
    p = lcpcli.load("samples/seed004.json")
    r = lcpcli.solve(p, method="lemke")
    r.status, r.z, r.error
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

__version__ = "0.1.0"

_LAZY = {
    "Problem": "lcpcli.core.problem",
    "Result": "lcpcli.core.result",
    "Certificate": "lcpcli.core.certificate",
    "certify": "lcpcli.core.certificate",
    "forward_error_bound": "lcpcli.analysis.bounds",
    "solve": "lcpcli.api",
    "solve_many": "lcpcli.stacks",
    "solve_each": "lcpcli.stacks",
    "StackResult": "lcpcli.core.result",
    "load": "lcpcli.io",
    "save": "lcpcli.io",
    "list_problems": "lcpcli.io",
    "ProblemError": "lcpcli.core.errors",
    "methods": "lcpcli.solvers.registry",
}

__all__ = ["__version__", *_LAZY]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'lcpcli' has no attribute {name!r}")
    value = getattr(import_module(module), name)
    globals()[name] = value  # later lookups skip this hook (lcpcli.solve in a loop: ~3 us each)
    return value
