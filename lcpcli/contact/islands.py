"""Islands: the independent sub-LCPs of a scene, solved one by one and merged back.

Two contacts interact (``M_ij != 0``, or a friction row of one touches the other) only through a
dynamic body they share; static and kinematic bodies have infinite mass, so they transmit no
impulse.  An **island** is a connected component of the graph whose nodes are the dynamic bodies
and whose edges are the contacts between two dynamic bodies; a contact belongs to the island of
its dynamic body (one of its two bodies is dynamic).  Ordering the LCP's unknowns by island
makes ``M`` block diagonal, so the LCP splits into one LCP per island, and the scene's LCP has a
solution if and only if every island's has (the union of the islands' solutions is one).

Islands are numbered in the order of their first contact; inside an island the unknowns keep
the scene's order (normal impulses, then tangential impulses, then slacks).  Box2D, ODE
(``dxProcessIslands``), Bullet and MuJoCo (``mj_island``) split their contact problems the same
way.

:func:`solve_islands` solves a scene's islands: where they are all dense blocks of one size, in
one call of the batched solver on the blocks as written (:func:`_solve_stacked`), the answers
read from the stack's arrays; otherwise through :func:`solve_problems`, whose
:func:`solve_cold` stacks the islands of one size for the batched solver (``solve_each``).
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np

from lcpcli.contact._blocks import scatter_blocks
from lcpcli.contact.assembly import choose_storage
from lcpcli.contact.scene import Scene
from lcpcli.core.certificate import Certificate, certificate_of
from lcpcli.core.problem import Problem, is_sparse
from lcpcli.core.result import CONVERGED, SOLVED, Outcome
from lcpcli.solvers import DEFAULT_METHOD

#: Warm start, islands of at least WARM_NEWTON_MIN_N unknowns whose ``z0`` does not already
#: pass the certificate: first this method from ``z0`` ...
WARM_METHOD = "newton"
#: ... for at most this many iterations; if its certificate fails, the island is solved cold.
WARM_MAX_ITER = 20
#: Below this many unknowns a cold pivoting solve costs less than Newton's set-up and final
#: active-set polish (measured: 72-unknown islands, 0.8 ms cold with Lemke against 2.7 ms for
#: Newton started at the solution), so a ``z0`` that does not pass is not used there.
WARM_NEWTON_MIN_N = 1000
#: With ``jobs > 1``, islands go to a process pool only when they hold at least this many
#: unknowns in all and there are at least ``2 * jobs`` islands (below, forking the workers and
#: sending the problems back and forth costs more than it saves; benchmarks/bench_contact.py).
PARALLEL_MIN_UNKNOWNS = 20_000
#: Seconds :func:`_block_buffer` takes per stored entry of ``M`` on one core (834 box stacks,
#: 2.4 million entries: 3 ms with a reused buffer, 5-7 ms on fresh memory): it writes the
#: blocks in one OpenMP thread per ``lcpcli.solvers.batched.MIN_THREAD_SECONDS`` of that work
#: at most (the batched kernels' rule: on a busy machine a thread with less to do costs more
#: in waiting to be scheduled than it saves; 834 box stacks: one thread).
SCATTER_SECONDS_PER_ENTRY = 1.25e-9
#: :func:`solve_islands` keeps one island-block buffer of at most this many doubles between
#: calls (a time-stepping loop solves one scene after another of the same size), when nothing
#: else refers to it: reusing it spares the first touch of fresh memory (about 2 ms of the
#: 6 ms that writing the 35 MB of 834 box stacks' blocks takes on one core).
BLOCK_POOL_MAX = 1 << 23  # 64 MiB: 834 box stacks need 35 MB
_block_pool: list[np.ndarray] = []


@dataclass
class Islands:
    """Island of every contact and body; ``count`` islands numbered by first contact."""

    contact_island: np.ndarray   # (nc,) island index of each contact
    body_island: np.ndarray      # (nb,) island of each dynamic body in contact, -1 otherwise
    count: int

    def sizes(self) -> np.ndarray:
        """Contacts per island."""
        return np.bincount(self.contact_island, minlength=self.count)

    def body_counts(self) -> np.ndarray:
        """Dynamic bodies per island."""
        b = self.body_island[self.body_island >= 0]
        return np.bincount(b, minlength=self.count)


def find_islands(scene: Scene) -> Islands:
    """Connected components of the contact graph through dynamic bodies (see module docstring)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    nb, nc = scene.n_bodies, scene.n_contacts
    ca, cb = scene.contact_a, scene.contact_b
    dyn = ~scene.fixed
    both = np.flatnonzero(dyn[ca] & dyn[cb])
    graph = sp.csr_matrix((np.ones(both.size), (ca[both], cb[both])), shape=(nb, nb))
    _, labels = connected_components(graph, directed=False)
    body_of = np.where(dyn[ca], ca, cb)        # a dynamic body of each contact
    raw = labels[body_of]
    # renumber: island 0 holds contact 0, island 1 the first contact not in island 0, ...
    uniq, first = np.unique(raw, return_index=True)
    order = np.argsort(first, kind="stable")
    new = np.empty(uniq.size, dtype=np.int64)
    new[order] = np.arange(uniq.size)
    contact_island = new[np.searchsorted(uniq, raw)] if nc else np.zeros(0, dtype=np.int64)
    body_island = np.full(nb, -1, dtype=np.int64)
    for side in (ca, cb):
        d = dyn[side]
        body_island[side[d]] = contact_island[d]
    return Islands(contact_island=contact_island, body_island=body_island, count=int(uniq.size))


