"""The contact LCP of a scene as a :class:`~lcpcli.core.problem.Problem`; its solution mapped back.

``build(scene, friction=K)`` returns a :class:`ContactLCP` (the whole-scene problem with contact
metadata in ``Problem.meta["contact"]``, its islands, the planar reduction and the softness
used); ``solve(clcp)`` solves it island by island with :func:`lcpcli.solve` (each island
certified, then the merged impulses certified on the whole-scene LCP) and returns an
:class:`Impact`: impulses, post-impact velocities, normal velocities, kinetic energies and the
per-island report.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lcpcli.contact.assembly import STATES, Assembly, assemble, choose_storage
from lcpcli.contact.friction import check_directions, friction_blocks
from lcpcli.contact.impact import (
    approaching,
    energy_increased,
    kinetic_energy,
    normal_velocities,
    post_velocities,
)
from lcpcli.contact.islands import (
    IslandLayout,
    Islands,
    basic_of,
    find_islands,
    island_problems,
    layout,
    solve_islands,
    solve_one,
)
from lcpcli.contact.planar import plane_normal
from lcpcli.contact.scene import Scene, check_coupling, check_nonnegative, per_contact
from lcpcli.core.errors import OptionError, ProblemError
from lcpcli.core.limits import check_dense_work
from lcpcli.core.numeric import real_array
from lcpcli.core.problem import Problem, is_sparse
from lcpcli.core.result import CONVERGED, NO_SOLUTION, NUMERICAL, SOLVED, Outcome
from lcpcli.solvers import DEFAULT_METHOD

#: Default method, per island: ``auto`` classifies each island's LCP and picks a method (Lemke
#: for the small dense islands, iterative sparse methods for big sparse ones).
#: Default softness (no regularisation: rigid contacts).
DEFAULT_SOFTNESS = 0.0
CONVENTION = ("w = M z + q, 0 <= z _|_ w >= 0; z = impulses; normals point from B to A; "
              "q_n = (1 + e) v_rel^- with e = eps for contacts approaching faster than their "
              "restitution threshold, e = 0 for the others; w_n = v_rel^+ + e v_rel^- "
              "(+ softness * M_ii * j_n when soft)")


@dataclass
class ContactLCP:
    """A scene's contact LCP: the problem, its assembly, islands and the layout of the unknowns."""

    scene: Scene
    assembly: Assembly
    problem: Problem
    friction: int                  # tangent directions per friction contact (0: frictionless)
    friction_contacts: np.ndarray  # (nf,) contacts with friction unknowns
    tangent_dirs: np.ndarray       # (nf, K, d)
    HA: Any                        # csr (n_impulses, dof * nm): A W for all impulse rows
    unknowns: list[str]            # names of the LCP unknowns, in order
    unknown_contact: np.ndarray    # (n,) the contact of each unknown
    islands: Islands
    layout: IslandLayout
    softness: np.ndarray           # (nc,) softness used per contact
    regularisation: np.ndarray     # (n,) added to M's diagonal (0 for rigid rows and slacks)
    plane: np.ndarray | None = None  # plane normal of a planar 3-D scene (friction reduced)
    requested_friction: int = 0    # K as asked (before 2-D / planar reduction)
    storage: str = "auto"          # as asked (islands use the same rule)
    notes: list[str] = field(default_factory=list)  # what the user should know (stderr)

    @property
    def n_impulses(self) -> int:
        """Unknowns that are impulses (normal + tangential; slacks excluded)."""
        return self.scene.n_contacts + self.friction_contacts.size * self.friction

    def island_sizes(self) -> np.ndarray:
        """Unknowns per island."""
        return np.diff(self.layout.offsets)


