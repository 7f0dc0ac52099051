"""Limits on what a user may ask for, defined once (numpy-free: the CLI checks them at start).

Work budgets (stated for users in docs/files.md, "Work budgets"): a step whose cost grows as
``n^2`` memory, ``n^3`` operations or ``2^n`` cones is checked from the sizes alone, before it
starts, so that a small file that declares a large problem cannot run for hours:

* **dense work** -- a dense copy of M (``n^2 * 8`` bytes: 0.75 GiB at n = 10,000), a dense
  factorisation or dense pivoting (about ``n^3`` = 1e12 operations at n = 10,000) -- runs up
  to n = :data:`DENSE_N_BUDGET`; above it the step is refused (one line, exit 2) unless
  ``LCPCLI_MAX_DENSE_N`` (:data:`DENSE_N_ENV`) raises the budget;
* **sparse factorisation** -- a sparse LU factorisation of M (SuperLU, in ``ip``, ``newton``,
  ``newton-min`` and ``auto``), whose workspace is about :data:`SPARSE_LU_ROW_BYTES` per row
  before any fill-in, whatever the number of nonzeros -- runs up to n =
  :data:`SPARSE_N_BUDGET` (0.75 GiB of workspace); above it the method is refused (one line,
  exit 2) unless ``LCPCLI_MAX_SPARSE_N`` (:data:`SPARSE_N_ENV`) raises the budget (a sparse
  NPZ of 1 MB declaring n = 5e7 made SuperLU fail with "gstrf was called with invalid
  arguments" after 69 s and 8 GB);
* **enumeration** of the ``2^n`` complementary cones is refused above ``--max-n`` (default
  24, :mod:`lcpcli.analysis.enumeration`) and announced on stderr (one ``lcpcli: note:``
  line, :func:`announce`) from n = :data:`ENUM_ANNOUNCE_N` (about a million cones) on.

The checks cost a comparison of integers: the normal paths do no extra pass over any data.
"""

from __future__ import annotations

import os
import warnings

from lcpcli.core.errors import OptionError, ProblemError

#: The largest iteration or pivot limit accepted (the kernels count in 32-bit signed integers
#: in places; a larger limit means "never stop" anyway).
MAX_ITER = 2**31 - 1

#: Largest n for dense work (a dense copy of M, dense factorisation or pivoting) by default.
DENSE_N_BUDGET = 10_000
#: The environment variable that overrides :data:`DENSE_N_BUDGET` (an integer >= DENSE_N_FLOOR).
DENSE_N_ENV = "LCPCLI_MAX_DENSE_N"
#: Dense work is never refused up to this n (the checks start above it: one comparison on the
#: small-solve path, no look at the environment).
DENSE_N_FLOOR = 100
#: Largest n for a sparse LU factorisation of M by default.
SPARSE_N_BUDGET = 2_000_000
#: The environment variable that overrides :data:`SPARSE_N_BUDGET` (an integer >= SPARSE_N_FLOOR).
SPARSE_N_ENV = "LCPCLI_MAX_SPARSE_N"
#: A sparse factorisation is never refused up to this n.
SPARSE_N_FLOOR = 10_000
#: SuperLU's workspace per row of the factorised matrix, before any fill-in (measured with
#: scipy 1.17: 467 MB at n = 1e6, 1.69 GB at 4e6, 4.1 GB at 1e7 for a diagonal M).
SPARSE_LU_ROW_BYTES = 400
#: A warm start read for a problem of n unknowns holds n values; one that names its unknowns
#: (matched by name: ``contact-matrix --z0`` of the previous step's impulses, whose contacts may
#: be gone) up to WARM_START_NAMED_FACTOR * n + WARM_START_SLACK.  Checked from the NPZ/NPY
#: header, before anything is decompressed (:func:`warm_start_entries`).
WARM_START_NAMED_FACTOR = 4
WARM_START_SLACK = 1024
#: From this n on, an enumeration of the 2^n complementary cones is announced before it starts.
ENUM_ANNOUNCE_N = 20


class CostNote(UserWarning):
    """An expensive step is starting (announced on stderr as ``lcpcli: note:``, not refused)."""

    #: How the CLI labels it (:func:`lcpcli.core.text.show_warning`).
    label = "note"


def announce(text: str) -> None:
    """Announce the cost of a step about to start (one line on stderr in the CLI; a
    :class:`CostNote` warning for library callers, who may filter it).  Every call is shown
    (no "once per location" registry: each expensive step is announced)."""
    warnings.warn_explicit(text, CostNote, "lcpcli", 0, module="lcpcli")