@dataclass
class IslandLayout:
    """The LCP's unknowns grouped by island: island ``k`` is ``perm[offsets[k]:offsets[k+1]]``."""

    perm: np.ndarray
    offsets: np.ndarray

    def unknowns(self, k: int) -> np.ndarray:
        return self.perm[self.offsets[k]: self.offsets[k + 1]]

    @property
    def count(self) -> int:
        return int(self.offsets.size - 1)


def layout(islands: Islands, unknown_contact: np.ndarray) -> IslandLayout:
    """Group the unknowns (``unknown_contact[i]``: the contact of unknown ``i``) by island."""
    isl = islands.contact_island[unknown_contact]
    perm = np.argsort(isl, kind="stable")
    offsets = np.searchsorted(isl[perm], np.arange(islands.count + 1))
    return IslandLayout(perm=perm, offsets=offsets)


def island_problems(problem: Problem, lay: IslandLayout, storage: str = "auto",
                    name: str = "island") -> list[Problem]:
    """The islands' LCPs: principal blocks of ``problem.M`` (dense or CSR by ``storage``)."""

    M, q = problem.M, problem.q
    out = []
    if lay.count == 1 and lay.perm.size == problem.n:
        return [problem]  # one island holding every unknown, in order (a stable sort)
    qp = q[lay.perm]
    if not is_sparse(M):
        P = np.asarray(M)[np.ix_(lay.perm, lay.perm)]
        for k in range(lay.count):
            s, e = int(lay.offsets[k]), int(lay.offsets[k + 1])
            block = P[s:e, s:e]
            if storage == "sparse":
                import scipy.sparse as sp

                block = sp.csr_matrix(block)
            out.append(Problem(M=block, q=qp[s:e].copy(), name=f"{name}#{k + 1}"))
        return out
    import scipy.sparse as sp

    blocks = _dense_blocks(M, lay, storage)
    if blocks is not None:
        return [Problem(M=block, q=qp[int(lay.offsets[k]): int(lay.offsets[k + 1])].copy(),
                        name=f"{name}#{k + 1}") for k, block in enumerate(blocks)]
    P = M.tocsr()[lay.perm][:, lay.perm].tocsr()
    P.sum_duplicates()
    # block diagonal: rows s..e-1 hold entries in columns s..e-1 only, so each block is a slice
    # of P's arrays (no scipy slicing per island)
    ptr, idx, val = P.indptr, P.indices, P.data
    for k in range(lay.count):
        s, e = int(lay.offsets[k]), int(lay.offsets[k + 1])
        a, b = int(ptr[s]), int(ptr[e])
        n = e - s
        if choose_storage(storage, n, b - a) == "dense":
            block = np.zeros((n, n))
            rows = np.repeat(np.arange(n), np.diff(ptr[s:e + 1]))
            block[rows, idx[a:b] - s] = val[a:b]
        else:
            block = sp.csr_matrix((val[a:b].copy(), idx[a:b] - s, ptr[s:e + 1] - a),
                                  shape=(n, n))
        out.append(Problem(M=block, q=qp[s:e].copy(), name=f"{name}#{k + 1}"))
    return out


