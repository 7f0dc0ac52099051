"""The pivoting tolerances, defined once (kernel-free and numpy-free, so the teaching replicas
and the analysis can use them without loading a compiled kernel).

All are relative: a method's pivot is compared with the largest entry of its column (or row), a
ratio with the smallest ratio, a P-matrix test's pivot with the terms it was computed from.
Scale-invariance of the methods' verdicts comes from equilibrating the problem first
(:mod:`lcpcli.solvers.pipeline`); the matrix-class tests are scale-free by construction
(:mod:`lcpcli.analysis.classify`).
"""

from __future__ import annotations

#: Relative pivot tolerance of the pivoting methods (Lemke, Murty, the ``pivot`` command's ratio
#: test): entries below this fraction of the largest of their column (Lemke) or row (Murty) are
#: not pivots.
PIVOT_TOL = 1e-11
#: Relative tolerance under which two ratios are a tie (then the lexicographic rule decides).
TIE_TOL = 1e-9
#: A certified error at or below this is rounding level: such an answer is not polished further
#: (the batched Lemke kernel's re-solve of the end basis, the active-set polish's later rounds).
POLISHED = 1e-12
#: Entries of z at or below this fraction of ``||z||_inf`` are at rounding level: degenerate
#: basic values that a tableau leaves exactly 0 (a row made only of such terms reads
#: ``w_i / s_i ~ 1``); the warm starts, the batched Lemke kernel and the active-set polish
#: (:func:`lcpcli.solvers.support.refine`) also try an answer with them set to 0, and the
#: certificate decides.
TINY_Z = 1e-14
#: Relative pivot tolerance of the P-matrix tests (:mod:`lcpcli.analysis.classify`): a pivot
#: ``det(K_{I+j}) / det(K_I)`` of the depth-first principal-minor search, or a 2 x 2 minor
#: ``1 - k_ij k_ji`` of the unit-diagonal scaling K, counts as positive when it exceeds this
#: fraction of the magnitude of the terms it was computed from.  A minor it cannot show
#: positive is a candidate that the exact (rational) check refutes or not; M is never declared
#: "not P" on this threshold alone.
P_TEST_PIVOT_TOL = 1e-12