def power_of_two(n: int) -> str:
    """``"2^20 = 1,048,576"``; from 2^64 on the exponent alone (2^30000 has 9,000 digits, more
    than Python converts to text by default)."""
    return f"2^{n} = {2 ** n:,}" if n < 64 else f"2^{n:,}"


def _budget(env: str, default: int, floor: int, work: str) -> int:
    """The budget ``$env`` if set (an integer >= ``floor``, else OptionError), else ``default``."""
    raw = os.environ.get(env)
    if raw is None or not raw.strip():
        return default
    try:
        value = int(raw.strip().replace("_", ""))
    except ValueError:
        value = 0
    if value < floor:
        raise OptionError(f"{env}={raw[:40]!r} must be an integer >= {floor} (the largest n "
                          f"for {work})")
    return value


def dense_n_budget() -> int:
    """The largest n for dense work: ``$LCPCLI_MAX_DENSE_N`` if set, else DENSE_N_BUDGET."""
    return _budget(DENSE_N_ENV, DENSE_N_BUDGET, DENSE_N_FLOOR, "dense work")


def sparse_n_budget() -> int:
    """The largest n for a sparse factorisation: ``$LCPCLI_MAX_SPARSE_N`` if set, else
    SPARSE_N_BUDGET."""
    return _budget(SPARSE_N_ENV, SPARSE_N_BUDGET, SPARSE_N_FLOOR, "a sparse factorisation")


def within_dense_budget(n: int) -> bool:
    """Whether dense work on an n x n matrix is within the dense-work budget (one comparison up
    to :data:`DENSE_N_FLOOR`; the one rule behind :func:`check_dense_work` and the ``auto``
    storage choices that pick dense only within it)."""
    return n <= DENSE_N_FLOOR or n <= dense_n_budget()


def dense_cost(n: int, cubic: bool = True) -> str:
    """What dense work on an n x n matrix costs, in words: the memory of one copy and, for a
    factorisation or pivoting (``cubic``), about n^3 operations."""
    memory = f"{n * n * 8 / 2**30:,.2f} GiB per copy of M"
    return f"{memory}, about {float(n) ** 3:.1e} operations" if cubic else memory


def check_dense_work(n: int, step: str, *, instead: str = "", cubic: bool = True,
                     source: str | None = None) -> None:
    """ProblemError (exit 2) when ``step`` -- dense work on an n x n matrix -- is over the budget.

    ``step`` names the work (``"method 'lemke' pivots on the dense M"``); ``instead`` suggests
    another way (appended to the message); ``cubic``: the step does O(n^3) operations (else
    only its memory is named); ``source`` (the file) prefixes the message.  Called before the
    step allocates anything.
    """
    if within_dense_budget(n):
        return
    budget = dense_n_budget()
    hint = f", or {instead}" if instead else ""
    raise ProblemError(f"n = {n:,}: {step} ({dense_cost(n, cubic)}): over the dense-work budget "
                       f"n <= {budget:,}; set {DENSE_N_ENV}={n} to run it anyway{hint}", source)


def check_sparse_factorisation(n: int, step: str, *, instead: str = "",
                               source: str | None = None) -> None:
    """ProblemError (exit 2) when ``step`` -- a sparse LU factorisation of an n x n matrix --
    is over the sparse-factorisation budget (its workspace alone is about
    ``n * SPARSE_LU_ROW_BYTES``).  Called before anything is factorised; ``instead`` and
    ``source`` as for :func:`check_dense_work`."""
    if n <= SPARSE_N_FLOOR:
        return
    budget = sparse_n_budget()
    if n <= budget:
        return
    hint = f", or {instead}" if instead else ""
    workspace = n * SPARSE_LU_ROW_BYTES / 2**30
    raise ProblemError(f"n = {n:,}: {step} (SuperLU needs about {workspace:,.2f} GiB of "
                       f"workspace before any fill-in): over the sparse-factorisation budget "
                       f"n <= {budget:,}; set {SPARSE_N_ENV}={n} to run it anyway{hint}", source)


def warm_start_entries(n: int, named: bool) -> int:
    """The most values a warm start for n unknowns may hold: n by position, more by name
    (:data:`WARM_START_NAMED_FACTOR`, :data:`WARM_START_SLACK`)."""
    return WARM_START_NAMED_FACTOR * n + WARM_START_SLACK if named else n