def _dense_blocks(M: Any, lay: IslandLayout, storage: str) -> list[np.ndarray] | None:
    """The islands' blocks of the CSR matrix ``M`` as dense arrays, when every island is stored
    dense (:func:`choose_storage`): views of :func:`_block_buffer`'s buffer, the blocks of one
    size back to back in island order, so that a stack of them
    (:func:`lcpcli.stacks.solve_each`) is a view of it.  None when an island is stored sparse
    or ``M`` is not block diagonal in the islands (the caller slices instead)."""
    found = _block_buffer(M, lay, storage)
    if found is None:
        return None
    buf, start, sizes = found
    return [buf[a: a + n * n].reshape(n, n)
            for a, n in zip(start.tolist(), sizes.tolist(), strict=True)]


def _block_buffer(M: Any, lay: IslandLayout, storage: str,
                  pooled: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(buf, start, sizes)``: the islands' dense blocks of the CSR matrix ``M`` written by one
    compiled pass over ``M``'s entries (:func:`lcpcli.contact._blocks.scatter_blocks`) into one
    buffer, island ``k``'s ``sizes[k] x sizes[k]`` block (row-major) at ``buf[start[k]:]``: the
    blocks of one size back to back in island order.  None as :func:`_dense_blocks`.
    ``pooled``: ``buf`` may be the buffer :func:`_keep_buffer` kept (the caller gives it back
    there when done)."""
    N = M.shape[0]
    sizes = np.diff(lay.offsets).astype(np.int64)
    if lay.perm.size != N or lay.count == 0 or not np.all(sizes > 0):
        return None
    M = M.tocsr()
    nnz = np.add.reduceat(np.diff(M.indptr)[lay.perm], lay.offsets[:-1])
    if any(choose_storage(storage, n, e) != "dense"  # once per distinct size and fill
           for n, e in set(zip(sizes.tolist(), nnz.tolist(), strict=True))):
        return None
    order = np.argsort(sizes, kind="stable")  # one size after another, islands in order
    length = sizes * sizes
    start = np.empty(lay.count, np.int64)
    start[order] = np.concatenate(([0], np.cumsum(length[order])[:-1]))
    island = np.empty(N, np.int64)
    island[lay.perm] = np.repeat(np.arange(lay.count), sizes)
    local = np.empty(N, np.int64)
    local[lay.perm] = np.arange(N) - np.repeat(lay.offsets[:-1].astype(np.int64), sizes)
    row_start = start[island] + local * sizes[island]
    total = int(length.sum())
    buf = _block_pool.pop() if pooled and _block_pool else None
    fresh = buf is None or buf.size != total
    if fresh:
        buf = np.empty(total)  # every row zeroes its own block row first (sizes=)
    indices, indptr = M.indices, M.indptr
    if indices.dtype != indptr.dtype:
        indices, indptr = indices.astype(np.int64), indptr.astype(np.int64)
    from lcpcli.solvers.batched import MIN_THREAD_SECONDS, default_threads

    threads = max(1, min(default_threads(),
                         int(M.data.size * SCATTER_SECONDS_PER_ENTRY / MIN_THREAD_SECONDS)))
    if not scatter_blocks(M.data, indices, indptr, row_start, local, island, buf, threads,
                          sizes, fresh):
        return None
    return buf, start, sizes


def _keep_buffer(buf: np.ndarray) -> None:
    """Keep ``buf`` (from :func:`_block_buffer`) for the next call when nothing but the
    caller's name refers to it (no view of it lives on: a Result built on an island's block
    keeps it from being reused) and it holds at most :data:`BLOCK_POOL_MAX` doubles."""
    # references: the caller's name, this parameter and getrefcount's own argument
    if sys.getrefcount(buf) == 3 and buf.base is None and buf.size <= BLOCK_POOL_MAX:
        _block_pool[:] = [buf]


@dataclass
class IslandAnswers:
    """The islands' answers, island ``k`` at index ``k`` of every list: what the scene's
    verdict and per-island report are made of (:func:`lcpcli.contact.model.solve`).

    ``z`` and ``basic`` are merged in the scene's unknown order (``basic``: :func:`basic_of` of
    each island's answer); ``methods`` (the method that answered, ``info["chosen"]`` where
    ``auto`` chose), ``status``, ``iterations``, ``seconds``, ``errors`` (the certified error)
    and ``warm`` (whether the warm start gave the answer) are those of each island's
    :class:`Result`; ``results`` holds the full Result of every island that is not solved (its
    message, termination and Farkas vector) and of the islands answered one by one.
    ``checked``: the whole scene's ``(certificate, w)`` for ``z`` when it follows from the
    islands' own (:func:`scene_check`), else None (the caller checks ``z`` on the scene)."""

    z: np.ndarray
    basic: np.ndarray
    methods: list[str]
    status: list[Any]
    iterations: list[int]
    seconds: list[float]
    errors: list[float]
    warm: list[bool]
    results: dict[int, Any]
    checked: tuple[Certificate, np.ndarray] | None = None