@dataclass
class Impact:
    """A solved contact LCP mapped back onto the scene."""

    result: Any                    # lcpcli.core.result.Result (whole scene)
    normal_impulses: np.ndarray    # (nc,)
    tangent_impulses: np.ndarray   # (nf, K)
    slacks: np.ndarray             # (nf,)
    velocity: np.ndarray           # (nb, d) after impact
    omega: np.ndarray              # (nb, r) after impact
    normal_velocity: np.ndarray    # (nc,) after impact
    energy_before: float
    energy_after: float
    approaching: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))  # (nc,)
    islands: list[dict[str, Any]] | None = None  # per island report (None: whole scene solve)
    #: (n,) bool: z_i basic in the basis the answer was pivoted to (each island's, as
    #: Lemke's batched kernel ended on it, else ``z_i > 0``): the next step's warm basis
    #: (``solve(..., z0=impact.result.z, basis0=impact.basic)``).  None without a result.
    basic: np.ndarray | None = None

    @property
    def energy_increase(self) -> bool:
        return energy_increased(self.energy_before, self.energy_after)


def build(scene: Scene, friction: int = 0, storage: str = "auto", *,
          restitution_threshold: float | None = None, softness: float | None = None,
          planar: bool = True) -> ContactLCP:
    """The contact LCP of ``scene`` (``friction`` = K tangent directions, 0 = frictionless).

    ``restitution_threshold`` and ``softness`` replace the scene-level values (contacts that
    give their own keep them).  ``planar``: reduce friction to the 2 in-plane directions when
    the motion of a 3-D scene is planar (:mod:`lcpcli.contact.planar`).
    """
    import scipy.sparse as sp

    k = check_directions(int(friction), scene.dimension)
    choose_storage(storage, 0, 0)  # validate the name early
    for value, label in ((restitution_threshold, "--restitution-threshold"),
                         (softness, "--softness")):
        try:
            check_nonnegative(value, label)
        except ProblemError as exc:  # an option, not the scene file (exit 2 either way)
            raise OptionError(str(exc)) from None
    check_coupling(scene, 1 + k)  # M's size from the contact counts, before assembling it
    if storage == "dense":
        check_dense_work(scene.n_contacts * (2 + k if k else 1), "--storage dense builds M as a "
                         "dense matrix", instead="use --storage sparse", cubic=False)
    with np.errstate(over="ignore", invalid="ignore"):  # checked below: _check_representable
        asm = assemble(scene, storage, restitution_threshold=restitution_threshold)
    nc = scene.n_contacts
    names = [f"n[{c}]" for c in scene.contact_names]
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow: refused below
        plane = plane_normal(scene) if planar and scene.dimension == 3 else None
    notes = []
    if k:
        with np.errstate(over="ignore", invalid="ignore"):
            fb = friction_blocks(asm, k, plane)
        fc, dirs, kk = fb["fc"], fb["dirs"], fb["K"]
        G = fb["matrix"]
        q = fb["q"]
        HA = sp.vstack([asm.H, fb["HD"]]).tocsr()
        for f in fc:
            names += [f"t{i + 1}[{scene.contact_names[f]}]" for i in range(kk)]
        names += [f"lambda[{scene.contact_names[f]}]" for f in fc]
        unknown_contact = np.concatenate([np.arange(nc), np.repeat(fc, kk), fc])
        diag = G.diagonal()
    else:
        fc, dirs, kk = np.zeros(0, dtype=np.int64), np.zeros((0, 0, scene.dimension)), 0
        G, q, HA = asm.M, asm.q, asm.H
        unknown_contact = np.arange(nc)
        diag = asm.inv_eff_mass
    scene_soft = scene.softness_default if softness is None else softness
    soft = per_contact(scene.softness, scene_soft, DEFAULT_SOFTNESS)
    n = q.shape[0]
    reg = np.zeros(n)
    n_imp = nc + fc.size * kk
    with np.errstate(invalid="ignore"):  # 0 x an overflowed diagonal: refused below
        reg[:n_imp] = soft[unknown_contact[:n_imp]] * diag[:n_imp]
    if k:
        kind = choose_storage(storage, n, int(G.nnz))
        M = G.toarray() if kind == "dense" else G
    else:
        M = G
    if np.any(reg > 0):
        with np.errstate(over="ignore", invalid="ignore"):
            M = (M + sp.diags(reg)).tocsr() if is_sparse(M) else M + np.diag(reg)
    _check_representable(M, q, scene)
    if scene.dimension == 2 and int(friction) not in (0, 2):
        notes.append(f"--friction {friction} in a 2-D scene: the tangent line has two "
                     f"directions (+t, -t), so K = 2 is used")
    if plane is not None and k and fc.size:
        full = nc + fc.size * (k + 1)
        notes.append(f"planar motion (plane normal {_fmt_vec(plane)}): friction uses the 2 "
                     f"in-plane directions +-(e x n) instead of K = {k} ({n} unknowns instead "
                     f"of {full})")
    if k and fc.size == 0:
        notes.append(f"--friction {k}: no contact has a friction coefficient mu > 0, so the LCP "
                     f"is frictionless")
    if nc == 0:
        notes.append("the scene has no contacts: the LCP is empty and no velocity changes")
    isl = find_islands(scene)
    lay = layout(isl, unknown_contact)
    meta = {"contact": contact_meta(scene, asm, kk, fc, names, isl, plane, soft)}
    problem = Problem.create(M, q, name=scene.name or "contact",
                             description=f"contact LCP of scene {scene.name!r}: "
                                         f"{nc} contacts, {asm.modelled.size} moving bodies, "
                                         f"{isl.count} islands"
                                         + (f", friction K={kk}" if kk else ", frictionless"),
                             meta=meta)
    return ContactLCP(scene=scene, assembly=asm, problem=problem, friction=kk,
                      friction_contacts=fc, tangent_dirs=dirs, HA=HA, unknowns=names,
                      unknown_contact=unknown_contact, islands=isl, layout=lay, softness=soft,
                      regularisation=reg, plane=plane, requested_friction=int(friction),
                      storage=storage, notes=notes)


