"""The pivoting tolerances, defined once (kernel-free, so the teaching replicas can use
them without loading a compiled kernel).

Both are relative: a pivot is compared with the largest entry of its column, a ratio with the
smallest ratio.  Scale-invariance of the verdicts comes from equilibrating the problem first
(:mod:`lcpcli.solvers.pipeline`).
"""

from __future__ import annotations

#: Relative pivot tolerance: entries below this fraction of the column's largest are not pivots.
PIVOT_TOL = 1e-11
#: Relative tolerance under which two ratios are a tie (then the lexicographic rule decides).
TIE_TOL = 1e-9
#: A certified error at or below this is rounding level: such an answer is not polished further
#: (the batched Lemke kernel's re-solve of the end basis, the active-set polish's later rounds).
POLISHED = 1e-12