def solve_islands(problem: Problem, lay: IslandLayout, storage: str, name: str,
                  method: str = DEFAULT_METHOD, tol: float | None = None,
                  z0: np.ndarray | None = None, basis0: np.ndarray | None = None, jobs: int = 1,
                  stacked: bool = True, **options: Any) -> IslandAnswers:
    """Solve the islands of ``problem`` (``lay``; blocks stored by ``storage``, named
    ``name#k``) from the warm start ``z0`` (and ``basis0``) of the whole scene, if given:
    :func:`solve_problems` on :func:`island_problems`, the same answers without a
    :class:`Result` per island where every island is a dense block of one size that
    :func:`lcpcli.stacks.solve_each` would stack (:func:`_solve_stacked`; ``stacked=False``:
    never, the reference the tests compare it with)."""
    fast = None if not stacked else _solve_stacked(problem, lay, storage, name, method, tol, z0,
                                                    basis0, jobs, options)
    if fast is not None:
        return fast
    problems = island_problems(problem, lay, storage, name)
    cuts = lay.offsets[1:-1]  # the islands' unknowns are lay.perm's consecutive pieces
    z0s = None if z0 is None else np.split(z0[lay.perm], cuts)
    bases = None if basis0 is None else np.split(basis0[lay.perm], cuts)
    results = solve_problems(problems, method, tol, z0s, jobs, bases0=bases, **options)
    z = np.zeros(problem.n)
    basic = np.zeros(problem.n, dtype=bool)
    if results:
        z[lay.perm] = np.concatenate([res.z for res in results])
        basic[lay.perm] = np.concatenate([basic_of(res) for res in results])
    return IslandAnswers(
        z=z, basic=basic, methods=[res.info.get("chosen") or res.method for res in results],
        status=[res.status for res in results],
        iterations=[int(res.iterations) for res in results],
        seconds=[res.seconds for res in results],
        errors=[float(res.certificate.error) for res in results],
        warm=[bool(res.info.get("warm", False)) for res in results],
        results=dict(enumerate(results)))


