"""Every memo of the solve path, behind one fence.

A small solve (n = 10: a few microseconds) would spend a good part of its time recomputing
things that depend on a handful of facts only: a method's option defaults, the method and
options of one of ``auto``'s attempts, the policy's ordered rows, the opening of a small dense
problem.  Each is memoised here, in a :class:`Memo` whose key lists every fact the value depends
on.  The key is built next to those facts, by the function named in each memo's comment, so a
new fact that changes the value cannot be left out of the key without changing that function:

* :data:`REQUESTS`: a request without options -> (method, validated tol, parsed default
  options) (key: :func:`lcpcli.solvers.request.request_key`: the method's record, by ``id``
  and checked on a hit, and the tol given; the problem's own checks always run);
* :data:`OPTION_DEFAULTS`: a :class:`~lcpcli.solvers.registry.Method` -> its option defaults
  (key: the record's ``id``, checked against the record itself,
  :meth:`~lcpcli.solvers.registry.Method.parse_options`);
* :data:`ATTEMPTS`: one of ``auto``'s attempts without a warm start -> (method, parsed
  options) (key: :func:`lcpcli.solvers.methods.auto.attempt_key`: the method's name, the
  ``max_iter`` given and the registry's version);
* :data:`ORDERS`: the ordered policy rows of a problem kind in a regime (key:
  :func:`lcpcli.solvers.policy.table_key`: kind, regime and registry version or content);
* :data:`OPENINGS`: a dense problem's regime and first step when only the O(n) diagonal test
  decided them (key: :func:`lcpcli.solvers.policy.opening_key`, built from
  :func:`lcpcli.analysis.classify.diagonal_facts`: every property that test decides);
* :data:`FIRSTS`: ``auto``'s first attempt on such a problem without a warm start or
  ``order=``: the opening, the attempt's method and options and the head of its message (key:
  :func:`lcpcli.solvers.methods.auto.first_key`: the opening's facts, the number of zero
  diagonal entries, the one other fact the message's class phrase reads, and the ``max_iter``
  given; one flat tuple, :func:`~lcpcli.solvers.methods.auto.first_key_of`, which ``auto``
  also builds from the minima of a dense M with a positive diagonal, without a classifier).

Rule: a value stored under a key equals what a fresh computation with the same facts returns
(``tests/solvers/test_memo.py`` checks every memo is hit and that a hit equals a fresh
computation).  Each memo is bounded (it stops storing when full) and counts its misses.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import Any


class Memo(dict):
    """A bounded dictionary that counts its misses (a full memo stores nothing more).

    Look-ups are the dictionary's own ``get`` (C speed: the memos are on the small-solve
    path); a caller that finds nothing computes the value and :meth:`puts <put>` it, which counts a
    miss, so a repeated call that leaves ``misses`` unchanged was served from the memo."""

    __slots__ = ("name", "limit", "misses")

    def __init__(self, name: str, limit: int) -> None:
        super().__init__()
        self.name = name
        self.limit = limit
        self.misses = 0

    def put(self, key: Hashable, value: Any) -> Any:
        """Count a miss and store ``value`` under ``key`` unless the memo is full; return
        ``value``."""
        self.misses += 1
        if len(self) < self.limit:
            self[key] = value
        return value

    def clear(self) -> None:
        super().clear()
        self.misses = 0

    def __hash__(self) -> int:  # a module-level singleton, compared by identity
        return id(self)

    def __eq__(self, other: object) -> bool:
        return self is other


REQUESTS = Memo("requests", 1024)
OPTION_DEFAULTS = Memo("option defaults", 4096)
ATTEMPTS = Memo("auto attempts", 1024)
ORDERS = Memo("policy orders", 1024)
OPENINGS = Memo("auto openings", 4096)
FIRSTS = Memo("auto first attempts", 4096)

#: Every memo of the solve path.
MEMOS = (REQUESTS, OPTION_DEFAULTS, ATTEMPTS, ORDERS, OPENINGS, FIRSTS)


def clear() -> None:
    """Empty every memo (tests; a process that changes what a key cannot see)."""
    for memo in MEMOS:
        memo.clear()