def _check_representable(M: Any, q: np.ndarray, scene: Scene) -> None:
    """ProblemError (exit 2, one line) when the contact LCP overflows double precision: a valid
    scene whose masses, inertias, lever arms or velocities span too wide a range for
    ``M = J W J^T`` and ``q`` to be finite."""
    data = M.data if is_sparse(M) else M
    if np.all(np.isfinite(data)) and np.all(np.isfinite(q)):
        return
    what = "M = J W J^T" if not np.all(np.isfinite(data)) else "q (relative normal velocities)"
    raise ProblemError(f"the contact LCP of scene {scene.name or 'contact'!r} cannot be "
                       f"represented in double precision: {what} overflows (masses, inertias, "
                       f"lever arms or velocities out of range)")


def _count(n: int, word: str) -> str:
    return f"{n} {word}" + ("" if n == 1 else "s")


def _fmt_vec(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{x:.6g}" for x in v) + ")"


def contact_meta(scene: Scene, asm: Assembly, k: int, fc: np.ndarray, names: list[str],
                 isl: Islands, plane: np.ndarray | None, soft: np.ndarray) -> dict[str, Any]:
    """What a saved LCP carries so that a solution can be mapped back onto the scene."""
    names_b = scene.body_names
    return {
        "version": 2,
        "scene": scene.name,
        "dimension": scene.dimension,
        "convention": CONVENTION,
        "ordering": ("[normal impulses (one per contact) | tangent impulses (K per friction "
                     "contact, contact-major) | slacks lambda (one per friction contact)]")
        if k else "normal impulses, one per contact, in contact order",
        "friction_directions": k,
        "friction_contacts": [int(f) for f in fc],
        "plane_normal": None if plane is None else plane.tolist(),
        "islands": isl.count,
        "unknowns": names,
        "contacts": [{"name": nm, "a": names_b[a], "b": names_b[b], "restitution": e,
                      "mu": None if m != m else m, "state": STATES[st],
                      "restitution_used": eu, "restitution_threshold": th, "softness": sf,
                      "island": int(i)}
                     for nm, a, b, e, m, st, eu, th, sf, i in zip(
                         scene.contact_names, scene.contact_a.tolist(), scene.contact_b.tolist(),
                         scene.restitution.tolist(), scene.mu.tolist(), asm.state.tolist(),
                         asm.restitution_used.tolist(), asm.threshold.tolist(), soft.tolist(),
                         isl.contact_island.tolist(), strict=True)],
        "bodies": [{"name": nm, "static": st, "kinematic": kn,
                    "column_block": col if col >= 0 else None}
                   for nm, st, kn, col in zip(names_b, scene.static.tolist(),
                                              scene.kinematic.tolist(), asm.columns.tolist(),
                                              strict=True)],
    }


