"""Step-by-step replicas of the compiled methods, for teaching and debugging (``--trace``).

Each module is a pure-numpy copy of one compiled method: same data, same operations in the
same order, same tolerances, so it makes exactly the method's pivots (or sweeps) while
recording each one.  They import nothing from :mod:`lcpcli.solvers.kernels` (the tests compare
them with the kernels).

* :mod:`.lemke`: Lemke's complementary pivoting (``lemke-tableau``; ``lemke-revised`` has the
  same pivot rule), every pivot with its ratio test, tie-break and tableau;
* :mod:`.murty`: Murty's least-index principal pivoting (``murty``);
* :mod:`.dantzig`: Cottle-Dantzig principal pivoting (``dantzig``);
* :mod:`.pgs`: projected Gauss-Seidel / SOR sweeps (``pgs``, ``psor``);
* :mod:`.tableau`: the condensed tableau pivot and the two tableau layouts (dictionary
  ``w' = q' + M' z'`` and Murty's ``w - M z - d z0 = q``);
* :mod:`.path`: Lemke's rule applied to Dai & Drumwright's principal pivoting transform
  (``lcpcli pivot --driving``,
  ``--follow``).

A trace is a list of JSON-ready dicts; ``kind`` says which method wrote it (``lemke``,
``principal``, ``dantzig``, ``sweep``).  Names are 1-based (``w1``, ``z2``); the artificial
variable is ``z0`` (:data:`lcpcli.analysis.pivoting.ARTIFICIAL`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np


class Recorder:
    """A replica standing in for its kernel: returns the kernel's tuple, keeps the trace aside.

    ``Recorder(murty_traced)(*args)`` returns what ``murty_kernel(*args)`` returns (the
    replica's last item, the trace, is stored in :attr:`trace`; a second call replaces it).
    """

    def __init__(self, replica: Callable[..., tuple[Any, ...]]) -> None:
        self.replica = replica
        self.trace: list[dict[str, Any]] | None = None

    def __call__(self, *args: Any) -> tuple[Any, ...]:
        # floating-point exceptions as the compiled kernel has them: quiet (an intermediate
        # past the float64 range is inf or NaN, and the verdict is the certificate's)
        with np.errstate(all="ignore"):
            *out, self.trace = self.replica(*args)
        return tuple(out)