def _solve_stacked(problem: Problem, lay: IslandLayout, storage: str, name: str, method: str,
                   tol: float | None, z0: np.ndarray | None, basis0: np.ndarray | None,
                   jobs: int, options: dict[str, Any]) -> IslandAnswers | None:
    """The islands' answers when every island is a dense block of one size ``n`` (of a dense
    ``problem.M``, or of a CSR one: :func:`_block_buffer`), at least ``STACK_MIN`` of them, below
    ``WARM_MIN_N`` with a warm start, and no process pool (the cases where
    :func:`solve_problems` stacks them all in one :func:`lcpcli.solve_many` call): that call on
    the buffer as it is, the warm rows gathered in one step, and the answers read from the
    stack's arrays; a :class:`Result` (:func:`lcpcli.stacks.stacked_result`) only for the
    islands the kernel did not certify.  None in every other case."""
    from lcpcli.solvers.warm import WARM_MIN_N
    from lcpcli.stacks import STACK_MIN, solve_many, stacked_result

    K = lay.count
    if K < STACK_MIN or lay.perm.size != problem.n:
        return None
    sizes = np.diff(lay.offsets)
    n = int(sizes[0])
    if not np.all(sizes == n) or (z0 is not None and n >= WARM_MIN_N) or \
            (z0 is None and jobs > 1 and 2 * jobs <= K and problem.n >= PARALLEL_MIN_UNKNOWNS):
        return None
    perm = lay.perm
    buf = None
    if is_sparse(problem.M):
        found = _block_buffer(problem.M, lay, storage, pooled=True)
        if found is None:
            return None
        buf = found[0]
        del found
        M = buf.reshape(K, n, n)  # one size: the blocks in island order
    elif storage == "sparse":  # island_problems stores the blocks sparse: not stacked
        return None
    else:  # the principal blocks of a dense M, as island_problems slices them
        at = perm.reshape(K, n)
        M = np.asarray(problem.M)[at[:, :, None], at[:, None, :]]
    q = problem.q[perm].reshape(K, n)
    warm = None
    if z0 is not None:  # rows as solve_each makes them: 1 where z_i is basic
        warm = (basis0[perm] if basis0 is not None else z0[perm] > 0).reshape(K, n)
        warm = warm.astype(np.float64)
    res = solve_many(M, q, method, tol=tol, warm=warm, certificates=True, pivot_basis=True,
                     **options)
    errors = np.full(K, np.nan) if res.certificates is None else res.certificates[:, 0]
    # answered and certified in the kernel: a Result's certificate from that row passes
    # (lcpcli.core.certificate.certificate_of: error <= tol, finite)
    kernel = (errors <= res.tol) & (errors < np.inf)
    kernel[list(res.results)] = False
    warmed = np.zeros(K, bool) if res.warmed is None else res.warmed
    basic = res.z > 0
    if res.pivot_basis is not None:
        listed = kernel & (res.pivot_basis[:, 0] >= 0)
        basic[listed] = res.pivot_basis[listed] != 0
    share = res.seconds / K
    methods = ["bpp" if w else res.method for w in warmed.tolist()]
    status = [SOLVED] * K
    iterations = res.iterations.tolist()
    seconds = [share] * K
    errors_out = errors.tolist()
    warm_out = warmed.tolist()
    results: dict[int, Any] = {}
    for j in np.flatnonzero(~kernel).tolist():
        r = stacked_result(res, j, Problem(M=M[j], q=q[j].copy(), name=f"{name}#{j + 1}"))
        r.info["warm"] = bool(r.info.get("warm", False))
        results[j] = r
        basic[j] = basic_of(r)
        methods[j] = r.info.get("chosen") or r.method
        status[j], iterations[j], seconds[j] = r.status, int(r.iterations), r.seconds
        errors_out[j], warm_out[j] = float(r.certificate.error), r.info["warm"]
    z = np.empty(problem.n)
    z[perm] = res.z.reshape(-1)
    merged = np.empty(problem.n, dtype=bool)
    merged[perm] = basic.reshape(-1)
    checked = None
    if kernel.all() and is_sparse(problem.M) and problem.kind == "lcp":
        # M block diagonal in the islands: checked entry by entry by _block_buffer
        checked = scene_check(res.certificates, res.w, lay, res.tol)
    if buf is not None:
        del M
        _keep_buffer(buf)
    return IslandAnswers(z=z, basic=merged, methods=methods, status=status,
                         iterations=iterations, seconds=seconds, errors=errors_out,
                         warm=warm_out, results=results, checked=checked)


def scene_check(rows: np.ndarray, w: np.ndarray, lay: IslandLayout,
                tol: float) -> tuple[Certificate, np.ndarray]:
    """The whole scene's ``(certificate, w)`` (:func:`lcpcli.core.certificate.check` of the
    merged ``z`` on the scene's LCP) from its islands' certificates ``rows`` (one row of
    :data:`lcpcli.solvers.kernels.batch.CERT_FIELDS` per island, all status 0) and ``w``
    ((K, n), island order), for a scene whose ``M`` is block diagonal in the islands ``lay``.

    Why this is the scene's certificate (the definitions in :mod:`lcpcli.core.certificate`):
    with ``M`` block diagonal, row ``i``'s terms are those of its island's columns, so ``w_i``,
    ``(|M| |z|)_i`` and the row scale ``s_i`` are the island's; column ``j``'s entries lie in
    its island's rows, so ``kappa_j = max_i |M_ij| / s_i`` is the island's; a link joins row
    ``i`` and column ``j`` only where ``M_ij != 0``, so every block of linked rows lies in one
    island and its growth is the island's; each pair's backward error ``eps_i`` depends on
    ``z_i``, ``w_i``, ``s_i``, ``kappa_i`` only.  Hence ``error = max_i eps_i max(1, G)`` is
    the largest island error, the backward error and the diagnostics in data units (maxima
    over the pairs) are the islands' largest, and ``worst``, the first row (in the scene's
    order) with the largest error, is the first such row among the islands' own worst rows
    (inside an island the unknowns keep the scene's order), ``growth`` its island's.  The
    numbers are those of the islands' evaluation (their blocks stored dense: the sums in
    another order than a CSR pass over the scene, the same definition to rounding).  ``passed``
    by the one rule, :func:`lcpcli.core.certificate.certificate_of`, at ``tol``: the scene is
    solved exactly when every island's certificate passes."""
    err = rows[:, 0]
    top = err.max()
    at = np.flatnonzero(err == top)
    first = lay.perm[lay.offsets[at] + rows[at, 8].astype(np.int64)]
    pick = int(np.argmin(first))
    largest = rows.max(axis=0).tolist()
    cert = certificate_of(0, float(top), largest[1], float(rows[at[pick], 2]), largest[3],
                          largest[4], largest[5], largest[6], largest[7], int(first[pick]),
                          tol)
    merged = np.empty(lay.perm.size)
    merged[lay.perm] = w.reshape(-1)
    return cert, merged