def check_method(clcp: ContactLCP, method: str, islands: bool = True) -> None:
    """OptionError for an unknown method, or a densifying method on a huge sparse LCP (the
    whole scene's, or with ``islands`` the biggest island's); ProblemError for a method that
    factorises a sparse LCP over the sparse-factorisation budget (lcpcli.core.limits)."""
    from lcpcli.solvers.request import check_dense_ok, check_sparse_work, method_of

    spec = method_of(method)
    if not islands or clcp.layout.count <= 1:
        _check_dense_budget(clcp.problem, spec)
        check_dense_ok(clcp.problem, spec)  # one island: its LCP is the scene's
        if clcp.problem.sparse:
            check_sparse_work(clcp.problem.n, spec)
        return
    sizes = clcp.island_sizes()
    big = int(np.argmax(sizes))
    one = IslandLayout(perm=clcp.layout.unknowns(big), offsets=np.array([0, int(sizes[big])]))
    biggest = island_problems(clcp.problem, one, clcp.storage)[0]
    _check_dense_budget(biggest, spec)
    check_dense_ok(biggest, spec)
    if biggest.sparse:
        check_sparse_work(biggest.n, spec)


def _check_dense_budget(problem: Problem, spec: Any) -> None:
    """The dense-work budget of ``spec`` on ``problem`` (ProblemError), as the solve checks it,
    when the method works on a dense M: ``problem``'s M is dense, or the method densifies a
    sparse one."""
    from lcpcli.solvers.request import check_dense_work

    if not problem.sparse or not spec.sparse:
        check_dense_work(problem.n, spec)


def check_basis0(clcp: ContactLCP, basis0: Any) -> np.ndarray:
    """The warm basis as booleans of the LCP's length (True: z_i basic; OptionError
    otherwise)."""
    b = np.asarray(basis0).ravel()
    if b.shape[0] != clcp.problem.n or b.dtype.kind not in "biu":
        raise OptionError(f"the warm basis must be {clcp.problem.n} booleans (True: z_i basic), "
                          f"got {b.shape[0]} of type {b.dtype}")
    return b.astype(bool)


def check_z0(clcp: ContactLCP, z0: Any) -> np.ndarray:
    """The warm start as a vector of the LCP's length, of real numbers (the data rule of
    :func:`lcpcli.core.numeric.real_array`; OptionError otherwise)."""
    try:
        z = real_array(z0, "the warm start z0").ravel()
    except ProblemError as exc:
        raise OptionError(str(exc)) from None
    if z.shape[0] != clcp.problem.n:
        raise OptionError(f"the warm start z0 has {z.shape[0]} values but the contact LCP has "
                          f"{clcp.problem.n} unknowns ({', '.join(clcp.unknowns[:3])}"
                          f"{', ...' if clcp.problem.n > 3 else ''})")
    if not np.all(np.isfinite(z)):
        raise OptionError("the warm start z0 contains NaN or Inf")
    return z


