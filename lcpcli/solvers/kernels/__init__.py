"""Compiled kernels of the solver methods (Cython extensions built at install; no Python
objects inside the hot loops, the GIL released).  See docs/kernels.md.

The enumeration kernel (:mod:`lcpcli.analysis._enum`) and the stacked kernels (:mod:`.batch`)
run OpenMP threads.  GNU OpenMP does not survive ``fork()``: a child
forked from a process that has run a parallel region hangs or dies in its first one.  Worker
pools therefore start their processes with :func:`process_context` (``forkserver`` where the
platform has it, else ``spawn``), never with a bare ``fork``.
"""

from __future__ import annotations

import os
from typing import Any

from lcpcli.core.errors import LcpError


def process_context(preload: tuple[str, ...] = ()) -> Any:
    """A :mod:`multiprocessing` context that is safe with the kernels' OpenMP threads.

    ``forkserver`` (POSIX): workers fork from a clean server process that never ran a kernel;
    ``preload`` names modules the server imports once (so each worker starts with them loaded;
    it applies only when the server is started).  Elsewhere ``spawn``.  A current folder
    that no longer exists is an :class:`~lcpcli.core.errors.LcpError` (one line): a worker
    starts in its parent's folder, and multiprocessing fails on it with a bare
    FileNotFoundError.
    """
    import multiprocessing as mp

    try:
        os.getcwd()
    except FileNotFoundError:
        raise LcpError("the current folder no longer exists (it was deleted): worker processes "
                       "cannot start in it; change to a folder that exists (cd) and run again"
                       ) from None

    if "forkserver" in mp.get_all_start_methods():
        ctx = mp.get_context("forkserver")
        if preload:
            ctx.set_forkserver_preload(list(preload))
        return ctx
    return mp.get_context("spawn")