def solve_problems(problems: list[Problem], method: str = DEFAULT_METHOD, tol: float | None = None,
                   z0s: list[np.ndarray] | None = None, jobs: int = 1,
                   bases0: list[np.ndarray] | None = None, **options: Any) -> list[Any]:
    """Solve the island LCPs; one certified :class:`Result` per problem, in order.

    ``z0s``: warm starts, one per problem (:func:`warm_attempt`); the problems they do not solve
    start pivoting from the basis of their ``z0`` (``{i: z0_i > 0}`` as the certificate reads
    ``z0`` and ``w0 = M z0 + q``): islands of one size stacked in the batched kernel
    (:mod:`lcpcli.solvers.warm_stack`), others by ``lcpcli.solve(warm=basis)``, each solved
    cold where that does not end certified; ``bases0`` (with ``z0s``): the bases the pivoting
    starts from instead (booleans, True: z_i basic).  Problems without ``z0`` go to
    :func:`solve_cold`
    (``jobs > 1``: in a process pool when the work is large enough,
    :data:`PARALLEL_MIN_UNKNOWNS`; warm-started problems stay in this process).
    ``Result.info["warm"]`` says whether the warm start gave the answer.
    """
    results: list[Any] = [None] * len(problems)
    todo = list(range(len(problems)))
    warms: list[Any] | None = None
    if z0s is not None:
        todo, warms = [], []
        stacked = _stacked_warm(problems)
        for i, (p, z0) in enumerate(zip(problems, z0s, strict=True)):
            given = None if bases0 is None else np.asarray(bases0[i], dtype=bool)
            if stacked[i]:  # the batched kernel tries z0's basis first: no pass here
                todo.append(i)
                warms.append(np.asarray(z0) > 0 if given is None else given)
                continue
            res, basis = warm_attempt(p, method, tol, z0)
            if res is None:
                todo.append(i)
                warms.append(basis if given is None else given)
            else:
                results[i] = res
    cold = [problems[i] for i in todo]
    total = sum(p.n for p in cold)
    if warms is None and jobs > 1 and len(cold) >= 2 * jobs and \
            total >= PARALLEL_MIN_UNKNOWNS:
        answers = _solve_parallel(cold, method, tol, jobs, options)
    else:
        answers = solve_cold(cold, method, tol, options, warms=warms)
    for i, res in zip(todo, answers, strict=True):
        res.info["warm"] = bool(res.info.get("warm", False))
        results[i] = res
    return results


def _stacked_warm(problems: list[Problem]) -> list[bool]:
    """The problems whose warm start goes straight to the batched kernel
    (:mod:`lcpcli.solvers.warm_stack`): dense LCPs below n = 200 with at least
    ``lcpcli.stacks.STACK_MIN`` of their size.  Their kernel's first step is the basic solution
    of ``z0``'s basis, certified: ``z0`` itself when it was the answer, without the separate
    certificate :func:`warm_attempt` would take."""
    from lcpcli.solvers.warm import WARM_MIN_N
    from lcpcli.stacks import STACK_MIN

    small = [p.kind == "lcp" and not p.sparse and p.n < WARM_MIN_N for p in problems]
    sizes: dict[int, int] = {}
    for p, ok in zip(problems, small, strict=True):
        if ok:
            sizes[p.n] = sizes.get(p.n, 0) + 1
    return [ok and sizes[p.n] >= STACK_MIN for p, ok in zip(problems, small, strict=True)]