def solve(clcp: ContactLCP, method: str = DEFAULT_METHOD, tol: float | None = None, *,
          islands: bool = True, z0: Any = None, basis0: Any = None, jobs: int = 1,
          **options: Any) -> Impact:
    """Solve the contact LCP and map the impulses back onto the scene.

    ``islands`` (default): each island's LCP is solved with :func:`lcpcli.solve` (``method``,
    ``tol``, ``options``) through :func:`lcpcli.contact.islands.solve_problems`, the impulses
    are merged in the scene's unknown order and certified on the whole-scene LCP (the verdict);
    an island whose LCP is proven to have no solution proves the scene's has none.  Otherwise the
    whole-scene LCP is solved at once.  ``z0``: warm start (a vector of the LCP's length),
    see :func:`lcpcli.contact.islands.solve_one`; ``basis0`` (with ``z0``): the basis the
    pivoting starts from (booleans, True: z_i basic; a previous step's :attr:`Impact.basic`,
    matched by unknown name) instead of ``z0``'s support ``{i: z0_i > 0}``, which on the
    degenerate LCPs of redundant contacts is a poor start.  ``jobs``: processes for the islands.
    """
    check_method(clcp, method, islands)
    if jobs < 1:
        raise OptionError(f"--jobs must be >= 1, got {jobs}")
    z0 = None if z0 is None else check_z0(clcp, z0)
    if basis0 is not None:
        if z0 is None:
            raise OptionError("a warm basis (basis0) needs its warm start z0")
        basis0 = check_basis0(clcp, basis0)
    if not islands or clcp.layout.count == 0:
        result = solve_one(clcp.problem, method, tol, z0, dict(options), basis0)
        return impact_from(clcp, result.z, result, basic=basic_of(result))
    return impact_from(clcp, *_solve_islands(clcp, method, tol, z0, jobs, options, basis0))


def _solve_islands(clcp: ContactLCP, method: str, tol: float | None, z0: np.ndarray | None,
                   jobs: int, options: dict[str, Any], basis0: np.ndarray | None = None
                   ) -> tuple[np.ndarray, Any, list[Any], np.ndarray]:
    from lcpcli.api import certify_outcome
    from lcpcli.solvers.request import method_of, resolve_tol

    lay, isl = clcp.layout, clcp.islands
    t0 = time.perf_counter()
    ans = solve_islands(clcp.problem, lay, clcp.storage, clcp.scene.name or "contact", method,
                        tol, z0, basis0, jobs, **options)
    seconds = time.perf_counter() - t0
    z, basic, results = ans.z, ans.basic, ans.results
    used: dict[str, int] = {}
    for chosen in ans.methods:
        used[chosen] = used.get(chosen, 0) + 1
    reports = [{"index": k + 1, "contacts": c, "bodies": b, "unknowns": u, "method": m,
                "status": st, "iterations": it, "seconds": sec, "error": _finite(e),
                "warm": wm}
               for k, (c, b, u, m, st, it, sec, e, wm) in enumerate(zip(
                   isl.sizes().tolist(), isl.body_counts().tolist(),
                   np.diff(lay.offsets).tolist(), ans.methods, ans.status, ans.iterations,
                   ans.seconds, ans.errors, ans.warm, strict=True))]
    failed = [r for r in reports if r["status"] != SOLVED]
    infeasible = [r for r in reports if r["status"] == NO_SOLUTION]
    mix = ", ".join(f"{m} {c}" for m, c in sorted(used.items(), key=lambda x: -x[1]))
    n_warm = sum(r["warm"] for r in reports)
    warm = f"; {n_warm} solved from the warm start" if z0 is not None else ""
    if infeasible:
        first = infeasible[0]["index"] - 1
        msg = (f"{len(infeasible)} of {_count(lay.count, 'island')} without solution, so the "
               f"scene has none; island {first + 1}: {results[first].message}")
    elif failed:
        first = failed[0]["index"] - 1
        msg = (f"{len(failed)} of {_count(lay.count, 'island')} not solved; island {first + 1}: "
               f"{results[first].message}")
    else:
        msg = f"{_count(lay.count, 'island')} solved ({mix}){warm}"
    termination = CONVERGED
    if failed:  # a method that "converged" to a point its certificate rejects failed numerically
        termination = results[failed[0]["index"] - 1].termination
        termination = NUMERICAL if termination == CONVERGED else termination
    info: dict[str, Any] = {"islands": reports}
    y = scene_farkas(clcp.problem.n, lay, [(r["index"] - 1, results[r["index"] - 1])
                                           for r in infeasible])
    if y is not None:
        info["farkas_y"] = y.tolist()
    tol_used = resolve_tol(method_of(method), tol)
    outcome = Outcome(z=z, iterations=sum(r["iterations"] for r in reports),
                      termination=termination, message=msg, proven_infeasible=bool(infeasible),
                      info=info, checked=ans.checked)  # the scene's, from its islands' if set
    result = certify_outcome(clcp.problem, outcome, method, seconds, tol_used)
    return z, result, reports, basic


