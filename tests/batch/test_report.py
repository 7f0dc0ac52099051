"""The batch tally (lcpcli.batch.report.Tally): counts and extremes of any sequence of rows."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from lcpcli.batch.report import Tally

rows = st.lists(st.fixed_dictionaries({
    "status": st.sampled_from(["solved", "unsolved", "error"]),
    "source": st.sampled_from(["a.json", "b.json"]),
    "problem": st.sampled_from(["p", "q", "r"]),
    "seconds": st.one_of(st.none(), st.floats(0, 1), st.integers(0, 3)),
    "error": st.one_of(st.none(), st.floats(0, 1), st.just(0.5)),
    "n": st.one_of(st.none(), st.just(3)),
    "message": st.just("m")}), max_size=40)


@settings(max_examples=300, deadline=None)
@given(rows=rows, top=st.integers(0, 6))
def test_tally_keeps_the_largest_as_a_full_sort_does(rows, top):
    """The slowest and worst kept are the ``top`` largest of all rows (ties included), the
    first ``top`` errors in order, and the counts by status."""
    tally = Tally(top=top)
    for row in rows:
        tally.add(row)
    ok = [r for r in rows if r["status"] != "error"]
    slow = sorted(((float(r["seconds"]), r["source"], r["problem"]) for r in ok
                   if r["seconds"] is not None), reverse=True)[:top]
    worst = sorted(((math.inf if r["error"] is None else float(r["error"]), r["source"],
                     r["problem"]) for r in ok if r["n"] is not None), reverse=True)[:top]
    assert sorted(tally.slowest, reverse=True) == slow
    assert sorted(tally.worst, reverse=True) == worst
    assert tally.errors == [(r["source"], r["problem"], "m") for r in rows
                            if r["status"] == "error"][:top]
    assert tally.counts == {s: sum(r["status"] == s for r in rows)
                            for s in {r["status"] for r in rows}}