def solve_cold(problems: list[Problem], method: str, tol: float | None,
               options: dict[str, Any], threads: int | None = None,
               warms: list[Any] | None = None) -> list[Any]:
    """Each problem from scratch (or from its basis in ``warms``), certified:
    :func:`lcpcli.stacks.solve_each` (islands of one size, 8 or more, go through the batched
    kernels of ``lcpcli.solve_many`` in one call)."""
    from lcpcli.stacks import solve_each

    return solve_each(problems, method, tol=tol, threads=threads, warms=warms, **options)


def solve_one(problem: Problem, method: str, tol: float | None, z0: np.ndarray | None,
              options: dict[str, Any], basis0: np.ndarray | None = None) -> Any:
    """One LCP (an island or the whole scene): :func:`warm_attempt`, else :func:`solve_cold`
    (from ``basis0`` when given, else from ``z0``'s basis)."""
    return solve_problems([problem], method, tol, None if z0 is None else [z0], 1,
                          bases0=None if basis0 is None else [basis0], **options)[0]


def warm_attempt(problem: Problem, method: str, tol: float | None,
                 z0: np.ndarray) -> tuple[Any, np.ndarray]:
    """``(answer, basis)``: the warm start's answer, or None: ``z0`` itself if it passes the
    certificate (method ``z0``, no iteration); otherwise, on problems of at least
    :data:`WARM_NEWTON_MIN_N` unknowns, :data:`WARM_METHOD` from ``z0`` (at most
    :data:`WARM_MAX_ITER` iterations) if it solves it.  ``basis``: booleans, ``z_i`` basic in
    ``z0``'s basis as the certificate reads it (where the pivoting starts when there is no
    answer).  The tolerance is ``tol`` or ``method``'s default."""
    from lcpcli.api import certify_outcome, solve
    from lcpcli.solvers.request import method_of, resolve_tol

    limit = resolve_tol(method_of(method), tol)
    given = certify_outcome(problem, Outcome(np.asarray(z0, dtype=np.float64), 0, CONVERGED,
                                             "the warm start z0 passes the certificate"),
                            "z0", 0.0, limit, basis=True)
    basis = given.z_basic
    if given.solved:
        given.info["warm"] = True
        return given, basis
    if problem.n >= WARM_NEWTON_MIN_N:
        warm = solve(problem, WARM_METHOD, tol=tol, z0=z0, max_iter=WARM_MAX_ITER)
        if warm.solved:
            warm.info["warm"] = True
            return warm, basis
    return None, basis


def basic_of(result: Any) -> np.ndarray:
    """z_i basic in ``result``'s pivoting basis (``info["basis"]``, the basic z's that Lemke
    reports), else in its answer's support (``z_i > 0``)."""
    basic = result.z > 0
    listed = result.info.get("basis")
    if listed is not None and result.solved:
        basic = np.zeros(result.z.shape[0], dtype=bool)
        basic[np.asarray(listed, dtype=np.int64)] = True
    return basic


def _chunks(sizes: list[int], parts: int) -> list[list[int]]:
    """Split indices 0..len(sizes)-1 into ``parts`` lists of about equal summed cost n^2."""
    order = np.argsort(-np.asarray(sizes, dtype=np.float64) ** 2, kind="stable")
    loads = np.zeros(parts)
    out: list[list[int]] = [[] for _ in range(parts)]
    for i in order:
        j = int(np.argmin(loads))
        out[j].append(int(i))
        loads[j] += float(sizes[i]) ** 2 + 1.0
    return [c for c in out if c]


def _work(args: tuple[list[Problem], str, float | None, dict[str, Any]]) -> list[Any]:
    problems, method, tol, options = args
    return solve_cold(problems, method, tol, options, threads=1)  # one thread per worker


def _solve_parallel(problems: list[Problem], method: str, tol: float | None, jobs: int,
                    options: dict[str, Any]) -> list[Any]:
    # concurrent.futures / multiprocessing only here: most runs never use a pool
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    ctx = multiprocessing.get_context("fork" if "fork" in multiprocessing.get_all_start_methods()
                                      else "spawn")
    groups = _chunks([p.n for p in problems], jobs * 4)
    results: list[Any] = [None] * len(problems)
    with ProcessPoolExecutor(max_workers=min(jobs, os.cpu_count() or 1), mp_context=ctx) as ex:
        futures = [(g, ex.submit(_work, ([problems[i] for i in g], method, tol, options)))
                   for g in groups]
        for g, fut in futures:
            for i, res in zip(g, fut.result(), strict=True):
                results[i] = res
    return results