def scene_farkas(n: int, layout: IslandLayout,
                 infeasible: list[tuple[int, Any]]) -> np.ndarray | None:
    """The scene's Farkas vector from the first ``(island index, result)`` in ``infeasible``
    whose result carries one (``info["farkas_y"]``), zero outside that island; None if none
    carries one.

    The scene's M is block diagonal in the islands' unknowns (no row of one island has an entry
    in another's columns), so ``M^T y`` is the island's ``M_k^T y_k`` on its columns and 0
    elsewhere, and ``q^T y = q_k^T y_k``: a Farkas vector of the island, padded with zeros, is
    one of the scene (checked again on the whole LCP by the verdict, never taken on trust),
    which spares the whole-scene linear program (unsolved above a few thousand unknowns)."""
    for k, res in infeasible:
        yk = res.info.get("farkas_y")
        rows = layout.unknowns(k)
        if yk is None or np.shape(yk) != rows.shape:
            continue
        y = np.zeros(n)
        y[rows] = np.asarray(yk, dtype=np.float64)
        return y
    return None


def impact_from(clcp: ContactLCP, z: np.ndarray, result: Any = None,
                islands: list[dict[str, Any]] | None = None,
                basic: np.ndarray | None = None) -> Impact:
    """Post-impact state for the LCP unknowns ``z`` (see :mod:`lcpcli.contact.impact`)."""
    scene = clcp.scene
    nc, nf, k = scene.n_contacts, clcp.friction_contacts.size, clcp.friction
    z = np.asarray(z, dtype=np.float64)
    x = z[: clcp.n_impulses]
    v, w = post_velocities(scene, clcp.assembly.modelled, clcp.HA, x)
    vn = normal_velocities(scene, v, w)
    return Impact(result=result, normal_impulses=z[:nc].copy(),
                  tangent_impulses=z[nc: nc + nf * k].reshape(nf, k).copy(),
                  slacks=z[nc + nf * k:].copy(), velocity=v, omega=w,
                  normal_velocity=vn,
                  energy_before=kinetic_energy(scene, scene.velocity, scene.omega),
                  energy_after=kinetic_energy(scene, v, w),
                  approaching=approaching(vn, clcp.assembly.v_rel), islands=islands,
                  basic=basic)


# ---------------------------------------------------------------------- JSON
def matrix_json(M: Any) -> Any:
    """Dense M as a list of rows; sparse M as the project's CSR object."""
    if is_sparse(M):
        from lcpcli.io.sparse import sparse_parts

        parts = sparse_parts(M)
        return {k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in parts.items()}
    return np.asarray(M).tolist()


def islands_json(clcp: ContactLCP, impact: Impact | None = None) -> dict[str, Any]:
    """The ``islands`` object of the JSON output: count, sizes, and per island (with a solve)
    its method, status, iterations, seconds, error and whether the warm start solved it."""
    isl = clcp.islands
    out: dict[str, Any] = {"count": isl.count, "solved_separately": False,
                           "contacts": isl.sizes().tolist(),
                           "unknowns": clcp.island_sizes().tolist()}
    if impact is not None and impact.islands is not None:
        out["solved_separately"] = True
        out["per_island"] = impact.islands
    return out


def to_json(clcp: ContactLCP, impact: Impact | None = None) -> dict[str, Any]:
    """The ``contact-matrix --json`` object (keys listed in docs/contact.md)."""
    scene, asm = clcp.scene, clcp.assembly
    nc = scene.n_contacts
    isl = clcp.islands
    bodies = []
    for i, nm in enumerate(scene.body_names):
        bodies.append({"name": nm, "static": bool(scene.static[i]),
                       "kinematic": bool(scene.kinematic[i]),
                       "modelled": bool(asm.columns[i] >= 0), "reason": asm.reasons[i],
                       "mass": None if scene.fixed[i] else float(scene.mass[i]),
                       "velocity": scene.velocity[i].tolist(),
                       "angular_velocity": _ang(scene, scene.omega[i]),
                       "island": int(isl.body_island[i]) + 1 if isl.body_island[i] >= 0
                       else None})
    contacts = []
    fpos = {int(f): i for i, f in enumerate(clcp.friction_contacts)}
    for c in range(nc):
        entry = {"name": scene.contact_names[c],
                 "a": scene.body_names[int(scene.contact_a[c])],
                 "b": scene.body_names[int(scene.contact_b[c])],
                 "point": scene.point[c].tolist(), "normal": scene.normal[c].tolist(),
                 "restitution": float(scene.restitution[c]),
                 "mu": None if np.isnan(scene.mu[c]) else float(scene.mu[c]),
                 "normal_velocity_before": float(asm.v_rel[c]),
                 "state": STATES[int(asm.state[c])],
                 "restitution_threshold": float(asm.threshold[c]),
                 "restitution_used": float(asm.restitution_used[c]),
                 "softness": float(clcp.softness[c]),
                 "inverse_effective_mass": float(asm.inv_eff_mass[c]),
                 "effective_mass": _finite(asm.eff_mass[c]),
                 "unknown": c, "island": int(isl.contact_island[c]) + 1}
        if c in fpos:
            entry["tangent_directions"] = clcp.tangent_dirs[fpos[c]].tolist()
        contacts.append(entry)
    states = {name: int(np.sum(asm.state == i)) for i, name in enumerate(STATES)}
    out: dict[str, Any] = {
        "scene": scene.name, "dimension": scene.dimension,
        "M": matrix_json(clcp.problem.M), "q": clcp.problem.q.tolist(),
        "unknowns": clcp.unknowns, "storage": "sparse" if clcp.problem.sparse else "dense",
        "friction_directions": clcp.friction,
        "planar": {"plane_normal": None if clcp.plane is None else clcp.plane.tolist(),
                   "friction_reduced": bool(clcp.plane is not None and clcp.friction
                                            and clcp.friction_contacts.size)},
        "states": states, "islands": islands_json(clcp, impact),
        "bodies": bodies, "contacts": contacts, "warnings": list(scene.warnings) + list(clcp.notes),
    }
    if impact is not None:
        res = impact.result
        out.update({
            "impulses": [float(x) for x in res.z] if res is not None
            else impact.normal_impulses.tolist(),
            "velocities": [{"name": nm, "linear": impact.velocity[i].tolist(),
                            "angular": _ang(scene, impact.omega[i])}
                           for i, nm in enumerate(scene.body_names)],
            "normal_velocities": impact.normal_velocity.tolist(),
            "approaching_after": int(np.sum(impact.approaching)),
            "min_normal_velocity": float(impact.normal_velocity.min()) if nc else None,
            "energy_before": impact.energy_before,
            "energy_after": impact.energy_after,
            "energy_increase": impact.energy_increase,
            "status": res.status if res is not None else None,
        })
        if impact.basic is not None:
            out["basic"] = [bool(x) for x in impact.basic]
        if res is not None:
            out.update({"method": res.method, "message": res.message,
                        "iterations": int(res.iterations), "seconds": res.seconds,
                        "residual": _finite(res.certificate.residual),
                        "error": _finite(res.certificate.error)})
    return out


def _ang(scene: Scene, w: np.ndarray) -> Any:
    return float(w[0]) if scene.dimension == 2 else w.tolist()


def _finite(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None
